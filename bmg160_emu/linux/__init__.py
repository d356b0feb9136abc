"""The Linux routes: the chip behind a real kernel or another process's /dev/i2c-N.

umockdev (a virtual /dev/i2c-N for unmodified programs), the kernel's i2c-stub adapter,
and the vhost-user back ends of virtio-i2c and virtio-gpio that a guest kernel's own drivers
talk to, with the guest-paced clock. Built on the in-process buses of ``bmg160_emu.bus``;
submodules are imported on demand (umockdev needs PyGObject, which is optional).
"""
