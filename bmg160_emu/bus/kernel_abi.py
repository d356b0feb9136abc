"""The Linux i2c-dev user-space ABI: ioctl numbers, flags, functionality masks and structures.

The one place these numbers are written down, named as in the kernel headers
``<linux/i2c-dev.h>`` and ``<linux/i2c.h>``, so that the adapter (``i2c_bus``), the i2c-dev
emulation (``i2c_dev``) and the i2c-stub adapter read like the kernel code they mirror.
Layouts are those of x86-64 and other LP64 ABIs. The single ``I2C_FUNC_*`` bits live with
the transaction kinds they describe (``bmg160_emu.traffic.kinds``); the masks built from
them (``I2C_FUNC_SMBUS_EMUL`` ...) are here.
"""

from __future__ import annotations

import ctypes

from bmg160_emu.traffic.kinds import (
    I2C_FUNC_SMBUS_PEC,
    I2C_FUNC_SMBUS_PROC_CALL,
    I2C_FUNC_SMBUS_QUICK,
    I2C_FUNC_SMBUS_READ_BLOCK_DATA,
    I2C_FUNC_SMBUS_READ_BYTE,
    I2C_FUNC_SMBUS_READ_BYTE_DATA,
    I2C_FUNC_SMBUS_READ_I2C_BLOCK,
    I2C_FUNC_SMBUS_READ_WORD_DATA,
    I2C_FUNC_SMBUS_WRITE_BLOCK_DATA,
    I2C_FUNC_SMBUS_WRITE_BYTE,
    I2C_FUNC_SMBUS_WRITE_BYTE_DATA,
    I2C_FUNC_SMBUS_WRITE_I2C_BLOCK,
    I2C_FUNC_SMBUS_WRITE_WORD_DATA,
)

# ioctl request numbers (<linux/i2c-dev.h>)
I2C_RETRIES = 0x0701
I2C_TIMEOUT = 0x0702
I2C_SLAVE = 0x0703
I2C_TENBIT = 0x0704
I2C_FUNCS = 0x0705
I2C_SLAVE_FORCE = 0x0706
I2C_RDWR = 0x0707
I2C_PEC = 0x0708
I2C_SMBUS = 0x0720

I2C_RDWR_IOCTL_MAX_MSGS = 42  # <linux/i2c-dev.h>
I2C_DEV_MAX_TRANSFER = 8192  # drivers/i2c/i2c-dev.c: read()/write()/I2C_RDWR message cap

# i2c_msg.flags (<linux/i2c.h>)
I2C_M_RD = 0x0001
I2C_M_TEN = 0x0010
I2C_M_DMA_SAFE = 0x0200
I2C_M_RECV_LEN = 0x0400
I2C_M_NO_RD_ACK = 0x0800
I2C_M_IGNORE_NAK = 0x1000
I2C_M_REV_DIR_ADDR = 0x2000
I2C_M_NOSTART = 0x4000
I2C_M_STOP = 0x8000

# i2c_smbus_ioctl_data.read_write
I2C_SMBUS_WRITE = 0
I2C_SMBUS_READ = 1

# i2c_smbus_ioctl_data.size: the SMBus transaction kinds
I2C_SMBUS_QUICK = 0
I2C_SMBUS_BYTE = 1
I2C_SMBUS_BYTE_DATA = 2
I2C_SMBUS_WORD_DATA = 3
I2C_SMBUS_PROC_CALL = 4
I2C_SMBUS_BLOCK_DATA = 5
I2C_SMBUS_I2C_BLOCK_BROKEN = 6  # libi2c's 32-byte I2C block read
I2C_SMBUS_BLOCK_PROC_CALL = 7
I2C_SMBUS_I2C_BLOCK_DATA = 8
I2C_SMBUS_BLOCK_MAX = 32

SMBUS_SIZE_NAMES = {
    I2C_SMBUS_QUICK: "quick",
    I2C_SMBUS_BYTE: "byte",
    I2C_SMBUS_BYTE_DATA: "byte_data",
    I2C_SMBUS_WORD_DATA: "word_data",
    I2C_SMBUS_PROC_CALL: "proc_call",
    I2C_SMBUS_BLOCK_DATA: "block_data",
    I2C_SMBUS_I2C_BLOCK_BROKEN: "i2c_block_broken",
    I2C_SMBUS_BLOCK_PROC_CALL: "block_proc_call",
    I2C_SMBUS_I2C_BLOCK_DATA: "i2c_block_data",
}

I2C_FUNC_SMBUS_BYTE = I2C_FUNC_SMBUS_READ_BYTE | I2C_FUNC_SMBUS_WRITE_BYTE
I2C_FUNC_SMBUS_BYTE_DATA = I2C_FUNC_SMBUS_READ_BYTE_DATA | I2C_FUNC_SMBUS_WRITE_BYTE_DATA
I2C_FUNC_SMBUS_WORD_DATA = I2C_FUNC_SMBUS_READ_WORD_DATA | I2C_FUNC_SMBUS_WRITE_WORD_DATA
I2C_FUNC_SMBUS_BLOCK_DATA = I2C_FUNC_SMBUS_READ_BLOCK_DATA | I2C_FUNC_SMBUS_WRITE_BLOCK_DATA
I2C_FUNC_SMBUS_I2C_BLOCK = I2C_FUNC_SMBUS_READ_I2C_BLOCK | I2C_FUNC_SMBUS_WRITE_I2C_BLOCK
# What a plain I2C master with SMBus emulation in i2c-core offers (I2C_FUNC_SMBUS_EMUL).
I2C_FUNC_SMBUS_EMUL = (
    I2C_FUNC_SMBUS_QUICK
    | I2C_FUNC_SMBUS_BYTE
    | I2C_FUNC_SMBUS_BYTE_DATA
    | I2C_FUNC_SMBUS_WORD_DATA
    | I2C_FUNC_SMBUS_PROC_CALL
    | I2C_FUNC_SMBUS_WRITE_BLOCK_DATA
    | I2C_FUNC_SMBUS_I2C_BLOCK
    | I2C_FUNC_SMBUS_PEC
)


class i2c_smbus_data(ctypes.Union):
    _fields_ = [
        ("byte", ctypes.c_uint8),
        ("word", ctypes.c_uint16),
        ("block", ctypes.c_uint8 * (I2C_SMBUS_BLOCK_MAX + 2)),
    ]


class i2c_smbus_ioctl_data(ctypes.Structure):
    _fields_ = [
        ("read_write", ctypes.c_uint8),
        ("command", ctypes.c_uint8),
        ("size", ctypes.c_uint32),
        ("data", ctypes.POINTER(i2c_smbus_data)),
    ]


class i2c_msg(ctypes.Structure):
    _fields_ = [
        ("addr", ctypes.c_uint16),
        ("flags", ctypes.c_uint16),
        ("len", ctypes.c_uint16),
        ("buf", ctypes.POINTER(ctypes.c_uint8)),
    ]


class i2c_rdwr_ioctl_data(ctypes.Structure):
    _fields_ = [
        ("msgs", ctypes.POINTER(i2c_msg)),
        ("nmsgs", ctypes.c_uint32),
    ]


SMBUS_IOCTL_DATA_SIZE = ctypes.sizeof(i2c_smbus_ioctl_data)  # 16 on LP64
SMBUS_DATA_OFFSET = i2c_smbus_ioctl_data.data.offset  # 8
SMBUS_DATA_SIZE = ctypes.sizeof(i2c_smbus_data)  # 34
I2C_MSG_SIZE = ctypes.sizeof(i2c_msg)  # 16
I2C_MSG_BUF_OFFSET = i2c_msg.buf.offset  # 8
RDWR_IOCTL_DATA_SIZE = ctypes.sizeof(i2c_rdwr_ioctl_data)  # 16

