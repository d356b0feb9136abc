"""No register address or field mask typed as a number outside the register table.

A spec correction must be one edit in ``device/registers.py``; a copy typed elsewhere would
silently keep the old value. The check is an ast heuristic over the package; it flags:

1. an integer literal as the register argument of a register access: ``peek(R)``,
   ``poke(R, v)``, ``read(R, n)`` / ``write(R, data)`` with two arguments, and the SMBus
   calls ``read_byte_data(addr, R)``, ``write_byte_data(addr, R, v)``, ``read_word_data``,
   ``write_word_data``, ``read_i2c_block_data``, ``write_i2c_block_data``;
2. an integer literal masking the result of such a read (``peek(x) & 0x07``);
3. a module- or class-level constant named like a register of the table (``RANGE = 0x0F``,
   ``FIFO_DATA = 0x3F``) or ``*_REGISTER`` given an integer literal;
4. ``register == 0x10`` (or ``reg``, ``address`` ... compared with a literal).

Not register fields, so never flagged: bus-protocol numbers (the SPI read flag 0x80 and
address mask 0x7F, 7-bit I2C addresses, byte masks 0xFF on values that are not register
reads), and counts. Use ``registers.address_of(name)`` and ``registers.field_of(reg,
field).mask`` / ``.extract(value)`` instead.
"""

from __future__ import annotations

import ast
from pathlib import Path

from bmg160_emu.device import registers

ROOT = Path(__file__).resolve().parents[1] / "bmg160_emu"

# The table itself, and the firmware's table generated from it.
TABLE_FILES = {"device/registers.py", "firmware/register_table.py"}

REGISTER_ARG = {  # method -> index of its register argument
    "peek": 0, "poke": 0, "read": 0, "write": 0,
    "read_byte_data": 1, "write_byte_data": 1, "read_word_data": 1, "write_word_data": 1,
    "read_i2c_block_data": 1, "write_i2c_block_data": 1,
}
TWO_ARG_ONLY = {"read", "write"}  # file.read(n) / stream.write(text) take one
REGISTER_NAMES = {r.name for r in registers.REGISTERS if not r.name.startswith("RESERVED")}
REGISTER_VARIABLES = {"register", "reg", "register_address", "address_reg"}


def _is_int(node: ast.AST) -> bool:
    return (isinstance(node, ast.Constant) and isinstance(node.value, int)
            and not isinstance(node.value, bool))


def _register_call(node: ast.AST) -> bool:
    if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)):
        return False
    name = node.func.attr
    if name not in REGISTER_ARG:
        return False
    return not (name in TWO_ARG_ONLY and len(node.args) != 2)


def typed_registers(source: str, where: str) -> list[str]:
    """Every place in ``source`` that types a register address or field mask as a number."""
    found = []
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if _register_call(node):
            assert isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
            index = REGISTER_ARG[node.func.attr]
            if len(node.args) > index and _is_int(node.args[index]):
                found.append(f"{where}:{node.lineno}: register typed as a number in "
                             f"{node.func.attr}()")
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitAnd):
            sides = (node.left, node.right)
            if any(_register_call(s) for s in sides) and any(_is_int(s) for s in sides):
                found.append(f"{where}:{node.lineno}: field mask typed as a number")
        elif (isinstance(node, ast.Compare) and isinstance(node.left, ast.Name)
              and node.left.id in REGISTER_VARIABLES and any(_is_int(c) for c in node.comparators)):
            found.append(f"{where}:{node.lineno}: {node.left.id} compared with a typed address")
    for node in tree.body + [n for c in tree.body if isinstance(c, ast.ClassDef) for n in c.body]:
        if not isinstance(node, ast.Assign):
            continue
        for target in node.targets:
            names = target.elts if isinstance(target, ast.Tuple) else [target]
            values = node.value.elts if isinstance(node.value, ast.Tuple) else [node.value]
            for name, value in zip(names, values):
                if not (isinstance(name, ast.Name) and _is_int(value)):
                    continue
                if name.id in REGISTER_NAMES or name.id.endswith("_REGISTER"):
                    found.append(f"{where}:{node.lineno}: {name.id} typed as a number")
    return found


def test_no_register_address_or_mask_is_typed_outside_the_table():
    problems = []
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        if rel in TABLE_FILES:
            continue
        problems += typed_registers(path.read_text(encoding="utf-8"), rel)
    assert problems == []


def test_the_check_flags_each_kind_and_leaves_bus_protocol_numbers_alone():
    bad = (
        "RANGE = 0x0F\n"
        "SPI3_REGISTER, SPI3_BIT = 0x34, 0x01\n"
        "def f(chip, bus, register):\n"
        "    chip.peek(0x10)\n"
        "    bus.read_i2c_block_data(0x68, 0x02, 6)\n"
        "    x = chip.peek(BW) & 0x07\n"
        "    if register == 0x10:\n"
        "        pass\n"
    )
    assert [p.split(": ", 1)[0] for p in typed_registers(bad, "m.py")] == [
        "m.py:4", "m.py:5", "m.py:6", "m.py:7", "m.py:1", "m.py:2",
    ]
    fine = (
        "READ_FLAG = 0x80\n"
        "def g(spi, handle, byte, bus):\n"
        "    spi.xfer2([0x80 | reg])\n"
        "    handle.read(65536)\n"
        "    address = byte & 0x7F\n"
        "    bus.read_i2c_block_data(0x68, RATE_X_LSB, 6)\n"
    )
    assert typed_registers(fine, "ok.py") == []
