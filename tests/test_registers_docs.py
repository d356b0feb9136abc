"""The register map in the docs is the register table's own rendering."""

from pathlib import Path

from bmg160_emu.device.registers import REGISTERS, markdown_table

DOC = Path(__file__).resolve().parents[1] / "docs" / "device-model.md"


def test_device_model_page_embeds_the_current_register_table():
    text = DOC.read_text(encoding="utf-8")
    start = text.index("<!-- register-map:start -->\n") + len("<!-- register-map:start -->\n")
    end = text.index("<!-- register-map:end -->")
    assert text[start:end] == markdown_table()


def test_markdown_table_has_one_row_per_register():
    rows = [line for line in markdown_table().splitlines() if line.startswith("| 0x")]
    assert len(rows) == len(REGISTERS) == 64
