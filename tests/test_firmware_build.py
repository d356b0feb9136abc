"""Building the firmware: the generated header, memory use, the command and its errors."""

from __future__ import annotations

import re

import pytest
from _firmware_backends import firmware_skip_reason, require_firmware_build

from bmg160_emu import cli
from bmg160_emu.device.registers import BY_NAME, REGISTERS, RESET_VALUES, WRITE_MASKS
from bmg160_emu.firmware import build as build_mod
from bmg160_emu.firmware import register_table
from bmg160_emu.firmware.params_header import (
    BW_ODR_HZ,
    render_params_header,
    unapplied_output_note,
)
from bmg160_emu.firmware.register_table import FIRMWARE_REGISTERS
from bmg160_emu.noise.discretization import axis_coefficients
from bmg160_emu.noise.profile import load_profile

pytestmark = pytest.mark.firmware


def _floats(header: str, name: str) -> list[float]:
    body = re.search(rf"{name}\[8\]\[3\] PROGMEM = \{{(.*?)\}};", header, re.DOTALL).group(1)
    return [float(v.rstrip("f")) for v in re.findall(r"-?[0-9.]+(?:e-?[0-9]+)?f", body)]


def test_firmware_register_table_is_the_project_register_table():
    assert [r.reset for r in FIRMWARE_REGISTERS] == list(RESET_VALUES[:0x40])
    assert [r.write_mask for r in FIRMWARE_REGISTERS] == list(WRITE_MASKS[:0x40])
    # what the firmware does is said for every spec register, by a name the table has
    assert set(register_table._KINDS) <= set(BY_NAME)
    for reg in REGISTERS:
        assert reg.reserved or reg.name in register_table._KINDS, reg.name


def test_generated_register_header_defines_every_register_and_field():
    header = register_table.render_registers_header()
    for reg in REGISTERS:
        if not reg.reserved:
            assert f"#define BMG_REG_{reg.name} 0x{reg.address:02X}\n" in header
        for f in reg.fields:
            assert f"#define BMG_{reg.name}_{f.name.upper()}_MASK 0x{f.mask:02X}\n" in header


def test_the_header_carries_the_decoded_register_address_bits_of_the_spec_choice(monkeypatch):
    # spec 2.4: the firmware takes the model's choice, so a correction of it reaches both
    from bmg160_emu.device import spec_choices

    assert "#define BMG_REGISTER_ADDRESS_MASK 0x7F\n" in register_table.render_registers_header()
    monkeypatch.setattr(spec_choices, "REGISTER_ADDRESS_MASK", 0xFF)
    assert "#define BMG_REGISTER_ADDRESS_MASK 0xFF\n" in register_table.render_registers_header()


def test_header_carries_the_discretization_of_the_noise_engine_for_every_bw_code():
    header = render_params_header(profile="paper", mode="physical")
    axes = load_profile("paper").axes
    white = _floats(header, "bmg_noise_white")
    rw = _floats(header, "bmg_noise_rw_step")
    for code, odr in enumerate(BW_ODR_HZ):
        for i, axis in enumerate(axes):
            expected = axis_coefficients(axis, odr, "physical")
            assert white[3 * code + i] == pytest.approx(expected.white_std, rel=1e-8)
            assert rw[3 * code + i] == pytest.approx(expected.rw_step, rel=1e-8)


def test_paper_mode_header_uses_the_paper_white_std_at_200_hz():
    header = render_params_header(profile="paper", mode="paper")
    code_200hz = BW_ODR_HZ.index(200.0)
    # sigma_N = 0.249334 deg/s at 200 Hz (docs/noise-model.md, paper eq. 16)
    assert _floats(header, "bmg_noise_white")[3 * code_200hz] == pytest.approx(0.249334, abs=2e-6)


def test_header_sets_the_i2c_address_and_refuses_others():
    assert "#define BMG_I2C_ADDRESS 0x69" in render_params_header(address=0x69)
    with pytest.raises(ValueError, match="0x68 .*0x69"):
        render_params_header(address=0x6A)


def test_profile_with_quantization_noise_is_refused(tmp_path):
    text = "\n".join(
        f"[{a}]\nN = 0.01\nB = 0.001\nT = 10.0\nK = 0.0001\nbias = 0.0\nQ = 0.001" for a in "xyz"
    )
    path = tmp_path / "q.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match="Q or R"):
        render_params_header(profile=str(path))


def test_sine_terms_are_refused_and_an_output_stage_is_named(tmp_path):
    # the firmware makes white, Gauss-Markov and random-walk noise, unfiltered: a sine term
    # it would drop is an error; a sensor filter it cannot apply is said, not dropped unseen
    axes = "\n".join(
        f"[{a}]\nN = 0.01\nB = 0.001\nT = 10.0\nK = 0.0001\nbias = 0.0" for a in "xyz"
    )
    path = tmp_path / "p.toml"
    path.write_text(axes.replace("bias = 0.0", "bias = 0.0\nsine = [{ A = 0.002, f = 1.3 }]"))
    with pytest.raises(ValueError, match="sine terms"):
        render_params_header(profile=str(path))
    path.write_text(axes)
    assert unapplied_output_note(str(path)) is None
    path.write_text("[output]\norder = 2\ncorner_hz = 40.0\nrate_hz = 200.0\n" + axes)
    assert "bmg_noise_white" in render_params_header(profile=str(path))
    assert "no filter model" in unapplied_output_note(str(path))


def test_build_fits_the_atmega328p_with_room_for_the_stack():
    build = require_firmware_build(profile="paper", seed=11)
    assert build.elf.is_file() and build.hex.is_file()
    assert build.hex.read_text().startswith(":")
    assert 0 < build.flash_bytes <= build_mod.ATMEGA328P_FLASH
    # the deepest call chain (TWI interrupt over a float computation) needs < 256 bytes
    assert build.ram_bytes <= build_mod.ATMEGA328P_SRAM - 256


def test_build_command_writes_header_and_hex(tmp_path, capsys):
    if firmware_skip_reason():
        pytest.skip(firmware_skip_reason())
    status = cli.main(["firmware", "build", "--profile", "paper", "--address", "0x69",
                       "--out", str(tmp_path)])  # fmt: skip
    assert status == 0
    assert "BMG_I2C_ADDRESS 0x69" in (tmp_path / "bmg160_params.h").read_text()
    assert (tmp_path / "bmg160.hex").is_file()
    assert "flash:" in capsys.readouterr().out


def test_build_command_without_gcc_avr_gives_a_clear_error(monkeypatch, capsys, tmp_path):
    monkeypatch.setattr(build_mod.shutil, "which", lambda tool: None)
    status = cli.main(["firmware", "build", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert status == 2
    assert "avr-gcc" in err and "gcc-avr" in err and "Traceback" not in err


def test_build_command_rejects_a_bad_address(capsys):
    assert cli.main(["firmware", "build", "--address", "sixty"]) == 2
    assert "--address" in capsys.readouterr().err
