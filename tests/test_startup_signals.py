"""A ^C in the package's very first import (issue 35's start-up window, narrowed).

bmg160_emu/__init__.py imports bmg160_emu.startup, whose hold_signals() installs the
command's SIGINT handler; a SIGINT while that module itself loads (about 0.6 ms) raised
KeyboardInterrupt with a traceback out of the package (``tools/fuzz.py --signals``,
montecarlo-dask-json seed 7800004, SIGINT at 0.020 s). The test makes that moment
certain: a sitecustomize raises KeyboardInterrupt when bmg160_emu.startup is first looked
up, as the signal would."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

INTERRUPT_FIRST_LOOKUP = """
import sys

class _InterruptOnce:
    fired = False

    def find_spec(self, name, path=None, target=None):
        if name == "bmg160_emu.startup" and not _InterruptOnce.fired:
            _InterruptOnce.fired = True
            raise KeyboardInterrupt
        return None

sys.meta_path.insert(0, _InterruptOnce())
"""


@pytest.fixture
def interrupting_env(tmp_path):
    (tmp_path / "sitecustomize.py").write_text(INTERRUPT_FIRST_LOOKUP)
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(tmp_path), env.get("PYTHONPATH")) if p)
    return env


def test_the_command_answers_a_sigint_during_its_first_import_with_its_one_line(
        interrupting_env, tmp_path):
    done = subprocess.run([sys.executable, "-m", "bmg160_emu", "--version"], check=False,
                          env=interrupting_env, cwd=tmp_path, capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 130, done.stderr
    assert "Traceback" not in done.stderr
    assert done.stderr.strip().splitlines() == [
        "bmg160-emu: interrupted by SIGINT while starting; nothing written"]
    assert done.stdout == ""


def test_a_program_importing_the_package_gets_its_keyboardinterrupt(interrupting_env, tmp_path):
    done = subprocess.run([sys.executable, "-c", "import bmg160_emu"], check=False,
                          env=interrupting_env, cwd=tmp_path, capture_output=True, text=True,
                          timeout=60)
    # an uncaught KeyboardInterrupt: CPython prints it and dies of SIGINT (-2) or exits 1
    assert done.returncode in (1, -2), done.stderr
    assert done.stderr.strip().splitlines()[-1] == "KeyboardInterrupt"
