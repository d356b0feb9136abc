"""The core install as a driver author gets it: the wheel with no extras, in a fresh venv.

Builds the wheel, installs it (numpy and smbus2 from the package index, as pip does for a
user) with pytest into a new virtual environment outside the checkout, runs a driver's
test that uses the plugin's fixtures there, and checks that no extra's package came along
and that the venv stays small. Minutes and network: marked slow (``pytest --all``).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

# Generous: the core measured 102 MB (numpy 2.x ~70 MB, pip ~13 MB, docs/install.md), pytest
# adds ~5 MB; allantools' documentation tool chain alone added ~200 MB before issue 26.
CEILING_MB = 200

DRIVER_TEST = textwrap.dedent(
    """
    import time

    import pytest
    import smbus2


    @pytest.mark.bmg160(noise=False, true_rate=(10.0, 0.0, -5.0))
    def test_a_driver_reads_the_chip_id_and_the_rate(bmg160_smbus, bmg160_virtual_sleep):
        bus = smbus2.SMBus(1)
        assert bus.read_byte_data(0x68, 0x00) == 0x0F  # CHIP_ID
        bus.write_byte_data(0x68, 0x14, 0xB6)  # soft reset
        time.sleep(0.1)
        raw = bus.read_i2c_block_data(0x68, 0x02, 6)
        x = int.from_bytes(bytes(raw[0:2]), "little", signed=True) / 16.384
        z = int.from_bytes(bytes(raw[4:6]), "little", signed=True) / 16.384
        assert x == pytest.approx(10.0, abs=0.1)
        assert z == pytest.approx(-5.0, abs=0.1)
    """
)

EXTRAS_PACKAGES = ("scipy", "allantools", "matplotlib", "tqdm", "dask", "rich", "sphinx")


def _run(argv: list[str], cwd: Path, timeout: float) -> subprocess.CompletedProcess:
    # nothing from the checkout: the venv's own bmg160_emu, not a PYTHONPATH one
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    result = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True,
                            timeout=timeout, check=False)
    assert result.returncode == 0, f"{argv}\n{result.stdout[-2000:]}{result.stderr[-2000:]}"
    return result


@pytest.mark.slow
def test_the_core_wheel_runs_a_driver_test_in_a_fresh_venv(tmp_path):
    print("building the wheel, then a fresh venv with it and pytest (network, ~1 min)")
    dist = tmp_path / "dist"
    _run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", str(ROOT), "-w",
          str(dist)], tmp_path, 600)
    shutil.rmtree(ROOT / "build", ignore_errors=True)  # setuptools' leftovers in the checkout
    wheel = next(dist.glob("bmg160_emu-*.whl"))
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", str(venv)], tmp_path, 300)
    python = str(venv / "bin" / "python")
    _run([python, "-m", "pip", "install", "--quiet", str(wheel), "pytest"], tmp_path, 900)

    listed = _run([python, "-m", "pip", "list", "--format=freeze"], tmp_path, 120).stdout
    installed = {line.split("==")[0].lower() for line in listed.splitlines()}
    assert {"numpy", "smbus2", "bmg160-emu"} <= installed
    assert [p for p in EXTRAS_PACKAGES if p in installed] == []

    project = tmp_path / "driver"
    project.mkdir()
    (project / "test_driver.py").write_text(DRIVER_TEST, encoding="utf-8")
    ran = _run([python, "-m", "pytest", "-q", "-p", "no:cacheprovider"], project, 300)
    assert "1 passed" in ran.stdout
    demo = _run([str(venv / "bin" / "bmg160-emu"), "demo"], project, 120)
    assert "CHIP_ID = 0x0F" in demo.stdout

    size_mb = int(_run(["du", "-sm", str(venv)], tmp_path, 120).stdout.split()[0])
    print(f"core venv with pytest: {size_mb} MB (ceiling {CEILING_MB} MB)")
    assert size_mb < CEILING_MB
