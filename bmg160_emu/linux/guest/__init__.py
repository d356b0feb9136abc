"""Disposable Linux guests for the kernel routes: engines, the kernel from Debian's packages,
out-of-tree modules, and the harness that boots a guest beside the back ends.

One idea per module: :mod:`.engine` (what every engine offers), :mod:`.cache` (where
downloads and builds live), :mod:`.debian` (kernel packages), :mod:`.initramfs` (the
guest's first user space), :mod:`.kmod` (out-of-tree modules), :mod:`.qemu` (the QEMU
engine), :mod:`.harness` (boot, back ends, run, collect). Engines are found by
:func:`.engine.engines`; submodules are imported on demand.
"""
