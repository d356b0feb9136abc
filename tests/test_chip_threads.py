"""Thread safety: a reader and a configuration thread never see a torn sample (6.2)."""

import sys
import threading

from bmg160_emu.device.chip import BMG160


def test_reader_and_configuration_threads_never_see_a_torn_sample():
    # X = 257 * k counts at sample k (unfiltered): LSB and MSB change together, so a word
    # whose LSB and MSB come from different samples is not a multiple of 257
    chip = BMG160(noise=False)
    chip.write(0x13, b"\x80")
    chip.write(0x0F, b"\x00")
    s = chip.sensitivity
    chip.set_true_rate(lambda t: (257 * (round(t * 2000) % 120) / s, 0.0, 0.0))
    stop = threading.Event()
    errors = []

    def configure():
        i = 0
        while not stop.is_set():
            chip.advance(0.0005)
            chip.write(0x3D, bytes([i & 0x7F]))  # touches state, not the data path
            chip.write(0x10, b"\x80")  # same BW, as NCD rewrites it
            i += 1

    def read():
        for _ in range(3000):
            lsb = chip.read(0x02)[0]
            msb = chip.read(0x03)[0]
            value = lsb | msb << 8
            if value % 257:
                errors.append(value)

    threads = [threading.Thread(target=configure), threading.Thread(target=read)]
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-5)  # switch threads often, so samples arrive between reads
    try:
        for t in threads:
            t.start()
        threads[1].join()
        stop.set()
        threads[0].join()
    finally:
        sys.setswitchinterval(interval)
    assert chip.state.sample_seq > 100  # the configuration thread did run alongside
    assert errors == []


def test_without_shadowing_single_byte_reads_can_tear():
    # the same construction as above shows the test can fail: with shadow_dis the pair tears
    chip = BMG160(noise=False)
    chip.write(0x13, b"\xc0")
    s = chip.sensitivity
    chip.set_true_rate(lambda t: (257 * (round(t * 2000) % 120) / s, 0.0, 0.0))
    chip.advance(0.01)
    torn = 0
    for _ in range(200):
        lsb = chip.read(0x02)[0]
        chip.advance(0.0005)
        msb = chip.read(0x03)[0]
        torn += bool((lsb | msb << 8) % 257)
    assert torn > 0
