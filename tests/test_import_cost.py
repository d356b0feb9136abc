"""Start-up cost of the chip path: what it imports, checked in a fresh interpreter.

Start-up time itself is measured by tools/bench_cold_start.py (against ``import numpy`` in
the same run); these tests check its cause, which a timing cannot pin down: the chip and the
fake bus must not pull in the heavy scientific and plotting packages that only
identification, plots and the tools need.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

# Packages the chip path must not import: seconds of start-up between them (scipy.signal
# alone is about 0.6 s on an idle machine), and none of them does anything for a read.
HEAVY = ("scipy", "matplotlib", "allantools", "tqdm", "pandas", "dask", "unittest")


def _imported_after(code: str) -> set[str]:
    """Names of the modules in sys.modules after running ``code`` in a fresh interpreter."""
    script = textwrap.dedent(code) + textwrap.dedent(
        """
        import json, sys
        print(json.dumps(sorted(sys.modules)))
        """
    )
    result = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=False
    )
    assert result.returncode == 0, result.stderr
    return set(json.loads(result.stdout.splitlines()[-1]))


def _heavy(modules: set[str]) -> list[str]:
    return sorted(set(HEAVY) & {name.partition(".")[0] for name in modules})


def test_the_low_pass_filter_needs_no_scipy() -> None:
    modules = _imported_after(
        """
        import numpy as np
        from bmg160_emu.noise.lowpass import LowPass
        f = LowPass(200, 23.0)
        f.run(np.ones((2000, 3)), np.ones((2, 3)))
        """
    )
    assert _heavy(modules) == []


def test_the_bus_layer_needs_nothing_heavy() -> None:
    modules = _imported_after(
        """
        import bmg160_emu.bus.i2c, bmg160_emu.bus.smbus, bmg160_emu.traffic.transaction
        """
    )
    assert _heavy(modules) == []


def test_a_noise_profile_loads_without_the_generator() -> None:
    """noise/__init__ is lazy: the firmware header and identification read profiles without
    loading the generator (and whatever the generator imports)."""
    modules = _imported_after(
        """
        from bmg160_emu.noise.profile import load_profile
        load_profile("paper")
        """
    )
    assert "bmg160_emu.noise.engine" not in modules
    assert _heavy(modules) == []


def test_a_chip_read_through_fake_smbus_imports_nothing_heavy() -> None:
    modules = _imported_after(
        """
        import bmg160_emu
        chip = bmg160_emu.BMG160(seed=1)
        chip.advance(0.01)
        chip.read(2, 6)
        bus = bmg160_emu.FakeSMBus(1, devices={0x68: chip})
        bus.read_i2c_block_data(0x68, 0x02, 6)
        """
    )
    assert _heavy(modules) == []


def test_a_chip_read_imports_no_logging_resources_or_archives() -> None:
    # issue 26: importlib.resources (with tempfile, zipfile, shutil, lzma) and logging were
    # ~15 % of a cold chip; the built-in profiles are read from the package folder and the
    # loggers are looked up when they have something to say
    modules = _imported_after(
        """
        import bmg160_emu
        c = bmg160_emu.BMG160(seed=1)
        c.advance(0.01)
        c.read(2, 6)
        """
    )
    unwanted = {"logging", "importlib.resources", "tempfile", "zipfile", "shutil", "lzma"}
    assert sorted(unwanted & modules) == []
