"""Standard output with no room (``> /dev/full``, a full disk): one error line, as cat and
echo give ("write error: No space left on device"), never the OSError traceback every
command printed (found by hand beside the odd-names campaign, 2026-12-06)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full here")


@pytest.mark.parametrize("argv", [["demo", "--seed", "1", "--samples", "3"],
                                  ["dump", "--seed", "1"], ["doctor"]], ids=" ".join)
def test_a_command_whose_stdout_is_full_says_so_in_one_line(argv):
    env = dict(os.environ, PYTHONPATH=str(REPO))
    with open("/dev/full", "w") as full:
        proc = subprocess.run([sys.executable, "-m", "bmg160_emu", *argv], stdout=full,
                              stderr=subprocess.PIPE, text=True, env=env, check=False,
                              stdin=subprocess.DEVNULL)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == (f"bmg160-emu {argv[0]}: error: cannot write standard output: "
                           "No space left on device\n")
