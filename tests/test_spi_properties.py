"""Property test (hypothesis): any sequence of spidev calls on FakeSpiDev raises only what
spidev raises (TypeError, OverflowError, OSError), and the chip stays sound: FIFO frame count
at most 100, and a soft reset written over SPI restores every configuration register."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bmg160_emu.bus.spi import FakeSpiDev
from bmg160_emu.device.chip import BMG160
from bmg160_emu.device.registers import REGISTERS, RESET_VALUES

FIFO_STATUS = 0x0E
CONFIG_REGISTERS = [r.address for r in REGISTERS if r.write_mask and r.address not in (0x33, 0x3C)]
SPIDEV_ERRORS = (TypeError, OverflowError, OSError)

frames = st.lists(st.one_of(st.integers(0, 0xFF), st.integers(-5, 600)), max_size=40)
calls = st.one_of(
    st.tuples(st.just("xfer"), frames),
    st.tuples(st.just("xfer2"), frames),
    st.tuples(st.just("xfer3"), frames),
    st.tuples(st.just("writebytes"), frames),
    st.tuples(st.just("readbytes"), st.integers(-3, 40)),
    st.tuples(st.just("mode"), st.integers(-1, 4)),
    st.tuples(st.just("bits_per_word"), st.sampled_from([7, 8, 12, 16, 32, 33])),
    st.tuples(st.sampled_from(["lsbfirst", "cshigh", "threewire", "no_cs", "loop"]), st.booleans()),
    st.tuples(st.just("advance"), st.sampled_from([0.0, 0.001, 0.05])),
    st.tuples(st.just("soft_reset")),
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(calls, max_size=25), st.integers(0, 2**16))
def test_any_spidev_call_sequence_raises_only_spidev_errors_and_keeps_the_chip_sound(ops, seed):
    chip = BMG160(seed=seed)
    spi = FakeSpiDev(chip)
    for name, *args in ops:
        reset_ok = False
        try:
            if name == "advance":
                chip.advance(args[0])
            elif name == "soft_reset":
                for flag in ("lsbfirst", "cshigh", "threewire", "no_cs", "loop"):
                    setattr(spi, flag, False)
                spi.mode = 0
                spi.bits_per_word = 8
                spi.xfer2([0x14, 0xB6])  # BGW_SOFTRESET (spec 4.13)
                reset_ok = True  # SDI is the chip's input in 4- and 3-wire mode alike
            elif name in ("xfer", "xfer2", "xfer3", "writebytes", "readbytes"):
                getattr(spi, name)(*args)
            else:
                setattr(spi, name, args[0])
        except SPIDEV_ERRORS:
            pass
        assert chip.peek(FIFO_STATUS) & 0x7F <= 100
        if reset_ok:
            dump = chip.dump()
            assert {r: dump[r] for r in CONFIG_REGISTERS} == {
                r: RESET_VALUES[r] for r in CONFIG_REGISTERS
            }
    spi.close()
