"""What a user installs: the license, the version it reports, the files a wheel must carry."""

from __future__ import annotations

import importlib.metadata
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_distribution_declares_the_mit_license_and_ships_the_text():
    meta = importlib.metadata.metadata("bmg160-emu")
    assert meta["License-Expression"] == "MIT"
    assert "LICENSE" in (meta.get_all("License-File") or [])
    assert (ROOT / "LICENSE").read_text(encoding="utf-8").startswith("MIT License")


def test_kernel_module_sources_carry_the_gpl_spdx_header():
    # The README's rule: a Linux kernel module is GPL-2.0 and says so on its first line.
    # Kernel code is recognised by the header every module includes.
    offenders = []
    for source in ROOT.rglob("*.[ch]"):
        if any(part in {".venv", "build", "site"} for part in source.relative_to(ROOT).parts):
            continue
        text = source.read_text(encoding="utf-8", errors="replace")
        if re.search(r"#include\s*<linux/module\.h>", text):
            first = text.splitlines()[0] if text else ""
            if "SPDX-License-Identifier: GPL-2.0" not in first:
                offenders.append(str(source.relative_to(ROOT)))
    assert offenders == []


def test_metadata_version_is_the_package_version():
    # Single source: pyproject reads bmg160_emu.__version__ (tool.setuptools.dynamic).
    import bmg160_emu

    assert importlib.metadata.version("bmg160-emu") == bmg160_emu.__version__
    assert re.fullmatch(r"\d+\.\d+\.\d+", bmg160_emu.__version__)


def test_version_option_prints_the_package_version(capsys):
    import bmg160_emu
    from bmg160_emu.cli import main

    try:
        main(["--version"])
    except SystemExit as exc:
        assert exc.code == 0
    assert capsys.readouterr().out == f"bmg160-emu {bmg160_emu.__version__}\n"


def test_changelog_top_release_is_the_package_version():
    import bmg160_emu

    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    releases = re.findall(r"^## \[([^\]]+)\]", text, flags=re.MULTILINE)
    assert releases and releases[0] == bmg160_emu.__version__


def test_a_checkout_builds_its_own_firmware_folder():
    # Editable install / source tree: no shipped copy, so the checkout's sources and its
    # firmware/build folder are used (a wheel's copy is exercised by .ci/package.sh).
    from bmg160_emu.firmware import build

    assert not (ROOT / "bmg160_emu" / "firmware" / "sources").exists()
    assert build.FIRMWARE_DIR == ROOT / "firmware"
    assert build.BUILD_ROOT == ROOT / "firmware" / "build"


def test_the_sdist_manifest_ships_the_firmware_and_the_changelog():
    manifest = (ROOT / "MANIFEST.in").read_text(encoding="utf-8").splitlines()
    assert "graft firmware" in manifest
    assert any(line.startswith("include") and "CHANGELOG.md" in line for line in manifest)


def _sh_blocks(markdown: str) -> list[list[str]]:
    return [b.strip().splitlines() for b in re.findall(r"```sh\n(.*?)```", markdown, re.DOTALL)]


def test_readme_commands_make_a_venv_and_ci_runs_the_same_test_command():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    demo, tests = _sh_blocks(readme)[:2]
    for block in (demo, tests):
        assert block[0] == "python3 -m venv .venv && . .venv/bin/activate"
    assert demo[1] == "python3 -m pip install . && bmg160-emu demo"
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    # the README's line, verbatim, plus --all (the quick default leaves long tests out); the
    # extras the long tests need ([all]) are installed before it
    assert tests[1] == "python3 -m pip install -e '.[test]' && python3 -m pytest"
    assert tests[1] + " --all" in ci
    assert ci.index("python3 -m pip install --quiet -e '.[all]'") < ci.index(tests[1] + " --all")
    assert "python3 -m venv .venv" in ci and ". .venv/bin/activate" in ci
