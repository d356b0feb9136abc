"""docs/test-your-driver.md runs as written: its files are written, its commands run, and the
output shown after a command is the output the command gives (test durations aside)."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

PAGE = Path(__file__).resolve().parent.parent / "docs" / "test-your-driver.md"
FENCE = re.compile(r"^```(\w+)([^\n]*)\n(.*?)^```\s*$", re.MULTILINE | re.DOTALL)
DURATION = re.compile(r" in \d+(\.\d+)?s\b")


def blocks() -> list[tuple[str, str, str]]:
    """(language, attributes, body) of every fenced block, in page order."""
    return [(m.group(1), m.group(2).strip(), m.group(3)) for m in FENCE.finditer(PAGE.read_text())]


def normalised(text: str) -> list[str]:
    return [DURATION.sub(" in Ns", line.rstrip()) for line in text.strip().splitlines()]


def test_every_block_is_a_file_a_command_or_the_output_of_the_command_before_it():
    kinds = [language for language, _, _ in blocks()]
    assert kinds.count("python") >= 2 and "sh" in kinds
    for index, (language, attributes, _) in enumerate(blocks()):
        if language == "python":
            assert re.fullmatch(r'title="[\w.]+\.py"', attributes), f"block {index}: no file name"
        elif language == "text":
            assert index > 0 and blocks()[index - 1][0] == "sh", f"block {index}: output of what?"
        else:
            assert language == "sh", f"block {index}: {language} blocks cannot be run"


def test_the_page_runs_as_written(tmp_path):
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env.pop("PYTEST_ADDOPTS", None)
    env["COLUMNS"] = "80"  # pytest pads its progress line to the terminal width
    ran = 0
    last_output = None
    for language, attributes, body in blocks():
        if language == "python":
            name = re.fullmatch(r'title="([\w.]+)"', attributes).group(1)
            (tmp_path / name).write_text(body, encoding="utf-8")
        elif language == "sh":
            last_output = ""
            for command in body.strip().splitlines():
                result = subprocess.run(
                    shlex.split(command), cwd=tmp_path, env=env, capture_output=True, text=True,
                    timeout=300, check=False,
                )  # fmt: skip
                assert result.returncode == 0, f"{command}\n{result.stdout}\n{result.stderr}"
                last_output += result.stdout
                ran += 1
        elif language == "text":
            assert normalised(last_output) == normalised(body)
    assert ran >= 1
