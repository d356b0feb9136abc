"""The UML kernel's build inputs: patches that apply to Debian's source and say why, a
config fragment whose dropped lines are named, a cache key that follows every input, and
the one-line refusal of a host whose FPU state does not fit."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from bmg160_emu.linux.guest import uml, uml_build
from bmg160_emu.linux.guest.engine import EngineError


def test_every_patch_has_a_licence_and_a_reason() -> None:
    patches = uml_build.patches()
    assert patches
    for patch in patches:
        head, _, body = patch.read_text().partition("\n--- a/")
        assert head.startswith("SPDX-License-Identifier: GPL-2.0\n"), patch.name
        assert len(head.split()) > 30, f"{patch.name}: the note on why is missing"
        assert body, f"{patch.name}: no diff"


def _built_tree() -> Path | None:
    kernel = uml_build.find_kernel()
    return None if kernel is None else kernel.tree


@pytest.mark.skipif(_built_tree() is None, reason="no UML build in the cache")
@pytest.mark.skipif(shutil.which("patch") is None, reason="patch absent")
def test_the_built_tree_carries_exactly_the_patches() -> None:
    # Reversing each patch on the built tree (a dry run) succeeds only if the patch applied
    # there as it is: the cache holds what the patch files say.
    tree = _built_tree()
    for patch in uml_build.patches():
        result = subprocess.run(["patch", "-p1", "--reverse", "--dry-run", "-i", str(patch)],
                                cwd=tree, capture_output=True, text=True, check=False)
        assert result.returncode == 0, result.stdout + result.stderr
    offsets = (tree / "arch/x86/um/user-offsets.c").read_text()
    assert f"DEFINE_LONGS(HOST_FP_SIZE, {uml_build.FP_AREA_BYTES})" in offsets


def test_a_config_line_kconfig_dropped_is_named(tmp_path: Path) -> None:
    fragment = [line for line in uml_build.CONFIG_FRAGMENT.read_text().splitlines()
                if line.startswith("CONFIG_")]
    config = tmp_path / ".config"
    config.write_text("\n".join(fragment) + "\n")
    uml_build._check_config(config)  # all there: no error
    dropped = "CONFIG_BMG160=m"
    config.write_text("\n".join(line for line in fragment if line != dropped) + "\n")
    number = uml_build.CONFIG_FRAGMENT.read_text().splitlines().index(dropped) + 1
    with pytest.raises(EngineError, match=rf"uml.config:{number}: {dropped} was dropped"):
        uml_build._check_config(config)


def test_the_cache_key_follows_the_source_version_and_each_input(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    key = uml_build.build_key("6.1.176-1")
    assert uml_build.build_key("6.1.176-1") == key
    assert uml_build.build_key("6.1.170-3") != key
    fragment = tmp_path / "uml.config"
    fragment.write_text(uml_build.CONFIG_FRAGMENT.read_text() + "CONFIG_KCOV=y\n")
    monkeypatch.setattr(uml_build, "CONFIG_FRAGMENT", fragment)
    assert uml_build.build_key("6.1.176-1") != key


def test_a_host_fpu_state_larger_than_the_kernels_room_is_one_line() -> None:
    assert uml.xsave_problem(2432, uml_build.FP_AREA_BYTES) is None  # AMD EPYC, AVX-512
    assert uml.xsave_problem(11008, uml_build.FP_AREA_BYTES) is None  # Intel with AMX
    assert uml.xsave_problem(None, uml_build.FP_AREA_BYTES) is None  # cannot tell: try
    line = uml.xsave_problem(16384, uml_build.FP_AREA_BYTES)
    assert line is not None and "\n" not in line
    assert "16384" in line and str(uml_build.FP_AREA_BYTES) in line


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc absent")
def test_the_xsave_probe_reads_the_cpus_area(tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BMG160_EMU_CACHE", str(tmp_path))
    size = uml.host_xsave_bytes()
    assert size is not None
    # The legacy region (512) plus the XSAVE header (64) is the least an XSAVE area holds
    # (Intel SDM vol. 1, 13.4); AVX-512 with AMX tiles tops out near 11 KB.
    assert 576 <= size <= 16384


def test_an_interrupted_build_goes_on_where_it_stopped(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    root = tmp_path / "uml-key"
    tree = root / uml_build.SOURCE_PACKAGE
    (tree / "include" / "config").mkdir(parents=True)
    (tree / "include" / "config" / "kernel.release").write_text("6.1.176\n")
    (tree / "init").mkdir()
    (tree / "init" / "main.o").write_text("")  # what make had compiled when it was stopped
    for mark in ("unpacked", "configured"):
        (root / mark).write_text("")
    commands: list[list[str]] = []
    monkeypatch.setattr(uml_build, "_run", lambda command, *a, **k: commands.append(command))
    said: list[str] = []
    uml_build._build_locked(root, "6.1.176-1", said.append)
    # nothing unpacked, patched or configured again: make goes on from its objects
    assert [c[:2] for c in commands] == [["make", "ARCH=um"], ["make", "ARCH=um"]]
    assert "linux" in commands[0] and "modules_install" in commands[1][-1]
    assert said[0] == f"uml: resuming the unfinished build in {root}"
    assert f"about {uml_build.BUILD_OBJECTS - 1:,} files to compile (1 already built" in said[1]
    assert (root / "ready").exists() and (tree / "init" / "main.o").exists()
    # a build stopped while unpacking starts over
    shutil.rmtree(root)
    (root / "half").mkdir(parents=True)
    commands.clear()
    with pytest.raises(FileNotFoundError):  # (tar is not run here: no tree appears)
        uml_build._build_locked(root, "6.1.176-1", said.append)
    assert commands[0][0] == "tar" and not (root / "half").exists()


def test_the_builds_progress_says_how_much_is_left_and_for_how_long() -> None:
    assert uml_build._progress_line(200, 0, 60.0, 0.0) == "uml: 200 files compiled"
    assert uml_build._progress_line(200, 800, 60.0, 240.0) == (
        "uml: 200 of 800 files compiled (25 %), about 3 min 0 s left")
    assert uml_build._progress_line(790, 800, 300.0, 240.0).endswith("about 4 s left")
