"""The user-mode Linux kernel of the ``uml`` engine, built once from Debian's
``linux-source-6.1`` into the cache (``uml-<hash>``; about 3.5 min on 2 cores).

Why a build of our own: Debian's ``user-mode-linux`` package has no I2C_VIRTIO, GPIOLIB or
BMG160 and no headers to build modules against (linux-kernel-notes.md, "User-mode Linux").
The folder's name hashes everything that shapes the result (the source package's version,
``uml/uml.config``, the patches in ``uml/``; the i2c-virtio module, patched as for the QEMU has its own small folder), so a change gives a new folder and nothing stale is reused;
a ``ready`` file written last marks a finished build. i2c-virtio is built out of tree against the tree, as for the
QEMU route, instead of patching Kconfig: its menu depends on HAS_IOMEM, which UML lacks, and
a module needs no kernel change and takes the same source and patch as the other route.
"""

from __future__ import annotations

import fcntl
import json
import os
import re
import shutil
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

from bmg160_emu.linux.guest.cache import cache_dir, content_hash
from bmg160_emu.linux.guest.engine import EngineError, Progress
from bmg160_emu.linux.guest.user_modules import keep_modules, module_sources

SOURCE_PACKAGE = "linux-source-6.1"
SOURCE_TARBALL = Path("/usr/src/linux-source-6.1.tar.xz")
DATA = Path(__file__).with_name("uml")
CONFIG_FRAGMENT = DATA / "uml.config"
# The modules built out of tree, from the QEMU route's folder: the i2c-virtio patch (waits
# uninterruptibly) and the board module (the chips' IRQs from virtio-gpio lines).
MODULE_SOURCES = Path(__file__).with_name("module_sources")
I2C_VIRTIO_PATCH = MODULE_SOURCES / "i2c-virtio-wait.patch"
BOARD_SOURCE = MODULE_SOURCES / "bmg160-board.c"
# The FP register area patch 0001 makes room for, in bytes; hosts with a larger XSAVE
# area (CPUID leaf 0xD) cannot run user space under this kernel.
FP_AREA_BYTES = 12288
# What a build from nothing compiles (``*.o`` files of linux and the modules, counted in a
# finished tree of this configuration) and its wall time on 2 quiet cores: the progress
# lines' total and first estimate (docs/kernel-engines.md, "The kernel build").
BUILD_OBJECTS = 950
BUILD_QUIET_S = 240
# Debian packages the build runs (make, gcc, patch, xz for the tarball, the kernel's own
# build tools) and the source itself.
BUILD_PACKAGES = {
    "make": "make",
    "gcc": "gcc",
    "patch": "patch",
    "xz": "xz-utils",
    "bc": "bc",
    "flex": "flex",
    "bison": "bison",
}
# Debian packages whose files the build needs, with a file that shows each is there.
BUILD_FILES = {
    "libelf-dev": Path("/usr/include/gelf.h"),
    SOURCE_PACKAGE: SOURCE_TARBALL,
}


@dataclass(frozen=True)
class UmlKernel:
    """A finished build: the ``linux`` binary, its modules and its build tree."""

    root: Path  # the uml-<hash> folder

    @property
    def tree(self) -> Path:
        """The configured and built source tree (``make ARCH=um M=...`` builds against it)."""
        return self.root / SOURCE_PACKAGE

    @property
    def binary(self) -> Path:
        return self.tree / "linux"

    @property
    def modules_root(self) -> Path:
        """INSTALL_MOD_PATH: holds lib/modules/<release> with modules.dep and modules.builtin."""
        return self.root / "modroot"

    @property
    def vio(self) -> Path:
        """The out-of-tree modules (i2c-virtio.ko, bmg160-board.ko), in a folder named by
        their sources' hash."""
        sources = [p for p in (I2C_VIRTIO_PATCH, BOARD_SOURCE) if p.exists()]
        return self.root / f"vio-{content_hash(sources, 'vio')}"

    @property
    def i2c_virtio(self) -> Path:
        return self.vio / "i2c-virtio.ko"

    @property
    def board(self) -> Path:
        return self.vio / "bmg160-board.ko"

    @property
    def facts(self) -> dict[str, object]:
        """What the ``ready`` file recorded: release, fp_area_bytes, source version."""
        return dict(json.loads((self.root / "ready").read_text()))

    @property
    def release(self) -> str:
        return str(self.facts["release"])


def patches() -> list[Path]:
    """The kernel patches, applied in name order."""
    return sorted(DATA.glob("*.patch"))


def source_version() -> str | None:
    """The installed linux-source-6.1's Debian version, or None."""
    try:
        out = subprocess.run(
            ["dpkg-query", "-W", "-f=${Version}", SOURCE_PACKAGE],
            capture_output=True, text=True, check=False,
        )
    except FileNotFoundError:
        return None
    return out.stdout.strip() or None if out.returncode == 0 else None


def build_key(version: str) -> str:
    """The hash naming the build folder."""
    return content_hash([CONFIG_FRAGMENT, *patches()], version, f"fp={FP_AREA_BYTES}")


def build_root(version: str | None = None) -> Path | None:
    """Where the build for the installed source goes (None without the source)."""
    version = version or source_version()
    return None if version is None else cache_dir() / f"uml-{build_key(version)}"


def find_kernel() -> UmlKernel | None:
    """The finished build for the installed source and our inputs, or None."""
    root = build_root()
    if root is None or not (root / "ready").exists():
        return None
    return UmlKernel(root)


def missing_packages() -> list[str]:
    """Debian packages the build needs and this host lacks."""
    lacking = [pkg for cmd, pkg in BUILD_PACKAGES.items() if shutil.which(cmd) is None]
    lacking += [pkg for pkg, path in BUILD_FILES.items() if not path.exists()]
    return lacking


def _run(command: list[str], cwd: Path, log: Path, progress: Progress | None = None,
         total: int = 0, estimate_s: float = 0.0) -> None:
    """Run a build step, its output to ``log``; with ``progress``, a line every 200 compiled
    files, with ``total`` (the files the step compiles, 0 if not known) and what is left of
    ``estimate_s`` (its wall seconds on a quiet 2-core host) told from the rate so far."""
    env = dict(os.environ, LC_ALL="C")
    started = time.monotonic()
    with log.open("a") as sink:
        sink.write(f"$ {' '.join(command)}\n")
        sink.flush()
        proc = subprocess.Popen(
            command, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
        )
        assert proc.stdout is not None
        compiled = 0
        for line in proc.stdout:
            sink.write(line)
            if progress is not None and line.lstrip().startswith("CC"):
                compiled += 1
                if compiled % 200 == 0:
                    progress(_progress_line(compiled, total, time.monotonic() - started,
                                            estimate_s))
        if proc.wait() != 0:
            raise EngineError(f"uml build failed in {cwd}: {' '.join(command)} (log: {log})")


def _progress_line(compiled: int, total: int, elapsed_s: float, estimate_s: float) -> str:
    """``uml: 400 of 1,850 files compiled (22 %), about 3 min 10 s left``: the time left from
    this build's own rate once it has one, else from the quiet-host estimate."""
    if not total:
        return f"uml: {compiled} files compiled"
    done = min(compiled, total)
    left_s = (elapsed_s / done * (total - done)) if elapsed_s > 0 else estimate_s
    minutes, seconds = divmod(round(left_s), 60)
    left = f"{minutes} min {seconds} s" if minutes else f"{seconds} s"
    return (f"uml: {compiled:,} of {total:,} files compiled ({100 * done // total} %), "
            f"about {left} left")


def _check_config(config: Path) -> None:
    """Every line of the fragment must survive olddefconfig (a dropped one is silent): a
    ``CONFIG_X=v`` line as it is, a ``# CONFIG_X is not set`` line as X not set."""
    built = set(config.read_text().splitlines())
    for number, line in enumerate(CONFIG_FRAGMENT.read_text().splitlines(), 1):
        unset = re.fullmatch(r"# (CONFIG_\w+) is not set", line)
        if unset and any(b.startswith(f"{unset.group(1)}=") for b in built):
            raise EngineError(
                f"{CONFIG_FRAGMENT}:{number}: {unset.group(1)} was set by the kernel's Kconfig")
        if line.startswith("CONFIG_") and line not in built:
            raise EngineError(
                f"{CONFIG_FRAGMENT}:{number}: {line} was dropped by the kernel's Kconfig"
            )


def _kernel_release(tree: Path) -> str:
    return (tree / "include" / "config" / "kernel.release").read_text().strip()


def build(progress: Progress) -> UmlKernel:
    """Build the kernel into the cache unless it is there (one build at a time: a lock)."""
    lacking = missing_packages()
    if lacking:
        raise EngineError("uml build needs: apt-get install " + " ".join(lacking))
    version = source_version() or "unknown"
    root = build_root(version)
    assert root is not None
    root.parent.mkdir(parents=True, exist_ok=True)
    with open(root.parent / f"{root.name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if (root / "ready").exists():
            kernel = UmlKernel(root)
            progress(f"uml: kernel ready in {root}")
        else:
            kernel = _build_locked(root, version, progress)
        if not (kernel.vio / "ready").exists():
            _build_vio(kernel, progress)
        return kernel


def _build_locked(root: Path, version: str, progress: Progress) -> UmlKernel:
    """Unpack, patch, configure, build, install; a step already done in ``root`` (an
    interrupted build) is not done again, and make goes on from the objects it left."""
    kernel = UmlKernel(root)
    tree = kernel.tree
    log = root / "build.log"
    unpacked = root / "unpacked"  # the tree is whole and patched
    if not unpacked.exists():
        if root.exists():
            shutil.rmtree(root)  # stopped while unpacking or patching: that is redone
        root.mkdir(parents=True)
        progress(f"uml: unpacking {SOURCE_TARBALL} ({version}) into {root}")
        _run(["tar", "-xf", str(SOURCE_TARBALL)], root, log)
        for patch in patches():
            progress(f"uml: applying {patch.name}")
            _run(["patch", "-p1", "--forward", "-i", str(patch)], tree, log)
        unpacked.write_text("")
    else:
        progress(f"uml: resuming the unfinished build in {root}")
    configured = root / "configured"
    if not configured.exists():
        progress("uml: configuring (defconfig + uml.config)")
        _run(["make", "ARCH=um", "defconfig"], tree, log)
        _run(["scripts/kconfig/merge_config.sh", "-m", ".config", str(CONFIG_FRAGMENT)],
             tree, log)
        _run(["make", "ARCH=um", "olddefconfig"], tree, log)
        _check_config(tree / ".config")
        configured.write_text("")
    jobs = f"-j{os.cpu_count() or 1}"
    done = sum(1 for _ in tree.rglob("*.o"))
    left = max(BUILD_OBJECTS - done, 0)
    progress(f"uml: building linux and modules: about {left:,} files to compile "
             f"({done:,} already built; about {BUILD_QUIET_S // 60} min on 2 quiet cores "
             "from nothing)")
    _run(["make", "ARCH=um", jobs, "linux", "modules"], tree, log, progress,
         total=left, estimate_s=BUILD_QUIET_S * left / BUILD_OBJECTS)
    _run(["make", "ARCH=um", f"INSTALL_MOD_PATH={kernel.modules_root}", "modules_install"],
         tree, log)
    facts = {
        "release": _kernel_release(tree),
        "source_version": version,
        "fp_area_bytes": FP_AREA_BYTES,
    }
    (root / "ready").write_text(json.dumps(facts, indent=1) + "\n")
    progress(f"uml: kernel {facts['release']} ready in {root}")
    return kernel


def _build_vio(kernel: UmlKernel, progress: Progress) -> None:
    """i2c-virtio from the same source, and the board module, out of tree (about 10 s)."""
    progress("uml: building i2c-virtio and bmg160-board out of tree")
    outside = kernel.vio
    if outside.exists():
        shutil.rmtree(outside)
    outside.mkdir()
    log = outside / "build.log"
    shutil.copy(kernel.tree / "drivers" / "i2c" / "busses" / "i2c-virtio.c", outside)
    shutil.copy(BOARD_SOURCE, outside)
    (outside / "Kbuild").write_text("obj-m := i2c-virtio.o bmg160-board.o\n")
    if I2C_VIRTIO_PATCH.exists():
        text = re.sub(r"drivers/i2c/busses/", "", I2C_VIRTIO_PATCH.read_text())
        (outside / I2C_VIRTIO_PATCH.name).write_text(text)
        _run(["patch", "-p1", "--forward", "-i", I2C_VIRTIO_PATCH.name], outside, log)
    _run(["make", "ARCH=um", "-C", str(kernel.tree), f"M={outside}", "modules"], outside, log)
    (outside / "ready").write_text("")


def user_module(kernel: UmlKernel, path: Path, progress: Progress) -> list[Path]:
    """The ``.ko`` files of a user's module for this kernel: ``path`` itself, or what its
    source folder (with a Kbuild or Makefile) builds with ARCH=um against the tree, once per
    content of the folder's files and kernel build."""
    sources = module_sources(path)
    if path.is_file():
        return sources
    key = content_hash(sources, kernel.root.name, *(str(p.relative_to(path)) for p in sources))
    out = kernel.root / "user-modules" / f"{path.resolve().name}-{key}"
    built = sorted(out.glob("*.ko"))
    if built:
        return built
    progress(f"uml: building {path} against {kernel.tree}")
    build = out.with_name(out.name + ".build")
    if build.exists():
        shutil.rmtree(build)
    shutil.copytree(path, build, ignore=shutil.ignore_patterns("*.o", "*.ko", ".*.cmd"))
    log = build / "build.log"
    _run(["make", "ARCH=um", "-C", str(kernel.tree), f"M={build}", "modules"], build, log)
    kept = keep_modules(build, out, path)
    shutil.rmtree(build)
    return kept


if __name__ == "__main__":  # .ci/setup.d/uml.sh
    print(build(lambda line: print(line, flush=True)).root)
