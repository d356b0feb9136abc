"""The bmg160-emu dispatcher: every command registers, user errors are one line, pipes close quietly."""

import subprocess
import sys

import pytest

from bmg160_emu import cli


def test_every_command_module_registers_a_command_with_help():
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    names = set(sub.choices)
    assert {"demo", "generate", "identify", "run", "stub", "dump", "script", "trace"} <= names
    for name, command in sub.choices.items():
        assert command.format_help().strip(), name


def test_no_command_prints_help_and_exits_2(capsys):
    assert cli.main([]) == 2
    assert "usage: bmg160-emu" in capsys.readouterr().out


def test_a_reader_closing_the_pipe_ends_the_command_quietly():
    # `bmg160-emu demo | head -1`: 3000 samples (~180 kB) overflow the pipe buffer, so the
    # demo is still printing when head has gone.
    proc = subprocess.run(
        f"{sys.executable} -m bmg160_emu demo --samples 3000 | head -1",
        shell=True,
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.stdout.startswith("BMG160 at 0x68")
    assert "error" not in proc.stderr.lower()
    assert "Traceback" not in proc.stderr


def test_help_names_a_command_s_options_and_refuses_an_unknown_one(capsys):
    # issue 35: there was no help subcommand
    from bmg160_emu.cli import main

    assert main(["help", "record"]) == 0
    assert "usage: bmg160-emu record" in capsys.readouterr().out
    assert main(["help"]) == 0
    assert "bmg160-emu help COMMAND" in capsys.readouterr().out
    with pytest.raises(SystemExit) as exc:
        main(["help", "recrod"])
    assert exc.value.code == 2 and "no command 'recrod'" in capsys.readouterr().err


def test_a_mistyped_option_is_told_with_the_command_s_usage(capsys):
    # issue 35: `demo --sed 3` printed the top-level usage
    from bmg160_emu.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["demo", "--sed", "3"])
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert err.startswith("usage: bmg160-emu demo") and "unrecognized arguments: --sed 3" in err
