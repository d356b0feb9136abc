"""The default test run is the quick one; --all, BMG160_ALL_TESTS=1 and -m choose otherwise.

Each case runs pytest in a fresh interpreter on a small folder holding this suite's
conftest.py and one test per marker.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent

TESTS = '''
import pytest

def test_plain(): pass

@pytest.mark.slow
def test_slow(): pass

@pytest.mark.kernel
def test_kernel(): pass

@pytest.mark.firmware
def test_firmware(): pass

@pytest.mark.umockdev
def test_umockdev(): pass
'''

INI = """[pytest]
markers =
    slow: long
    kernel: qemu
    firmware: avr
    umockdev: umockdev
"""


@pytest.fixture
def suite(tmp_path):
    shutil.copy(HERE / "conftest.py", tmp_path / "conftest.py")
    (tmp_path / "test_markers.py").write_text(TESTS, encoding="utf-8")
    (tmp_path / "pytest.ini").write_text(INI, encoding="utf-8")
    return tmp_path


def _pytest(folder: Path, *args: str, env_all: str | None = None) -> tuple[set[str], str]:
    env = {k: v for k, v in os.environ.items() if k != "BMG160_ALL_TESTS"}
    if env_all is not None:
        env["BMG160_ALL_TESTS"] = env_all
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "-v", "-p", "no:cacheprovider", *args], cwd=folder,
        env=env, capture_output=True, text=True, timeout=120, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
    passed = set(re.findall(r"::test_(\w+) PASSED", result.stdout))
    return passed, result.stdout


def test_the_default_run_leaves_the_long_markers_out_and_says_so(suite):
    passed, out = _pytest(suite)
    assert passed == {"plain"}
    assert "4 deselected" in out
    assert "the quick suite; tests marked slow, docs, kernel, firmware, umockdev are left out" in out
    assert "4 long tests (slow, docs, kernel, firmware, umockdev) left out" in out


def test_all_runs_everything_and_says_what_each_long_test_runs(suite):
    passed, out = _pytest(suite, "--all")
    assert passed == {"plain", "slow", "kernel", "firmware", "umockdev"}
    assert "[kernel] test_markers.py::test_kernel: running a Linux guest (user-mode Linux or QEMU)..." in out
    assert "left out" not in out.split("short test summary")[-1]


def test_the_environment_variable_is_the_same_as_all(suite):
    assert _pytest(suite, env_all="1")[0] == {"plain", "slow", "kernel", "firmware",
                                              "umockdev"}
    assert _pytest(suite, env_all="0")[0] == {"plain"}


def test_an_explicit_marker_expression_chooses_by_itself(suite):
    assert _pytest(suite, "-m", "kernel")[0] == {"kernel"}
    assert _pytest(suite, "-m", "not firmware")[0] == {"plain", "slow", "kernel", "umockdev"}
