"""The in-process buses: SMBus, I2C and SPI operations turned into the chip's primitives.

``I2CBus`` (the adapter, with the kernel's I2C and SMBus semantics of ``kernel_abi`` and
``i2c_dev``), ``FakeSMBus`` and ``FakeSpiDev``, ``patch_smbus`` and ``patch_spidev``, and the
transaction log every front end records (docs/architecture.md). The routes through a real
kernel or another process live in ``bmg160_emu.linux``.
"""
