"""Every sub-command is added through one helper and reports errors through one type."""

from __future__ import annotations

import argparse
import ast
from pathlib import Path

from bmg160_emu import cli

COMMANDS = Path(__file__).resolve().parents[1] / "bmg160_emu" / "commands"


def test_every_command_parser_comes_from_add_command_parser():
    offenders = []
    for path in sorted(COMMANDS.glob("*.py")):
        if path.name == "_common.py":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                    and node.func.attr == "add_parser" and isinstance(node.func.value, ast.Name)
                    and node.func.value.id == "subparsers"):
                offenders.append(f"{path.name}:{node.lineno}")
    assert offenders == []


def test_every_command_has_a_summary_a_description_and_examples_as_written():
    parser = cli.build_parser()
    actions = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    commands = actions[0].choices
    # one sub-command per module of commands/, plus `help`, which lives in the dispatcher
    # (it prints another command's help, and no command may import cli)
    modules = {p.stem.replace("_", "-") for p in COMMANDS.glob("*.py") if not p.name.startswith("_")}
    assert set(commands) == modules | {"help"}
    for name, sub in commands.items():
        assert sub.description and sub.epilog, name
        assert sub.formatter_class is argparse.RawDescriptionHelpFormatter, name

