"""A command that needs an optional package names the extra that brings it, in one line.

Each case runs the command in a fresh interpreter where the package cannot be imported
(``sys.modules[name] = None``: import raises ModuleNotFoundError, as on a core install).
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import pytest

from bmg160_emu.commands._extras import EXTRA_OF_MODULE, extra_for, missing_message

if sys.version_info >= (3, 11):
    import tomllib
else:  # the core's own dependency on 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parent.parent
SCENARIOS = ROOT / "examples" / "scenarios"

# import name -> the distribution an extra lists for it
DISTRIBUTION = {
    "scipy": "scipy", "allantools": "allantools", "matplotlib": "matplotlib", "tqdm": "tqdm",
    "dask": "dask", "distributed": "dask", "Basilisk": "bsk", "rich": "rich", "gi": "PyGObject",
}


def _without(hidden: tuple[str, ...], argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """``bmg160-emu ARGV`` with the packages ``hidden`` unimportable."""
    code = textwrap.dedent(
        f"""
        import sys
        for name in {hidden!r}:
            sys.modules[name] = None
        from bmg160_emu.cli import main
        sys.exit(main({argv!r}))
        """
    )
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True,
                          text=True, timeout=300, check=False)


def _one_line_error(result: subprocess.CompletedProcess) -> str:
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    errors = [line for line in result.stderr.splitlines() if ": error: " in line]
    assert len(errors) == 1, result.stderr
    return errors[0]


def _record(tmp_path: Path) -> Path:
    out = tmp_path / "rest.csv"
    result = subprocess.run([sys.executable, "-m", "bmg160_emu", "record", "--duration", "2s",
                             "--seed", "1", "-o", str(out)], capture_output=True, text=True,
                            timeout=120, check=False)
    assert result.returncode == 0, result.stderr
    return out


def test_identify_without_allantools_names_the_noise_extra(tmp_path):
    line = _one_line_error(_without(("allantools",), ["identify", str(_record(tmp_path))],
                                    tmp_path))
    assert line == ("bmg160-emu identify: error: identify needs the [noise] extra "
                    "(allantools): pip install 'bmg160-emu[noise]'")


def test_identify_without_scipy_names_the_noise_extra(tmp_path):
    line = _one_line_error(_without(("scipy",), ["identify", str(_record(tmp_path))], tmp_path))
    assert line.endswith("identify needs the [noise] extra (scipy): pip install "
                         "'bmg160-emu[noise]'")


def test_generate_through_a_filter_without_scipy_names_the_noise_extra(tmp_path):
    argv = ["generate", "--duration", "2s", "--seed", "1", "--bandwidth", "2", "-o", "n.npy"]
    line = _one_line_error(_without(("scipy",), argv, tmp_path))
    assert "generate needs the [noise] extra (scipy)" in line
    assert not (tmp_path / "n.npy").exists()


def test_generate_without_a_filter_needs_no_extra(tmp_path):
    argv = ["generate", "--duration", "2s", "--seed", "1", "--raw", "-o", "n.npy"]
    result = _without(("scipy", "tqdm", "allantools", "matplotlib"), argv, tmp_path)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "n.npy").stat().st_size > 0


def test_montecarlo_without_dask_runs_in_process_and_says_so(tmp_path):
    argv = ["montecarlo", str(SCENARIOS / "rest.toml"), "--runs", "2"]
    result = _without(("dask", "distributed", "tqdm"), argv, tmp_path)
    assert result.returncode == 0, result.stderr
    assert "(--scheduler sync)" in result.stderr
    assert "pip install 'bmg160-emu[montecarlo]'" in result.stderr
    assert re.search(r"^\s+\d+\.\d+(\s+\d+\.\d+){4}$", result.stdout, re.MULTILINE)


def test_montecarlo_local_scheduler_without_dask_names_the_extra_and_sync(tmp_path):
    argv = ["montecarlo", str(SCENARIOS / "rest.toml"), "--runs", "2", "--scheduler", "local"]
    line = _one_line_error(_without(("dask", "distributed"), argv, tmp_path))
    assert line.endswith("--scheduler local needs the [montecarlo] extra (Dask): pip install "
                         "'bmg160-emu[montecarlo]', or --scheduler sync")


def test_montecarlo_tumble_without_scipy_names_the_montecarlo_extra(tmp_path):
    argv = ["montecarlo", str(SCENARIOS / "detumble.toml"), "--runs", "1", "--scheduler", "sync"]
    line = _one_line_error(_without(("scipy",), argv, tmp_path))
    assert line.endswith("montecarlo needs the [montecarlo] extra (scipy): pip install "
                         "'bmg160-emu[montecarlo]'")


@pytest.mark.parametrize("command, module, extra", [
    ("identify", "scipy.optimize", "noise"), ("generate", "tqdm", "noise"),
    ("montecarlo", "distributed.client", "montecarlo"), ("watch", "rich.live", "watch"),
    ("run", "gi.repository", "umockdev"), ("record", "Basilisk.architecture", "basilisk"),
])
def test_each_optional_package_maps_to_its_extra(command, module, extra):
    assert extra_for(command, module) == extra
    assert missing_message(command, module).endswith(f"pip install 'bmg160-emu[{extra}]'")


def test_a_module_no_extra_brings_is_not_taken_for_an_install_choice():
    assert missing_message("identify", "bmg160_emu.noise.nothing") is None
    assert missing_message("dump", "numpy") is None


def test_every_extra_named_in_an_error_lists_the_package():
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))[
        "project"]["optional-dependencies"]
    for module, extra in EXTRA_OF_MODULE.items():
        names = {re.split(r"[\[<>=;! ]", req, maxsplit=1)[0] for req in extras[extra]}
        assert DISTRIBUTION[module] in names, (module, extra)


def test_the_core_depends_on_numpy_and_smbus2_only():
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))[
        "project"]["dependencies"]
    names = {re.split(r"[\[<>=;! ]", req, maxsplit=1)[0] for req in deps}
    assert names == {"numpy", "smbus2", "tomli"}


def test_watch_without_rich_names_the_watch_extra(tmp_path, monkeypatch):
    from bmg160_emu.device.chip import BMG160
    from bmg160_emu.watch.session import WatchServer

    folder = Path(tempfile.mkdtemp(prefix="bmgx", dir="/tmp"))  # short: a socket path
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(folder))
    try:
        with WatchServer({0x68: BMG160(seed=1)}, [], title="test") as server:
            line = _one_line_error(_without(("rich",), ["watch", "--socket", str(server.path)],
                                            tmp_path))
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    assert line == ("bmg160-emu watch: error: watch needs the [watch] extra (rich): "
                    "pip install 'bmg160-emu[watch]'")
