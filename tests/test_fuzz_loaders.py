"""Every loader against mutated files (issue 12): a usable load or the format's own one-line
error, never another exception and never a hang (tests/_fuzz_formats.py has the registry and
the mutations; `python tools/fuzz.py --examples N` runs a long campaign).

The CI budget: 60 mutated files per format, derandomised so a failure reproduces. The
campaign in the closing note ran 5000 per format."""

from __future__ import annotations

import pytest
from _fuzz_formats import FORMATS, mutate, try_load
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

EXAMPLES_PER_FORMAT = 60


@pytest.mark.parametrize("fmt", FORMATS, ids=[f.name for f in FORMATS])
def test_mutated_files_load_or_raise_the_formats_own_error(fmt, tmp_path_factory):
    folder = tmp_path_factory.mktemp(fmt.name)

    @settings(max_examples=EXAMPLES_PER_FORMAT, derandomize=True, deadline=None,
              database=None, suppress_health_check=list(HealthCheck))
    @given(st.integers(min_value=0, max_value=2**32 - 1))
    def check(seed: int) -> None:
        data, applied = mutate(fmt, seed)
        outcome = try_load(fmt, data, folder)
        assert outcome.kind in ("loaded", "format error"), (
            f"{fmt.name}, mutation seed {seed} ({'+'.join(applied)}): {outcome.detail}; "
            f"rerun: python tools/fuzz.py --format {fmt.name} --first-seed {seed} --examples 1")

    check()


def test_the_seed_files_themselves_load():
    # the mutations start from valid files: if these did not load, every mutation would be
    # a format error and the test above could not fail
    from pathlib import Path

    from _fuzz_formats import seed_folder

    for fmt in FORMATS:
        fmt.load(seed_folder() / fmt.seed)
    assert Path(seed_folder()).is_dir()
