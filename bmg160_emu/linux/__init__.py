"""Linux front ends: a umockdev ``/dev/i2c-N`` for unmodified programs, and the i2c-stub
adapter that keeps a real kernel's i2c-stub memory in step with the model for kernel drivers.

Submodules are imported on demand: the umockdev one needs PyGObject, which is optional.
"""
