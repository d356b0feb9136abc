"""generate's output filters on a second thread (noise.worker_thread, issue 37): a measured
response's FIR (noise.response_fir) is numpy's convolution of the whole stream and the
low-pass is scipy's recursion over the whole stream, bit for bit, on one thread or two,
however the record is cut; the second thread only when asked for and for large requests."""

import os
import threading

import numpy as np
import pytest

from bmg160_emu.noise.profile import AxisNoise, OutputStage, Profile
from bmg160_emu.noise.response_fir import PIECE, ResponseFIR
from bmg160_emu.noise.sensor_noise import PIECE as LOW_PASS_PIECE
from bmg160_emu.noise.sensor_noise import profile_noise
from bmg160_emu.noise.worker_thread import usable_cpus

RNG = np.random.default_rng(11)
TAPS = [RNG.random(65), None, RNG.random(5)]  # a long FIR, an axis without one, a short one
STREAM = RNG.standard_normal((3 * PIECE + 64 + 999, 3))
CUTS = (1, 2 * PIECE + 17, 3, PIECE - 1, 978)  # two large requests (2 pieces and more)


def _run(threads, cuts=CUTS, worker=None):
    fir = ResponseFIR(TAPS, threads, worker)
    fir.start(STREAM[:fir.settle_samples])
    at = fir.settle_samples

    def take(m):
        nonlocal at
        at += m
        return STREAM[at - m:at]

    return fir, np.concatenate([fir.run(n, take) for n in cuts])


@pytest.mark.parametrize("threads", [1, 2])
def test_the_fir_is_numpys_convolution_of_the_whole_stream(threads):
    fir, got = _run(threads)
    assert fir.settle_samples == 64
    end = 64 + sum(CUTS)
    assert np.array_equal(got[:, 0], np.convolve(STREAM[:end, 0], TAPS[0], "valid"))
    assert np.array_equal(got[:, 1], STREAM[64:end, 1])  # no FIR: as it is
    assert np.array_equal(got[:, 2], np.convolve(STREAM[60:end, 2], TAPS[2], "valid"))


def test_a_second_thread_changes_no_bit_and_is_used_only_for_large_requests():
    one, a = _run(1)
    two, b = _run(2)
    assert np.array_equal(a, b)
    assert not one.worker.started and two.worker.started  # (CUTS holds a request of 2 pieces)
    small, _ = _run(2, cuts=(PIECE, 5, 2 * PIECE - 1))  # each below two pieces: no worker
    assert not small.worker.started


def test_one_worker_at_most():
    before = threading.active_count()
    _run(2)
    assert threading.active_count() <= before + 1 <= before + usable_cpus()
    assert 1 <= usable_cpus()


def test_a_thread_count_other_than_one_or_two_is_refused():
    with pytest.raises(ValueError, match="filter threads must be 1 or 2, got 3"):
        ResponseFIR(TAPS, 3)
    with pytest.raises(ValueError, match="filter threads must be 1 or 2, got 0"):
        profile_noise("paper", seed=1, fir_threads=0)


def test_an_error_while_drawing_comes_through_after_the_pieces_sent():
    fir = ResponseFIR(TAPS, 2)
    fir.start(STREAM[:64])
    calls = []

    def take(m):
        calls.append(m)
        if len(calls) == 2:
            raise RuntimeError("drawing failed")
        return STREAM[64:64 + m]

    with pytest.raises(RuntimeError, match="drawing failed"):
        fir.run(3 * PIECE, take)


def test_generate_gives_the_same_bits_on_one_thread_or_two():
    # a 65-tap moving average's response as identify writes it, an LSB, a Q term: generate's path
    h = np.ones(65) / 65
    r = np.correlate(h, h, "full")[64:]
    response = tuple(float(v) for v in r / (r[0] + 2.0 * r[1:].sum()))
    axis = AxisNoise(N=0.02, B=0.004, T=30.0, K=4e-4, Q=1e-3, bias=0.1, response=response)
    p = Profile("t", axis, axis, axis, output=OutputStage(rate_hz=200.0, lsb_dps=0.0305))
    records = []
    for threads in (1, 2):
        gen = profile_noise(p, seed=9, fir_threads=threads)
        records.append(np.concatenate([gen.generate(n) for n in (7, 2 * PIECE + 3, 100)]))
    assert np.array_equal(records[0], records[1])
    assert "response65/65/65taps" in profile_noise(p, seed=9).describe()


@pytest.mark.parametrize("options", [
    {"bandwidth_code": 4},  # BW code 4's low-pass alone
    {"bandwidth_code": 3, "profile": "datasheet"},
])
def test_the_low_pass_gives_the_same_bits_on_one_thread_or_two(options):
    options = {"profile": "paper", **options}
    cuts = (5, 2 * LOW_PASS_PIECE + 11, 1000, 3 * LOW_PASS_PIECE)  # two of them on the worker
    records, gens = [], []
    for threads in (1, 2):
        gen = profile_noise(**options, seed=3, fir_threads=threads)
        records.append(np.concatenate([gen.generate(n) for n in cuts]))
        gens.append(gen)
    assert np.array_equal(records[0], records[1])
    assert not gens[0].worker.started and gens[1].worker.started
    # and both are the one recursion over the whole stream: one call on one thread
    whole = profile_noise(**options, seed=3, fir_threads=1).generate(sum(cuts))
    assert np.array_equal(records[1], whole)


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform")
def test_a_forked_child_starts_its_own_worker():
    import multiprocessing

    fir, parent = _run(2)
    assert fir.worker.started
    context = multiprocessing.get_context("fork")
    queue = context.Queue()

    def child():
        # the parent's worker object, without its thread: a pool of the parent's would never run
        started = fir.worker.started
        again = _run(2, worker=fir.worker)[1]
        queue.put((started, fir.worker.started, again.tobytes() == parent.tobytes()))

    process = context.Process(target=child)
    process.start()
    process.join(20)  # (the child takes milliseconds; one waiting on a lost thread is killed)
    if process.is_alive():
        process.kill()
    assert process.exitcode == 0 and queue.get(timeout=5) == (False, True, True)
