"""Bus front ends: they turn SMBus, I2C, SPI and Linux i2c-dev operations into the chip's
primitives (docs/architecture.md). Submodules are imported on demand: the umockdev one needs
PyGObject, which is optional."""
