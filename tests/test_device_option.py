"""--part and --device NAME@ADDRESS[:BUS] on the chip-building commands, trace headers that
carry parts and stand-ins, the seed chosen when --seed is absent, and rigs with stand-ins."""

from __future__ import annotations

import argparse
import json
import re

import pytest

from bmg160_emu.cli import main
from bmg160_emu.commands._chip_options import (
    add_chip_options,
    buses_from_args,
    chips_from_args,
    configs_from_args,
    header_from_chip_args,
)
from bmg160_emu.commands._common import CommandError
from bmg160_emu.device.config import ChipConfig
from bmg160_emu.device.parts import PART_NAMES
from bmg160_emu.device.standin import StandinConfig, StandinDevice
from bmg160_emu.io.trace import TraceFormatError, TraceHeader, read_trace

SEED_LINE = re.compile(r"^bmg160-emu (\w+): seed (\d+) \(random; --seed \2 repeats it\)$",
                       re.MULTILINE)


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="t", exit_on_error=False)
    add_chip_options(parser, devices=True)
    return parser.parse_args(list(argv))


def usage_error(capsys, *argv: str) -> str:
    with pytest.raises(SystemExit) as info:
        main(list(argv))
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    return err


# --------------------------------------------------------------------------- parsing


def test_part_choices_are_the_part_names(capsys):
    assert parse("--part", PART_NAMES[-1]).part == PART_NAMES[-1]
    err = usage_error(capsys, "dump", "--part", "bmi999_gyro")
    assert "argument --part: invalid choice: 'bmi999_gyro'" in err
    for name in PART_NAMES:
        assert repr(name) in err


@pytest.mark.parametrize(("spec", "message"), [
    ("bmg160@0x6g", "bmg160@0x6g: not an I2C address: '0x6g'"),
    ("bmg160", "bmg160: give NAME@ADDRESS[:BUS], e.g. bmg160@0x68"),
    ("@0x68", "@0x68: give NAME@ADDRESS[:BUS]"),
    ("bmg160@0x18", "bmg160@0x18: a bmg160 answers at 0x68 or 0x69 only, not 0x18"),
    ("bmg160@0x68:x", "bmg160@0x68:x: bus must be an integer >= 0, not 'x'"),
    ("bmg160@0x80", "bmg160@0x80: I2C address must be 0x03..0x77, not 0x80"),
    ("bmm150@0x18", "bmm150@0x18: a bmm150 answers at 0x10, 0x11, 0x12, 0x13 only"),
    ("sprocket@0x18", "sprocket@0x18: unknown device 'sprocket': a part (bmg160"),
    ("nowhere/x.toml@0x18", "nowhere/x.toml@0x18: nowhere/x.toml: no such stand-in file"),
])
def test_bad_device_specs_are_one_line_usage_errors(capsys, spec, message):
    err = usage_error(capsys, "dump", "--device", spec)
    assert err.startswith("bmg160-emu dump: error: argument --device: ") and message in err, err


def test_a_bad_stand_in_file_is_named_with_its_place(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\nchip_id_register = 0\nchip_id = 1\naddresses = []\n'
                   '[registers]\n0x01 = { reset = 300 }\n')
    err = usage_error(capsys, "dump", "--device", f"{bad}@0x30")
    assert f"{bad}: [registers] 0x01: reset must be an integer 0x00..0xFF, not 300" in err


def test_addresses_and_devices_make_one_config_each_in_order():
    args = parse("--address", "0x69", "--device", "bma2x2_accel@0x18", "--device",
                 f"{PART_NAMES[0]}@0x68:2", "--range", "500", "--seed", "4")
    configs = configs_from_args(args)
    assert [type(c) for c in configs] == [ChipConfig, StandinConfig, ChipConfig]
    assert [(c.address, c.bus) for c in configs] == [(0x69, None), (0x18, None), (0x68, 2)]
    assert configs[0].setup_writes == configs[2].setup_writes != []  # gyro options: gyros only
    buses = buses_from_args(args, 1)
    assert sorted(buses) == [1, 2]
    assert isinstance(buses[1][0x18], StandinDevice)
    clocks = {id(d.clock) for b in buses.values() for d in b.values()}
    assert len(clocks) == 1  # one clock for the whole session


def test_devices_alone_replace_the_default_chip_unless_a_part_is_named():
    configs = configs_from_args(parse("--device", "bmi088_accel@0x19", "--seed", "1"))
    assert [c.address for c in configs] == [0x19]
    configs = configs_from_args(parse("--part", PART_NAMES[-1], "--device", "bmi088_accel@0x19"))
    assert [(c.address, getattr(c, "part", None)) for c in configs] == [
        (0x68, PART_NAMES[-1]), (0x19, None)]


def test_two_devices_at_one_place_are_refused():
    with pytest.raises(CommandError, match=r"--device bmg160@0x68: --address 0x68 is "
                                           "already at that address on that bus"):
        configs_from_args(parse("--address", "0x68", "--device", "bmg160@0x68"))
    with pytest.raises(CommandError, match=r"--device bmi088_accel@0x18: --device "
                                           "bma2x2_accel@0x18 is already at that address"):
        configs_from_args(parse("--device", "bma2x2_accel@0x18", "--device",
                                "bmi088_accel@0x18"))
    # the same address on another bus is another place
    assert len(configs_from_args(parse("--device", "bmg160@0x68", "--device",
                                       "bmg160@0x68:3"))) == 2


def test_a_one_bus_command_refuses_a_device_on_another_bus():
    args = parse("--device", "bmm150@0x10:4", "--seed", "1")
    args.bus = 1
    with pytest.raises(CommandError, match="a --device on bus 4 has nowhere to go"):
        chips_from_args(args)


def test_the_part_reaches_the_chip_and_its_trace_header():
    part = PART_NAMES[-1]
    args = parse("--part", part, "--device", "bmm150@0x12", "--seed", "9")
    header = header_from_chip_args(args).to_dict()
    entries = header["chips"]
    if part != "bmg160":
        assert entries[0]["part"] == part
    assert entries[1]["address"] == 0x12 and entries[1]["standin"]["name"] == "bmm150"
    rebuilt = TraceHeader.from_dict(json.loads(json.dumps(header))).build_chips()
    direct = chips_from_args(args)
    assert sorted(rebuilt) == sorted(direct) == [0x12, 0x68]
    for address, chip in direct.items():
        assert rebuilt[address].dump() == chip.dump()


def test_a_header_naming_an_unknown_part_is_refused_clearly():
    header = TraceHeader(1, [{"settings": {}, "part": "bmi999_gyro"}])
    with pytest.raises(ValueError, match="a 'bmi999_gyro', a part this version does not know"):
        header.build_chips()


def test_a_header_with_two_devices_at_one_address_on_two_buses_is_refused():
    args = parse("--device", "bmg160@0x68", "--device", "bmg160@0x68:3", "--seed", "1")
    header = TraceHeader.from_dict(header_from_chip_args(args).to_dict())
    with pytest.raises(TraceFormatError, match="two devices at 0x68 .on two buses."):
        header.build_chips()


def test_a_broken_stand_in_entry_in_a_trace_names_its_line(tmp_path):
    path = tmp_path / "t.jsonl"
    path.write_text(json.dumps({"format": "bmg160-emu trace", "version": 1, "seed": 1,
                                "chips": [{"standin": {"name": "x"}, "address": 0x18}]}) + "\n")
    with pytest.raises(TraceFormatError, match=rf"^{path}:1: header chips\[0\].standin: "
                                               "missing 'chip_id_register'"):
        read_trace(path)


# --------------------------------------------------------------------------- commands


def test_a_script_session_with_stand_ins_traces_and_replays(tmp_path, capsys):
    script = tmp_path / "bmx.script"
    script.write_text("read CHIP_ID == 0x0F\nchip 0x18\nwrite 0x14 0xB6\nread 0x00 == 0xFA\n"
                      "write 0x0F 0x05\nread 0x0F == 0x05\nchip 0x68\nadvance 10ms\n"
                      "burst RATE_X_LSB 6\n")
    trace = tmp_path / "bmx.jsonl"
    assert main(["script", str(script), "--device", "bmg160@0x68", "--device",
                 "bma2x2_accel@0x18", "--trace", str(trace), "-q", "--seed", "3"]) == 0
    _, records = read_trace(trace)
    assert {r["address"] for r in records} == {0x18, 0x68}
    assert main(["trace", str(trace), "--replay"]) == 0
    assert "no divergence: 6 transactions replayed" in capsys.readouterr().out


def test_a_script_needs_a_gyro_besides_the_stand_ins(tmp_path, capsys):
    script = tmp_path / "s.script"
    script.write_text("read 0x00 == 0xFA\n")
    assert main(["script", str(script), "--device", "bma2x2_accel@0x18", "--seed", "1"]) == 2
    assert "a script drives a gyro part" in capsys.readouterr().err


def test_dump_of_a_single_stand_in_is_exactly_i2cdump(capsys):
    assert main(["dump", "--device", "bma2x2_accel@0x19", "--seed", "1"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("     0  1  2  3") and len(out) == 17
    assert out[1].startswith("00: fa 00")


def test_dump_json_refuses_a_stand_in(capsys):
    assert main(["dump", "--device", "bmm150@0x10", "--format", "json", "--seed", "1"]) == 2
    assert "a stand-in dumps as i2cdump only" in capsys.readouterr().err


def test_stub_takes_one_device_per_process(capsys):
    assert main(["stub", "--bus", "0", "--address", "0x68", "--device", "bmg160@0x69"]) == 2
    assert "one chip address per process" in capsys.readouterr().err


# --------------------------------------------------------------------------- seeds


@pytest.mark.parametrize("argv", [
    ["dump"],
    ["demo", "--samples", "1", "--fifo-frames", "1"],
])
def test_commands_without_seed_choose_print_and_use_one(capsys, argv):
    assert main(argv) == 0
    captured = capsys.readouterr()
    found = SEED_LINE.findall(captured.err)
    assert [command for command, _ in found] == [argv[0]]
    seed = found[0][1]
    assert main([*argv, "--seed", seed]) == 0
    again = capsys.readouterr()
    assert again.out == captured.out  # the printed seed repeats the session
    assert not SEED_LINE.search(again.err)


def test_record_without_seed_stores_the_seed_it_prints(tmp_path, capsys):
    out = tmp_path / "r.csv"
    assert main(["record", "--duration", "0.05", "-o", str(out)]) == 0
    found = SEED_LINE.findall(capsys.readouterr().err)
    assert [c for c, _ in found] == ["record"]
    settings = json.loads(out.read_text().splitlines()[1].lstrip("# "))
    assert settings["seed"] == int(found[0][1])


def test_script_without_seed_writes_the_printed_seed_into_its_trace(tmp_path, capsys):
    script = tmp_path / "s.script"
    script.write_text("read CHIP_ID == 0x0F\n")
    trace = tmp_path / "s.jsonl"
    assert main(["script", str(script), "-q", "--trace", str(trace)]) == 0
    found = SEED_LINE.findall(capsys.readouterr().err)
    assert read_trace(trace)[0]["seed"] == int(found[0][1])


def test_one_gyro_sessions_offer_no_device_option(capsys):
    for command in (["record", "--duration", "1", "-o", "x.csv"], ["demo"]):
        err = usage_error(capsys, *command, "--device", "bmm150@0x10")
        assert "unrecognized arguments: --device bmm150@0x10" in err


def test_a_negative_seed_is_refused():
    # a usage error at parse time now (limits.SEED), before any chip is built
    with pytest.raises(argparse.ArgumentError, match="seed must be an integer from 0"):
        parse("--seed", "-3")


# --------------------------------------------------------------------------- rigs


def test_a_rig_puts_scenario_stand_ins_on_its_buses(tmp_path):
    from bmg160_emu.adcs.rig import GyroRig
    from bmg160_emu.adcs.scenarios import ScenarioError, load_scenario

    path = tmp_path / "bmx055.toml"
    path.write_text('duration_s = 1.0\n[[gyro]]\naddress = 0x68\npart = "bmg160"\n'
                    '[[device]]\nname = "bma2x2_accel"\naddress = 0x18\n'
                    '[[device]]\nname = "bmm150"\naddress = 0x10\nbus = 2\n')
    rig = GyroRig(load_scenario(path), seed=1)
    assert sorted(rig.buses) == [1, 2]
    assert rig.bus(1).read_byte_data(0x18, 0x00) == 0xFA
    rig.bus(2).write_byte_data(0x10, 0x4B, 0x01)
    assert rig.bus(2).read_byte_data(0x10, 0x40) == 0x32
    assert rig.standins[0].clock is rig.clock
    path.write_text('duration_s = 1.0\n[[device]]\nname = "bmm150"\naddress = 0x18\n')
    with pytest.raises(ScenarioError, match="device 1: a bmm150 answers at 0x10"):
        GyroRig(load_scenario(path), seed=1)
    path.write_text('duration_s = 1.0\n[[gyro]]\npart = "bmi999_gyro"\n')
    with pytest.raises(ScenarioError, match="part must be one of"):
        GyroRig(load_scenario(path), seed=1)


def test_a_part_gets_its_own_noise_profile_unless_one_is_given():
    from bmg160_emu.device.parts import part_table

    for part in PART_NAMES:
        (config,) = configs_from_args(parse("--part", part))
        assert config.profile == part_table(part).noise_profile
        assert header_from_chip_args(parse("--part", part, "--seed", "1")).to_dict()[
            "chips"][0]["settings"]["profile"] == config.profile
    (config,) = configs_from_args(parse("--part", "bmi088_gyro", "--profile", "paper"))
    assert config.profile == "paper"
    assert configs_from_args(parse())[0].profile == "paper"  # the bmg160 as before


def test_a_rig_gyro_of_a_part_gets_its_profile():
    from bmg160_emu.adcs.rig import GyroSpec
    from bmg160_emu.device.parts import part_table

    assert GyroSpec(part="bmi055_gyro").profile == part_table("bmi055_gyro").noise_profile
    assert GyroSpec().profile == "paper"
    assert GyroSpec(part="bmi088_gyro", profile="paper").profile == "paper"


def test_a_noiseless_session_or_a_data_replay_prints_no_seed(tmp_path, capsys):
    # nothing in them is drawn from the seed, so there is nothing to repeat
    assert main(["dump", "--no-noise"]) == 0
    assert not SEED_LINE.search(capsys.readouterr().err)
    data = tmp_path / "a.csv"
    assert main(["record", "--duration", "0.05", "--seed", "3", "-o", str(data)]) == 0
    capsys.readouterr()
    assert main(["replay", str(data), "--unit", "counts", "-o", str(tmp_path / "b.csv")]) == 0
    assert not SEED_LINE.search(capsys.readouterr().err)
