"""docs/pytest-plugin.md's noise table is what the chip gives now (tools/noise_per_bw.py):
a change of the noise model or of the chip's filter fails here until the page is regenerated."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_noise_table_of_the_plugin_page_is_current():
    result = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "noise_per_bw.py"), "--check",
         str(ROOT / "docs" / "pytest-plugin.md")],
        capture_output=True, text=True, check=False, timeout=300)
    assert result.returncode == 0, result.stderr


def test_the_table_shows_less_noise_at_a_narrower_filter():
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import noise_per_bw
    finally:
        sys.path.remove(str(ROOT / "tools"))
    wide, narrow = noise_per_bw.noise_std(0, samples=2000), noise_per_bw.noise_std(7, samples=2000)
    # 2000 samples: the std is known to ~2 %; the two differ by far more than that
    assert all(narrow < 0.5 * wide)
