"""The NVM (6.10): the image of the NVM-backed registers, its program cycles left and its
busy time, seen through TRIM_NVM_CTRL."""

from __future__ import annotations

from bmg160_emu.device import spec_choices as choice
from bmg160_emu.device.registers import NVM_ADDRESSES, address_of, field_of

_NVM_REMAIN = field_of("TRIM_NVM_CTRL", "nvm_remain")
_NVM_RDY = field_of("TRIM_NVM_CTRL", "nvm_rdy")
_NVM_PROG_MODE = field_of("TRIM_NVM_CTRL", "nvm_prog_mode")
NVM_MAX_REMAIN = _NVM_REMAIN.mask >> _NVM_REMAIN.lsb  # 15: what the 4-bit counter holds
_TRIM_NVM_CTRL = address_of("TRIM_NVM_CTRL")


class Nvm:
    """The NVM image of the NVM-backed registers, its cycles left and its busy time (6.10)."""

    def __init__(self, image: bytes, remain: int) -> None:
        if len(image) != len(NVM_ADDRESSES):
            raise ValueError(f"nvm_image must be {len(NVM_ADDRESSES)} bytes "
                             f"(0x{NVM_ADDRESSES[0]:02X}..0x{NVM_ADDRESSES[-1]:02X})")
        if not 0 <= remain <= NVM_MAX_REMAIN:
            raise ValueError(f"nvm_remain must be 0..{NVM_MAX_REMAIN}")
        self.image = bytearray(image)
        self.remain = remain
        self.busy_until_ns = -1

    def ready(self, now_ns: int) -> bool:
        return now_ns >= self.busy_until_ns

    def load_into(self, regs: bytearray) -> None:
        for i, address in enumerate(NVM_ADDRESSES):
            regs[address] = self.image[i]

    def program(self, regs: bytearray, now_ns: int) -> bool:
        """nvm_prog_trig: store the registers if unlocked, ready and cycles are left."""
        unlocked = regs[_TRIM_NVM_CTRL] & _NVM_PROG_MODE.mask
        if not (self.ready(now_ns) and unlocked and self.remain > 0):
            return False
        self.image[:] = bytes(regs[a] for a in NVM_ADDRESSES)
        self.remain -= 1
        self.busy_until_ns = now_ns + choice.NVM_PROG_TIME_NS
        return True

    def register(self, stored: int, now_ns: int) -> int:
        """TRIM_NVM_CTRL as read: cycles left, ready, and the stored nvm_prog_mode."""
        value = _NVM_REMAIN.insert(0, self.remain)
        value = _NVM_RDY.insert(value, self.ready(now_ns))
        return value | stored & _NVM_PROG_MODE.mask
