"""One fault into one chip, from now on: the form a line of a register script gives.

``inject(chip, "stuck_axis", "axis=y", "duration_s=2")``; with ``bus=`` (the I2CBus the chip
is on) bus faults too. The pytest plugin's ``bmg160_faults`` and the script's ``fault`` line
both come here.
"""

from __future__ import annotations

from typing import Any

from bmg160_emu.faults.model import BUS_KINDS, FaultError, fault_from_dict
from bmg160_emu.faults.schedule import FaultSchedule
from bmg160_emu.faults.targets import ChipOnBus, LoneChip


def parse_value(text: str) -> Any:
    """A ``key=value`` value as a script writes it: an int (0x.. too), a float, a
    comma-separated list of them, or the text itself."""
    for convert in (int, float):
        try:
            return convert(text, 0) if convert is int else convert(text)  # type: ignore[call-arg]
        except ValueError:
            pass
    if "," in text:
        return [parse_value(part) for part in text.split(",")]
    return text


def inject(chip: Any, kind: str, *args: str, bus: Any = None, seed: int | None = 0,
           **params: Any) -> FaultSchedule:
    """Inject one fault into a lone chip from now on: ``inject(chip, "stuck_axis", "axis=y")``.

    Arguments are ``key=value`` strings (as a script line gives them) or keywords. Without a
    trigger the fault starts at the chip's current time. With ``bus`` (the ``I2CBus`` the
    chip is on, such as the pytest plugin's) every kind is accepted, bus faults included,
    and transactions trigger and count as on a rig's bus (``seed``: the random stream of a
    ``probability`` trigger); without it bus faults are refused.
    """
    for arg in args:
        key, sep, value = arg.partition("=")
        if not sep or not key:
            raise FaultError(f"{kind}: expected key=value, not {arg!r}")
        params[key] = parse_value(value)
    if bus is not None:
        if not {"at_s", "on_transaction", "probability", "address", "on_register"} & set(params):
            params["at_s"] = float(chip.time)
        schedule = FaultSchedule([fault_from_dict({"kind": kind, **params}, kind)], seed=seed)
        schedule.install([ChipOnBus(chip, bus)])
        return schedule
    if kind in BUS_KINDS:
        raise FaultError(f"{kind} is a bus fault: give the bus the chip is on, "
                         f"inject(chip, {kind!r}, bus=...) (the pytest plugin's bmg160_smbus), "
                         "or use a GyroRig")
    if {"on_transaction", "probability"} & set(params):
        raise FaultError(f"{kind}: a lone chip has no transactions to count; give at_s")
    now = float(chip.time)
    params.setdefault("at_s", now)
    fault = fault_from_dict({"kind": kind, **params}, kind)
    assert fault.at_s is not None
    if fault.layer == "chip" and fault.at_s > now:
        raise FaultError(f"{kind}: acts at once on a lone chip; at_s cannot be in the future")
    schedule = FaultSchedule([fault], log_to_bus=False)
    target = LoneChip(chip)
    schedule.install_on_samples(target)
    if fault.layer == "sample":
        schedule.activate(0, target, fault.at_s)
    else:
        schedule.act_chip_fault(fault, target, now)
    return schedule
