"""How MicroPython's and CircuitPython's C cores take arguments and report bus failures.

Why one module: the drop-ins (``machine``, ``busio``) must refuse and accept what a board
refuses and accepts, and CPython's own conversions differ (``int(1.5)`` is 1, a ``str`` has
no buffer): a driver that passes a float length or a str buffer would pass on a PC and fail
on the board. The rules here follow the cores' sources:

- an integer argument goes through ``mp_obj_get_int`` (py/obj.c): bools and ints, a float
  or a str is ``TypeError: can't convert float to int``, an int beyond the port's machine
  word (32-bit ports: the ESP32, the RP2040) ``OverflowError: overflow converting long int
  to machine word``;
- a buffer goes through ``mp_get_buffer_raise`` (py/obj.c): anything with the buffer
  protocol, and a ``str`` for reading (its UTF-8 bytes, py/objstr.c); a str, or a read-only
  buffer, where one is written into is ``TypeError: object with buffer protocol required``;
- a buffer of ``n`` bytes the port allocates (``readfrom``, ``readfrom_mem``) is
  ``vstr_init_len(n)``: ``n + 1`` bytes from the heap, ``MemoryError: memory allocation
  failed, allocating N bytes`` past it; a negative ``n`` wraps to a huge length over a
  1-byte buffer, which overruns a board's memory instead of raising, so the drop-in stops
  the program there with a sentence that says so;
- a failed transfer is ``OSError`` with the port's errno: ENODEV (19) when nobody
  acknowledges the address, ETIMEDOUT (110) for a timeout, EIO (5) for any other failure
  (the ESP32 port's machine.I2C and SoftI2C; CircuitPython's busio on the RP2040).
"""

from __future__ import annotations

import errno
from typing import Any

__all__ = ["MACHINE_WORD_BITS", "allocate", "get_int", "micropython_error", "read_buffer",
           "write_buffer"]

MACHINE_WORD_BITS = 32  # mp_int_t on the 32-bit ports the drop-ins stand for
_NO_ACK = (errno.EREMOTEIO, errno.ENXIO, errno.ENODEV)  # an address nobody acknowledges


def get_int(value: Any) -> int:
    """``mp_obj_get_int``: bools and ints; TypeError for anything else, OverflowError
    beyond a 32-bit machine word."""
    if isinstance(value, int):  # bool is an int
        number = int(value)
    else:
        index = getattr(type(value), "__index__", None)
        if index is None or isinstance(value, (float, str, bytes)):
            raise TypeError(f"can't convert {type(value).__name__} to int")
        number = int(index(value))
    limit = 1 << (MACHINE_WORD_BITS - 1)
    if not -limit <= number < limit:
        raise OverflowError("overflow converting long int to machine word")
    return number


def read_buffer(value: Any) -> bytes:
    """``mp_get_buffer_raise(..., MP_BUFFER_READ)``: the bytes of a buffer or of a str."""
    if isinstance(value, str):
        return value.encode("utf-8")
    try:
        return memoryview(value).cast("B").tobytes()
    except TypeError:
        raise TypeError("object with buffer protocol required") from None


def write_buffer(value: Any) -> memoryview:
    """``mp_get_buffer_raise(..., MP_BUFFER_WRITE)``: a writable buffer's bytes."""
    try:
        view = memoryview(value)
    except TypeError:
        raise TypeError("object with buffer protocol required") from None
    if view.readonly:
        raise TypeError("object with buffer protocol required")
    return view.cast("B")


def allocate(length: int, heap_bytes: int | None, where: str) -> int:
    """The length of a buffer the port allocates for ``length`` bytes (vstr_init_len):
    MemoryError past the heap; a negative length stops the program (see the module)."""
    if length < 0:
        wrapped = length % (1 << MACHINE_WORD_BITS)
        raise ValueError(
            f"{where}: a length of {length} wraps to {wrapped} bytes on the board, read into "
            "a 1-byte buffer (vstr_init_len): MicroPython overruns its heap there instead of "
            "raising; the emulator stops the program")
    if heap_bytes is not None and length + 1 > heap_bytes:
        raise MemoryError(f"memory allocation failed, allocating {length + 1} bytes")
    return length


def micropython_error(exc: OSError) -> OSError:
    """The OSError the ports raise for a failed transfer (``OSError: [Errno 19] ENODEV``)."""
    code = errno.ENODEV if exc.errno in _NO_ACK else (
        errno.ETIMEDOUT if exc.errno == errno.ETIMEDOUT else errno.EIO)
    return OSError(code, errno.errorcode[code])
