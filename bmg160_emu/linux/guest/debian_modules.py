"""Out-of-tree kernel modules, built against the guest kernel's own headers and cached by
the content of their sources.

Two kinds. The **bundled** set fills what Debian's 6.1 configuration leaves out
(linux-kernel-notes.md): ``i2c-virtio`` (with ``module_sources/i2c-virtio-wait.patch``: the 6.1 driver
waits interruptibly, and a signal then frees requests the device still owns: slab
corruption), ``gpio-virtio`` (with ``module_sources/gpio-virtio-force-irq.patch``: QEMU 7.2's
vhost-user-gpio-pci never offers VIRTIO_GPIO_F_IRQ), the IIO software triggers
(``industrialio-sw-trigger``, ``industrialio-configfs``, ``iio-trig-hrtimer``) and our
``bmg160-board`` (a bmg160 client with its IRQ). Sources come from ``linux-source-6.1`` of
the kernel's own version. A **user** module is a ``.ko`` (used as it is) or a folder with a
``Kbuild`` file (built with ``make -C <headers> M=<copy>``; every ``.ko`` it makes is kept).
"""

from __future__ import annotations

import shutil
import subprocess
import tarfile
import tempfile
from pathlib import Path

from bmg160_emu.linux.guest.cache import cache_dir, content_hash
from bmg160_emu.linux.guest.debian import (
    GuestKernel,
    build_tree,
    headers_dir,
    prepare_kernel,
    source_tarball,
)
from bmg160_emu.linux.guest.engine import EngineError, Progress
from bmg160_emu.linux.guest.user_modules import keep_modules, module_sources

MODULE_SOURCES = Path(__file__).resolve().parent / "module_sources"
PATCHES = (MODULE_SOURCES / "gpio-virtio-force-irq.patch", MODULE_SOURCES / "i2c-virtio-wait.patch")
BOARD = MODULE_SOURCES / "bmg160-board.c"

# source file in linux-source-6.1 -> module name
SOURCES = {
    "drivers/i2c/busses/i2c-virtio.c": "i2c-virtio",
    "drivers/gpio/gpio-virtio.c": "gpio-virtio",
    "drivers/iio/industrialio-sw-trigger.c": "industrialio-sw-trigger",
    "drivers/iio/industrialio-configfs.c": "industrialio-configfs",
    "drivers/iio/trigger/iio-trig-hrtimer.c": "iio-trig-hrtimer",
}
MODULES = [*SOURCES.values(), "bmg160-board"]
TOOLS = (("make", "make"), ("gcc", "gcc"), ("patch", "patch"), ("xz", "xz-utils"))


def tools_missing() -> list[str]:
    """Build tools this host lacks, one line each with its Debian package."""
    return [f"{tool} is missing (Debian package {package})"
            for tool, package in TOOLS if shutil.which(tool) is None]


def extract_sources(kernel: GuestKernel, tree: Path, paths: list[str], target: Path) -> None:
    """Copy ``paths`` (relative to the kernel tree) from linux-source's tarball, flat."""
    tarball = source_tarball(kernel, tree)
    wanted = {f"linux-source-{kernel.major}/{path}": path for path in paths}
    found = 0
    with tarfile.open(tarball) as archive:
        for member in archive:
            if member.name in wanted:
                extracted = archive.extractfile(member)
                if extracted is None:
                    continue
                (target / Path(wanted[member.name]).name).write_bytes(extracted.read())
                found += 1
                if found == len(wanted):
                    return
    missing = [p for p in paths if not (target / Path(p).name).exists()]
    raise EngineError(f"{tarball} lacks {', '.join(missing)}")


def _make(kernel: GuestKernel, tree: Path, build: Path) -> None:
    result = subprocess.run(
        ["make", "-s", "-C", str(headers_dir(kernel, tree)), f"M={build}", "modules"],
        check=False, capture_output=True, text=True)
    if result.returncode:
        lines = [ln for ln in (result.stderr + result.stdout).splitlines() if ln.strip()]
        errors = [ln for ln in lines if "error" in ln.lower()] or lines
        raise EngineError(f"module build in {build} failed: {errors[0] if errors else '?'}")


def bundled_dir(cache: Path | None = None) -> Path | None:
    """The folder of the bundled modules for the cached kernel, or None if not built yet."""
    from bmg160_emu.linux.guest.debian import find_kernel

    kernel = find_kernel(cache)
    if kernel is None:
        return None
    out = (cache or cache_dir()) / f"kmod-{kernel.version}-{_bundled_key(kernel)}"
    return out if all((out / f"{m}.ko").exists() for m in MODULES) else None


def _bundled_key(kernel: GuestKernel) -> str:
    return content_hash([*PATCHES, BOARD], kernel.version, *SOURCES, length=8)


def build_bundled(cache: Path | None = None, progress: Progress = lambda _: None) -> Path:
    """Build (once) and return the folder holding every module of :data:`MODULES`."""
    ready = bundled_dir(cache)
    if ready is not None:
        return ready
    missing = tools_missing()
    if missing:
        raise EngineError("; ".join(missing))
    kernel = prepare_kernel(cache, progress)
    tree = build_tree(kernel, cache, progress)
    out = (cache or cache_dir()) / f"kmod-{kernel.version}-{_bundled_key(kernel)}"
    progress(f"building {', '.join(MODULES)} against linux-headers-{kernel.version}")
    with tempfile.TemporaryDirectory() as tmp:
        build = Path(tmp)
        extract_sources(kernel, tree, list(SOURCES), build)
        for patch in PATCHES:  # a/drivers/<dir>/<file>: the sources sit flat in build/
            strip = len(Path(patch.read_text().split("\n--- ", 1)[1].split()[0]).parts) - 1
            subprocess.run(["patch", "-s", f"-p{strip}", "-i", str(patch)], cwd=build,
                           check=True)
        shutil.copy2(BOARD, build / BOARD.name)
        (build / "Kbuild").write_text("".join(f"obj-m += {name}.o\n" for name in MODULES))
        _make(kernel, tree, build)
        out.mkdir(parents=True, exist_ok=True)
        for name in MODULES:
            shutil.copy2(build / f"{name}.ko", out / f"{name}.ko")
    return out


def user_module(path: Path, cache: Path | None = None,
                progress: Progress = lambda _: None) -> list[Path]:
    """The ``.ko`` files of a user's module: ``path`` itself, or what its source folder
    builds (once per content of the folder's files and kernel version)."""
    sources = module_sources(path)
    if path.is_file():
        return sources
    missing = tools_missing()
    if missing:
        raise EngineError("; ".join(missing))
    kernel = prepare_kernel(cache, progress)
    key = content_hash(sources, kernel.version, *(str(p.relative_to(path)) for p in sources))
    out = (cache or cache_dir()) / "user-modules" / f"{path.resolve().name}-{key}"
    built = sorted(out.glob("*.ko"))
    if built:
        return built
    tree = build_tree(kernel, cache, progress)
    progress(f"building {path} against linux-headers-{kernel.version}")
    with tempfile.TemporaryDirectory() as tmp:
        build = Path(tmp) / path.resolve().name
        shutil.copytree(path, build, ignore=shutil.ignore_patterns("*.o", "*.ko", ".*.cmd"))
        _make(kernel, tree, build)
        return keep_modules(build, out, path)
