"""What a driver wrote into a device's registers, and the check a test makes on it.

Why here: a test asks "did the driver set RANGE before BW?" the same way whichever stack the
driver used (smbus2's ``write_byte_data``, Blinka's ``writeto``, MicroPython's
``writeto_mem``, a kernel driver through virtio): the log's register writes
(:func:`bmg160_emu.traffic.kinds.register_writes`) are one ``(register, value)`` pair per
register whatever carried them, and register names are the device's own (a BMI088
gyroscope's GYRO_RANGE or RANGE, a stand-in's ACC_RANGE).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any


def register_address(device: Any, name: str) -> int:
    """The address of register ``name`` on ``device``: a part's data-sheet name or its
    BMG160 name, a stand-in's declared name; KeyError naming the device otherwise."""
    part = getattr(device, "part", None)
    if part is not None:
        return int(part.address_of(name))
    spec = getattr(device, "spec", None)
    if spec is not None:
        for address, register in spec.registers.items():
            if register.name.upper() == name.upper():
                return int(address)
        raise KeyError(f"no {spec.name} register named {name!r}")
    from bmg160_emu.device.registers import address_of

    return address_of(name)


def check_wrote(writes: Sequence[tuple[int, int]], device: Any, values: Mapping[str, int],
                before: str | None = None) -> None:
    """AssertionError unless every ``NAME=value`` is among ``writes`` and, with ``before``,
    each was first written before the first write of register ``before``."""
    __tracebackhide__ = True
    listed = ", ".join(f"0x{r:02x}=0x{v:02x}" for r, v in writes) or "none"
    first_before = None
    if before is not None:
        other = register_address(device, before)
        later = [i for i, (r, _v) in enumerate(writes) if r == other]
        if not later:
            raise AssertionError(f"the driver never wrote {before}; its writes: {listed}")
        first_before = later[0]
    for name, value in values.items():
        register = register_address(device, name)
        hits = [i for i, (r, v) in enumerate(writes) if r == register and v == value]
        if not hits:
            raise AssertionError(f"the driver never wrote {name} = 0x{value:02x}; its writes: "
                                 f"{listed}")
        if first_before is not None and hits[0] > first_before:
            raise AssertionError(f"{name} = 0x{value:02x} was not written before {before}; "
                                 f"its writes: {listed}")
