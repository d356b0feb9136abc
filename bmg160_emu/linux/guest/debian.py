"""Debian's own kernel, headers and sources, fetched with ``apt-get download`` and unpacked
with ``dpkg -x`` into the cache: no system install, nothing from outside the registries.

Why Debian's kernel: it boots under QEMU in seconds and ships the bmg160 driver and
i2c-stub as modules (linux-kernel-notes.md). Its ``linux-headers`` build out-of-tree modules
for it, and ``linux-source-6.1`` of the same version gives the sources of the drivers its
configuration leaves out (i2c-virtio, gpio-virtio, the IIO software triggers).
"""

from __future__ import annotations

import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

from bmg160_emu.linux.guest.cache import cache_dir
from bmg160_emu.linux.guest.engine import EngineError, Progress


@dataclass(frozen=True)
class GuestKernel:
    """An unpacked Debian kernel package: the image and its module tree."""

    root: Path  # the dpkg -x folder
    version: str  # the kernel release, 6.1.0-50-amd64

    @property
    def vmlinuz(self) -> Path:
        return self.root / "boot" / f"vmlinuz-{self.version}"

    @property
    def modules(self) -> Path:
        return self.root / "lib" / "modules" / self.version

    @property
    def major(self) -> str:
        """6.1: the linux-source and linux-kbuild packages' suffix."""
        return ".".join(self.version.split(".")[:2])

    def module_path(self, name: str) -> Path:
        for candidate in (name, name.replace("-", "_"), name.replace("_", "-")):
            hits = list(self.modules.rglob(f"{candidate}.ko"))
            if hits:
                return hits[0]
        raise FileNotFoundError(f"module {name} not in {self.modules}")


def find_kernel(cache: Path | None = None) -> GuestKernel | None:
    """The unpacked kernel in the cache, or None if it was never prepared."""
    root = (cache or cache_dir()) / "kernel" / "root"
    versions = sorted((root / "lib" / "modules").glob("*")) if root.exists() else []
    for moddir in reversed(versions):
        kernel = GuestKernel(root, moddir.name)
        if kernel.vmlinuz.exists() and (kernel.modules / "modules.dep").exists():
            return kernel
    return None


def _run(command: list[str], cwd: Path | None = None) -> None:
    result = subprocess.run(command, cwd=cwd, capture_output=True, text=True, check=False)
    if result.returncode:
        detail = (result.stderr or result.stdout).strip().splitlines()
        raise EngineError(f"{' '.join(command)} failed: {detail[-1] if detail else result.returncode}")


def prepare_kernel(cache: Path | None = None, progress: Progress = lambda _: None) -> GuestKernel:
    """Download Debian's current amd64 kernel package and unpack it (once)."""
    kernel = find_kernel(cache)
    if kernel:
        return kernel
    for tool, package in (("apt-cache", "apt"), ("dpkg", "dpkg"), ("depmod", "kmod")):
        if shutil.which(tool) is None:
            raise EngineError(f"{tool} is missing (Debian package {package})")
    work = (cache or cache_dir()) / "kernel"
    work.mkdir(parents=True, exist_ok=True)
    deps = subprocess.run(["apt-cache", "depends", "linux-image-amd64"],
                          capture_output=True, text=True, check=False).stdout
    names = [ln.split()[-1] for ln in deps.splitlines() if "Depends: linux-image-" in ln]
    if not names:
        raise EngineError("apt-cache names no linux-image package (run apt-get update)")
    debs = list(work.glob(f"{names[0]}_*.deb"))
    if not debs:
        progress(f"downloading {names[0]} (apt-get download)")
        _run(["apt-get", "download", "-q", names[0]], cwd=work)
        debs = list(work.glob(f"{names[0]}_*.deb"))
    progress(f"unpacking {debs[0].name}")
    _run(["dpkg", "-x", str(debs[0]), str(work / "root")])
    version = names[0].removeprefix("linux-image-")
    _run(["depmod", "-b", str(work / "root"), version])
    kernel = find_kernel(cache)
    if kernel is None:
        raise EngineError(f"unpacking {debs[0]} gave no usable kernel")
    return kernel


def package_version(kernel: GuestKernel) -> str:
    """The Debian version of the unpacked kernel package (6.1.176-1), from its file name."""
    kernel_dir = kernel.root.parent
    debs = sorted(kernel_dir.glob(f"linux-image-{kernel.version}_*.deb"))
    if not debs:
        raise EngineError(f"no linux-image-{kernel.version} package in {kernel_dir}")
    return debs[-1].name.split("_")[1]


def build_tree(kernel: GuestKernel, cache: Path | None = None,
               progress: Progress = lambda _: None) -> Path:
    """linux-source, linux-headers (arch + common) and linux-kbuild of the kernel's version,
    unpacked once; returns the root they were unpacked into."""
    version = package_version(kernel)
    work = (cache or cache_dir()) / "kbuild" / version
    root = work / "root"
    stamp = work / "unpacked"
    if stamp.exists():
        return root
    work.mkdir(parents=True, exist_ok=True)
    common = kernel.version.rsplit("-", 1)[0] + "-common"
    packages = [f"linux-source-{kernel.major}", f"linux-headers-{kernel.version}",
                f"linux-headers-{common}", f"linux-kbuild-{kernel.major}"]
    for package in packages:
        if not list(work.glob(f"{package}_{version}_*.deb")):
            progress(f"downloading {package}={version} (apt-get download)")
            _run(["apt-get", "download", "-q", f"{package}={version}"], cwd=work)
        deb = next(work.glob(f"{package}_{version}_*.deb"))
        progress(f"unpacking {deb.name}")
        _run(["dpkg", "-x", str(deb), str(root)])
    # the headers' top Makefile includes the common tree by its installed path: point it
    # at the unpacked one (linux-kernel-notes.md)
    makefile = headers_dir(kernel, root)
    (makefile / "Makefile").write_text(
        f"include {root}/usr/src/linux-headers-{common}/Makefile\n")
    stamp.write_text(version + "\n")
    return root


def headers_dir(kernel: GuestKernel, tree: Path) -> Path:
    """The folder ``make -C`` builds external modules in (``M=``)."""
    return tree / "usr/src" / f"linux-headers-{kernel.version}"


def source_tarball(kernel: GuestKernel, tree: Path) -> Path:
    return tree / "usr/src" / f"linux-source-{kernel.major}.tar.xz"
