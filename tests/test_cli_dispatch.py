"""The bmg160-emu dispatcher: every command registers, user errors are one line, pipes close quietly."""

import subprocess
import sys

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
