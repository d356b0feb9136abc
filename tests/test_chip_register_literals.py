"""Register behaviour comes from the table: no register address or field mask is typed as a
number in the device model outside ``device/registers.py`` (issue 10)."""

import ast
from pathlib import Path

import bmg160_emu.device

DEVICE = Path(bmg160_emu.device.__file__).parent
# Hex numbers that are not register addresses or masks, each with its reason.
ALLOWED_HEX = {
    ("spec_choices.py", 0x68), ("spec_choices.py", 0x69),  # I2C addresses (spec 2.1)
    ("fields.py", 0xFF),  # the default "every bit" mask of a value comparison, not a field
    ("contract.py", 0xFF),  # the 8-bit register pointer range
    ("chip.py", 0x68),  # the default I2C address
    ("chip.py", 0xFF), ("register_access.py", 0xFF),  # byte range of poke, pointer saturation (2.4)
    ("regmap.py", 0xB6),  # the soft-reset command value (4.13)
    ("spec_choices.py", 0x00),  # FIFO empty tag byte value (6.5)
    ("spec_choices.py", 0xF),  # NVM cycles left at delivery (6.10), a counter value
    # a stand-in's SPI command byte: the R/W bit and the 7 address bits; an undriven line
    ("standin_spi.py", 0x80), ("standin_spi.py", 0x7F), ("standin_spi.py", 0x00),
}


def _offenders(path: Path) -> list[str]:
    source = path.read_text(encoding="utf-8")
    tree = ast.parse(source)
    found = []
    # dict keys are field codes (e.g. latch_int code -> hold time), not addresses or masks
    keys = {id(k) for node in ast.walk(tree) if isinstance(node, ast.Dict) for k in node.keys}
    for node in ast.walk(tree):
        if isinstance(node, (ast.BinOp, ast.AugAssign)) and isinstance(
                node.op, (ast.BitAnd, ast.BitOr, ast.BitXor)):
            operands = (node.left, node.right) if isinstance(node, ast.BinOp) else (node.value,)
            for operand in operands:
                # "& 1" after a shift takes the low bit of a computed value, not a field
                if isinstance(operand, ast.Constant) and isinstance(operand.value, int) \
                        and operand.value != 1:
                    found.append(f"{path.name}:{node.lineno}: bit operation with {operand.value}")
        if isinstance(node, ast.Constant) and type(node.value) is int and id(node) not in keys:
            text = ast.get_source_segment(source, node) or ""
            # a register address or an 8-bit mask fits a byte (larger hex numbers are seeds
            # and salts)
            if text.lower().startswith("0x") and node.value <= 0xFF \
                    and (path.name, node.value) not in ALLOWED_HEX:
                found.append(f"{path.name}:{node.lineno}: hex literal {text}")
    return found


def test_no_register_address_or_mask_is_typed_outside_the_table():
    modules = sorted(p for p in DEVICE.glob("*.py") if p.name != "registers.py")
    assert len(modules) >= 10  # the scan sees the model's modules
    offenders = [line for path in modules for line in _offenders(path)]
    assert not offenders, "\n".join(offenders)


def test_the_scan_finds_a_typed_mask(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text("def f(regs):\n    return regs[0x13] & 0x40 | regs[2] >> 3 & 1\n",
                      encoding="utf-8")
    assert len(_offenders(sample)) == 3  # 0x13, 0x40 and the masking with 0x40
