"""One bus transaction against the register file (spec 2.4, 6.2): a burst with
auto-increment, the pointer staying on FIFO_DATA, 0x00 past the map, the MSB shadowing of
the rate registers, the write rules of the power modes; each register's own behaviour comes
from ``regmap``. Every function takes ``s``, the chip's state (``state.ChipState``).
"""

from __future__ import annotations

from bmg160_emu.device import regmap
from bmg160_emu.device import spec_choices as choice
from bmg160_emu.device.power_modes import DEEP_SUSPEND, FAST_POWER_UP, SUSPEND
from bmg160_emu.device.registers import FIRST_OUTSIDE_MAP, address_of, field_of
from bmg160_emu.device.state import ChipState

POINTER_MAX = 0xFF  # the 8-bit register pointer saturates here (spec 2.4)
RATE_X_LSB, RATE_END = address_of("RATE_X_LSB"), address_of("RATE_Z_MSB") + 1
_FIFO_DATA = address_of("FIFO_DATA")
_RATE_HBW = address_of("RATE_HBW")
_SHADOW_DIS = field_of("RATE_HBW", "shadow_dis").mask


def read_burst(s: ChipState, reg: int, n: int, now: int) -> tuple[bytes, int]:
    """Bytes of one read transaction and the pointer after it (2.4)."""
    out = bytearray(n)
    addr = reg & choice.REGISTER_ADDRESS_MASK
    for pos in range(n):
        if addr >= FIRST_OUTSIDE_MAP:
            addr = min(addr + n - pos, POINTER_MAX)
            break
        if addr == _FIFO_DATA:
            out[pos:] = read_fifo(s, n - pos, now)
            break
        out[pos] = read_reg(s, addr, now)
        addr += 1
    return bytes(out), addr


def read_fifo(s: ChipState, n: int, now: int) -> bytes:
    """n bytes of FIFO_DATA in one transaction (6.5): frames, then the empty pattern."""
    regmap.sync_bypass(s)
    axis, tag = regmap.frame_format(s)
    data = s.fifo.read(n, axis.stop - axis.start, bool(tag))
    s.fifo.end_transaction()
    if s.fifo_int_on:
        regmap.update_fifo_int(s, now)
    return data


def read_reg(s: ChipState, addr: int, now: int) -> int:
    """One register read with its side effects (MSB latch, data-ready cleared)."""
    if RATE_X_LSB <= addr < RATE_END:
        axis, msb = divmod(addr - RATE_X_LSB, 2)
        s.data_ready_pending = False
        shadowing = not s.regs[_RATE_HBW] & _SHADOW_DIS
        if not msb:
            if shadowing:  # the LSB read latches the MSB (6.2)
                s.msb_latch[axis] = s.cur[addr - RATE_X_LSB + 1]
                s.latched = True
            return s.cur[addr - RATE_X_LSB]
        latched = s.msb_latch[axis]
        if latched is not None:
            s.msb_latch[axis] = None
            if shadowing:
                return latched
        return s.cur[addr - RATE_X_LSB]
    return peek_reg(s, addr, now)


def peek_reg(s: ChipState, addr: int, now: int) -> int:
    """One register's content without side effects, at the address the bus would reach
    (bit 7 not decoded, spec 2.4: peek(0x80) is what a read of 0x80 returns)."""
    addr &= choice.REGISTER_ADDRESS_MASK
    if addr >= FIRST_OUTSIDE_MAP:
        return 0
    if RATE_X_LSB <= addr < RATE_END:
        axis, msb = divmod(addr - RATE_X_LSB, 2)
        if msb and not s.regs[_RATE_HBW] & _SHADOW_DIS:
            latched = s.msb_latch[axis]
            if latched is not None:
                return latched
        return s.cur[addr - RATE_X_LSB]
    hook = s.part.peek_at[addr]
    return s.regs[addr] if hook is None else hook(s, now)


def write_burst(s: ChipState, reg: int, data: bytes, now: int) -> int:
    """One write transaction; returns the pointer after it (auto-increment, 2.4)."""
    if len(data) > 1:
        s.strict_warning(f"multi-byte write of {len(data)} bytes at 0x{reg:02X} (spec 2.1)")
    addr = reg & choice.REGISTER_ADDRESS_MASK
    for value in data:
        if addr < FIRST_OUTSIDE_MAP:
            write_reg(s, addr, value, now)
        if addr != _FIFO_DATA:
            addr = min(addr + 1, POINTER_MAX)
    return addr


def write_reg(s: ChipState, addr: int, value: int, now: int) -> None:
    """A bus write: access rule of the power mode (6.7), store, action, effect."""
    mode = s.power_mode
    if mode == DEEP_SUSPEND and addr not in choice.WRITABLE_IN_DEEP_SUSPEND or \
            mode in (SUSPEND, FAST_POWER_UP) and addr not in choice.WRITABLE_IN_SUSPEND:
        s.strict_warning(f"write of 0x{value:02X} to 0x{addr:02X} ignored in {mode} (6.7)")
        return
    mask = s.part.write_masks[addr]  # the part's table (part_spec)
    old = s.regs[addr]
    s.regs[addr] = (old & ~mask) | (value & mask)
    action = s.part.action_at[addr]
    if action is not None:
        action(s, value, now)  # may reset the chip (a new register file)
    effect = s.part.effect_at[addr]
    if effect is not None:
        effect(s, old, s.regs[addr], now)


def poke_reg(s: ChipState, reg: int, value: int, now: int) -> None:
    """An upset: the content changes without access rules or write actions; what follows
    from the new content (``regmap.EFFECTS``) follows as after a write."""
    if RATE_X_LSB <= reg < RATE_END:
        cur = bytearray(s.cur)
        cur[reg - RATE_X_LSB] = value
        s.cur = bytes(cur)
        return
    if reg in s.part.absent:  # no register there to upset
        return
    old = s.regs[reg]
    s.regs[reg] = value
    effect = s.part.effect_at[reg]
    if effect is not None:
        effect(s, old, value, now)
