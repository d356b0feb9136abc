"""Stand-in declarations: the built-in ones, a TOML file, or an i2cdump-format dump.

``load_standin(name_or_path)`` gives a :class:`~bmg160_emu.device.standin.StandinSpec`:
a built-in name (``bmi088_accel``, ``bma2x2_accel``, ``bmm150``: the TOMLs shipped in
``bmg160_emu/device/standins/``), a ``.toml`` path, or any other path read as an i2cdump
byte-mode listing (every register present becomes plain storage, the chip-ID register
read-only). Every mistake is a :class:`StandinFormatError` naming the file and the place
(docs/sessions.md gives the TOML layout).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

from bmg160_emu.device.standin import (
    ADDRESS_BITS,
    DEFAULT_ADDRESS_BITS,
    REGISTER_SPACE,
    PowerGate,
    SoftReset,
    SpiInterface,
    StandinRegister,
    StandinSpec,
)
from bmg160_emu.io.dump import DumpFormatError, i2cdump_cells
from bmg160_emu.io.errors import FormatError, loads_toml, read_text

BUILTIN_PACKAGE = "bmg160_emu.device"
BUILTIN_DIR = "standins"


class StandinFormatError(FormatError):
    """A stand-in declaration that cannot be used; the message names the file and place."""


def builtin_names() -> tuple[str, ...]:
    """The stand-ins shipped with the package."""
    folder = resources.files(BUILTIN_PACKAGE).joinpath(BUILTIN_DIR)
    return tuple(sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml")))


def load_standin(name_or_path: str | Path) -> StandinSpec:
    """A built-in stand-in by name, or one declared in a TOML file or an i2cdump dump."""
    text = str(name_or_path)
    if text in builtin_names():
        resource = resources.files(BUILTIN_PACKAGE).joinpath(BUILTIN_DIR, f"{text}.toml")
        return spec_from_toml(resource.read_text(encoding="utf-8"), f"{text}.toml", source=text)
    path = Path(name_or_path)
    if not path.exists():
        raise StandinFormatError(
            f"{text}: no such stand-in file (built-in stand-ins: {', '.join(builtin_names())})")
    if path.is_dir():
        raise StandinFormatError(f"{text}: is a folder, not a stand-in TOML or dump")
    try:
        content = read_text(path, StandinFormatError)
    except OSError as exc:
        raise StandinFormatError(f"{text}: cannot read: {exc.strerror or exc}") from None
    if path.suffix.lower() == ".toml":
        return spec_from_toml(content, str(path), source=str(path))
    return spec_from_dump(content, str(path), name=path.stem)


# --------------------------------------------------------------------------- TOML

_TOP_KEYS = {"name", "description", "chip_id_register", "chip_id", "addresses", "absent_value",
             "no_increment", "soft_reset", "power_gate", "registers", "register_address_bits",
             "spi"}
_REGISTER_KEYS = {"name", "reset", "writable", "write_only"}
_SPI_KEYS = {"dummy_bytes", "starts_in_i2c", "three_wire_register", "three_wire_mask",
             "write_pairs"}
MAX_DUMMY_BYTES = 4  # more than any part of the family shifts out (the BMI088 accelerometer: 1)


def spec_from_toml(text: str, where: str, source: str = "") -> StandinSpec:
    """A declaration from TOML text (``where`` names the file in errors)."""
    return spec_from_dict(loads_toml(text, StandinFormatError, where), where, source or where)


def _byte(value: Any, where: str, what: str, high: int = 0xFF) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= high:
        raise StandinFormatError(f"{where}: {what} must be an integer 0x00..0x{high:02X}, "
                                 f"not {value!r}")
    return value


def _bytes(value: Any, where: str, what: str, high: int = 0xFF) -> tuple[int, ...]:
    if not isinstance(value, list):
        raise StandinFormatError(f"{where}: {what} must be a list of integers, not {value!r}")
    return tuple(_byte(v, where, f"{what}[{i}]", high) for i, v in enumerate(value))


def _table(data: dict, key: str, where: str, keys: set[str]) -> dict | None:
    value = data.get(key)
    if value is None:
        return None
    if not isinstance(value, dict):
        raise StandinFormatError(f"{where}: [{key}] must be a table")
    unknown = set(value) - keys
    if unknown:
        raise StandinFormatError(f"{where}: [{key}]: unknown keys {sorted(unknown)} "
                                 f"(known: {', '.join(sorted(keys))})")
    return value


def _register_keys(key: str, where: str) -> range:
    """``"0x4B"`` or a range ``"0x5D-0x71"`` (both ends included)."""
    first, dash, last = key.partition("-")
    try:
        low = int(first.strip(), 0)
        high = int(last.strip(), 0) if dash else low
    except ValueError:
        raise StandinFormatError(f"{where}: [registers] key {key!r} is not a register "
                                 "(0x4B) or a range (0x5D-0x71)") from None
    if not 0 <= low <= high < REGISTER_SPACE:
        raise StandinFormatError(f"{where}: [registers] key {key!r} is outside 0x00..0xFF "
                                 "or runs backwards")
    return range(low, high + 1)


def spec_from_dict(data: Any, where: str, source: str = "") -> StandinSpec:
    """A declaration from its plain-data form (TOML tables, or a trace header's entry)."""
    if not isinstance(data, dict):
        raise StandinFormatError(f"{where}: a stand-in declaration must be a table")
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise StandinFormatError(f"{where}: unknown keys {sorted(unknown)} "
                                 f"(known: {', '.join(sorted(_TOP_KEYS))})")
    for key in ("name", "chip_id_register", "chip_id", "addresses", "registers"):
        if key not in data:
            raise StandinFormatError(f"{where}: missing {key!r}")
    name = data["name"]
    if not isinstance(name, str) or not name or any(c in name for c in "@: /"):
        raise StandinFormatError(f"{where}: name must be a word without '@', ':', ' ' or '/', "
                                 f"not {name!r}")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise StandinFormatError(f"{where}: description must be text")
    chip_id_register = _byte(data["chip_id_register"], where, "chip_id_register")
    chip_id = _byte(data["chip_id"], where, "chip_id")
    addresses = _bytes(data["addresses"], where, "addresses", 0x7F)  # [] : any address
    absent = _byte(data.get("absent_value", 0x00), where, "absent_value")
    no_increment = _bytes(data.get("no_increment", []), where, "no_increment")
    bits = data.get("register_address_bits", DEFAULT_ADDRESS_BITS)
    if isinstance(bits, bool) or bits not in ADDRESS_BITS:
        raise StandinFormatError(f"{where}: register_address_bits must be 7 or 8, not {bits!r}")
    top = (1 << bits) - 1  # the highest register the chip can address

    table = data["registers"]
    if not isinstance(table, dict) or not table:
        raise StandinFormatError(f"{where}: [registers] must be a table of at least one register")
    registers: dict[int, StandinRegister] = {}
    for key, entry in table.items():
        here = f"{where}: [registers] {key}"
        if not isinstance(entry, dict):
            raise StandinFormatError(f"{here}: must be a table like {{ reset = 0x00 }}")
        unknown = set(entry) - _REGISTER_KEYS
        if unknown:
            raise StandinFormatError(f"{here}: unknown keys {sorted(unknown)} "
                                     f"(known: {', '.join(sorted(_REGISTER_KEYS))})")
        label = entry.get("name", "")
        write_only = entry.get("write_only", False)
        if not isinstance(label, str) or not isinstance(write_only, bool):
            raise StandinFormatError(f"{here}: name must be text and write_only true or false")
        register = StandinRegister(_byte(entry.get("reset", 0x00), here, "reset"),
                                   _byte(entry.get("writable", 0xFF), here, "writable"),
                                   write_only, label)
        for reg in _register_keys(str(key), where):
            if reg > top:
                raise StandinFormatError(
                    f"{here}: register 0x{reg:02X} is beyond a {bits}-bit register address "
                    f"(0x00..0x{top:02X}: register_address_bits)")
            if reg in registers:
                raise StandinFormatError(f"{here}: register 0x{reg:02X} is declared twice")
            registers[reg] = register
    declared = registers.get(chip_id_register)
    if declared is None:
        registers[chip_id_register] = StandinRegister(chip_id, 0x00, False, "CHIP_ID")
    elif declared.reset != chip_id or declared.writable or declared.write_only:
        raise StandinFormatError(
            f"{where}: [registers] 0x{chip_id_register:02X} is the chip-ID register: it must "
            f"reset to chip_id 0x{chip_id:02X}, be read-only (writable = 0) and readable")

    soft_reset = None
    entry = _table(data, "soft_reset", where, {"register", "value", "mask", "keeps"})
    if entry is not None:
        here = f"{where}: [soft_reset]"
        if "register" not in entry or "value" not in entry:
            raise StandinFormatError(f"{here}: needs register and value")
        soft_reset = SoftReset(_byte(entry["register"], here, "register"),
                               _byte(entry["value"], here, "value"),
                               _byte(entry.get("mask", 0xFF), here, "mask"),
                               _bytes(entry.get("keeps", []), here, "keeps"))
        if soft_reset.register not in registers:
            raise StandinFormatError(f"{here}: register 0x{soft_reset.register:02X} is not "
                                     "declared in [registers]")
    power_gate = None
    entry = _table(data, "power_gate", where, {"register", "mask", "open", "closed_value"})
    if entry is not None:
        here = f"{where}: [power_gate]"
        if "register" not in entry or "mask" not in entry:
            raise StandinFormatError(f"{here}: needs register and mask")
        power_gate = PowerGate(_byte(entry["register"], here, "register"),
                               _byte(entry["mask"], here, "mask"),
                               _bytes(entry.get("open", []), here, "open"),
                               _byte(entry.get("closed_value", 0x00), here, "closed_value"))
        gate = registers.get(power_gate.register)
        if gate is None or not gate.writable & power_gate.mask or power_gate.mask == 0:
            raise StandinFormatError(f"{here}: register 0x{power_gate.register:02X} must be "
                                     "declared with the mask's bits writable")
    for reg, what in ((chip_id_register, "chip_id_register"),
                      *((r, "no_increment") for r in no_increment)):
        if reg > top:
            raise StandinFormatError(f"{where}: {what} 0x{reg:02X} is beyond a {bits}-bit "
                                     f"register address (0x00..0x{top:02X})")
    spi = _spi_interface(data, where, registers)
    return StandinSpec(name, chip_id_register, chip_id, addresses, registers, description,
                       absent, no_increment, soft_reset, power_gate, source, bits, spi)


def _spi_interface(data: dict, where: str, registers: dict[int, StandinRegister]) -> SpiInterface:
    """The ``[spi]`` table: dummy bytes, the I2C start, the 3-wire bit (all optional)."""
    entry = _table(data, "spi", where, _SPI_KEYS)
    if entry is None:
        return SpiInterface()
    here = f"{where}: [spi]"
    dummy = entry.get("dummy_bytes", 0)
    if isinstance(dummy, bool) or not isinstance(dummy, int) or not 0 <= dummy <= MAX_DUMMY_BYTES:
        raise StandinFormatError(f"{here}: dummy_bytes must be an integer 0..{MAX_DUMMY_BYTES}, "
                                 f"not {dummy!r}")
    flags = {}
    for key in ("starts_in_i2c", "write_pairs"):
        flags[key] = entry.get(key, False)
        if not isinstance(flags[key], bool):
            raise StandinFormatError(f"{here}: {key} must be true or false, "
                                     f"not {flags[key]!r}")
    register = entry.get("three_wire_register")
    if register is None:
        if "three_wire_mask" in entry:
            raise StandinFormatError(f"{here}: three_wire_mask needs three_wire_register")
        return SpiInterface(dummy, **flags)
    register = _byte(register, here, "three_wire_register")
    mask = _byte(entry.get("three_wire_mask", 0x01), here, "three_wire_mask")
    declared = registers.get(register)
    if declared is None or mask == 0 or declared.writable & mask != mask:
        raise StandinFormatError(f"{here}: three_wire_register 0x{register:02X} must be "
                                 "declared with the three_wire_mask bits writable")
    return SpiInterface(dummy, three_wire_register=register, three_wire_mask=mask, **flags)


# --------------------------------------------------------------------------- dumps


def spec_from_dump(text: str, where: str, name: str, chip_id_register: int = 0x00) -> StandinSpec:
    """A stand-in from an i2cdump byte-mode listing: the registers it shows are plain
    storage with the dumped values as reset values, the chip-ID register read-only; cells
    printed ``XX`` and registers the dump leaves out read 0x00 and ignore writes."""
    try:
        cells = i2cdump_cells(text, where)
    except DumpFormatError as exc:
        raise StandinFormatError(str(exc)) from None
    values = {reg: value for reg, value in cells.items() if value is not None}
    if chip_id_register not in values:
        raise StandinFormatError(f"{where}: the dump has no readable register "
                                 f"0x{chip_id_register:02X} (the chip ID)")
    registers = {reg: StandinRegister(value) for reg, value in values.items()}
    chip_id = values[chip_id_register]
    registers[chip_id_register] = StandinRegister(chip_id, 0x00, False, "CHIP_ID")
    safe = "".join(c if c.isalnum() or c in "_-." else "_" for c in name) or "dump"
    return StandinSpec(safe, chip_id_register, chip_id, (), registers,
                       f"registers of {where}", 0x00, (), None, None, where)
