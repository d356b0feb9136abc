"""Faults on the real chip model: each one visible on the bus, in the log and in the truth."""

from __future__ import annotations

import numpy as np
import pytest

from bmg160_emu.adcs.evaluation import FifoReader
from bmg160_emu.adcs.faults import FAULT_FLAGS, Fault
from bmg160_emu.adcs.rig import GyroRig, GyroSpec
from bmg160_emu.adcs.scenarios import Scenario

LSB_250 = 1 / 131.072  # deg/s per count at +-250 deg/s (spec 5.1)


def _rig(faults, rate=(1.0, 2.0, 3.0), noise=False, seed=0):
    rig = GyroRig(Scenario.constant(rate, 30.0), [GyroSpec(noise=noise)], seed=seed,
                  faults=faults)
    gyro = rig.gyros[0]
    reader = FifoReader(gyro.bus, gyro.address, range_dps=250, bandwidth_code=4)
    reader.configure()
    return rig, gyro, reader


def _poll(rig, reader, seconds, period=0.05):
    frames = []
    for _ in range(round(seconds / period)):
        rig.advance(period)
        frames.append(reader.read_frames())
    return np.concatenate(frames)


def test_nack_fails_the_transaction_with_eremoteio_and_the_log_shows_it():
    rig, gyro, _ = _rig([Fault("nack", on_transaction=6)])
    bus = gyro.bus
    assert len(bus.log) == 3  # the reader's configuration writes: transactions 0, 1, 2
    for _ in range(3):
        bus.read_byte_data(0x68, 0x00)
    with pytest.raises(OSError) as failure:
        bus.read_byte_data(0x68, 0x00)
    assert failure.value.errno == 121
    assert bus.read_byte_data(0x68, 0x00) == 0x0F
    assert [t.error for t in bus.log][-2:] == ["EREMOTEIO", None]
    assert rig.faults.events[0].transaction == 6


def test_timeout_fails_with_etimedout_and_stalls_virtual_time():
    rig, gyro, _ = _rig([Fault("timeout", at_s=1.0, stall_s=0.25)])
    rig.advance(1.0)
    with pytest.raises(OSError) as failure:
        gyro.bus.read_byte_data(0x68, 0x00)
    assert failure.value.errno == 110
    assert rig.time == pytest.approx(1.25)


def test_stuck_axis_repeats_its_value_in_the_registers_and_is_flagged_in_the_truth():
    rig, gyro, reader = _rig([Fault("stuck_axis", at_s=1.0, axis="y", duration_s=1.0)],
                             rate=(0.0, 0.0, 0.0), noise=True)
    rates = _poll(rig, reader, 3.0)
    truth = rig.truth(0)
    stuck = (truth.fault_flags & FAULT_FLAGS["stuck_axis"]) != 0
    frames_at = truth.times_s[-rates.shape[0]:]  # one frame per truth sample (none lost)
    in_window = stuck[-rates.shape[0]:]
    assert 190 <= in_window.sum() <= 201  # 1 s at 200 Hz
    assert np.unique(rates[in_window, 1]).size == 1  # y frozen
    assert np.unique(rates[in_window, 0]).size > 10  # x keeps its noise
    assert frames_at[in_window][0] >= 1.0
    assert any(t.kind == "fault:stuck_axis" for t in gyro.bus.log)


def test_bias_step_shifts_the_output_by_its_size():
    rig, _, reader = _rig([Fault("bias_step", at_s=1.0, axis="z", step_dps=0.5)])
    rates = _poll(rig, reader, 2.0)
    # frame 150 is at 0.75 s, after the filter has settled and before the step
    assert rates[150, 2] == pytest.approx(3.0, abs=LSB_250)
    assert rates[-1, 2] == pytest.approx(3.5, abs=LSB_250)


def test_spike_and_saturation_reach_the_registers():
    rig, _, reader = _rig([Fault("spike", at_s=0.5, axis="x", amplitude_dps=100.0, samples=2),
                           Fault("saturation", at_s=1.0, axis="z", duration_s=0.1)])
    rates = _poll(rig, reader, 1.5)
    assert np.sum(rates[:, 0] > 50) == 2
    full_scale = 32767 * LSB_250
    assert 19 <= np.sum(np.isclose(rates[:, 2], full_scale)) <= 21  # 0.1 s at 200 Hz


def test_lost_samples_leave_fewer_frames_and_are_flagged():
    rig, _, reader = _rig([Fault("lost_samples", at_s=1.0, samples=7)])
    rates = _poll(rig, reader, 2.0)
    truth = rig.truth(0)
    lost = (truth.fault_flags & FAULT_FLAGS["lost_samples"]) != 0
    assert lost.sum() == 7
    assert rates.shape[0] == truth.times_s.size - 7  # every other sample reached the FIFO


def test_seu_flips_a_configuration_bit_and_the_driver_can_see_it():
    rig, gyro, _ = _rig([Fault("seu", at_s=1.0, register=0x0F, bit=0)])  # RANGE 3 -> 2
    rig.advance(1.0)
    assert gyro.bus.read_byte_data(0x68, 0x0F) & 0x07 == 2
    assert "0x03 -> 0x02" in rig.faults.events[0].detail
    assert any(t.kind == "fault:seu" for t in gyro.bus.log)
    # the chip now scales for +-500 deg/s: a 3 deg/s rate reads half the counts of +-250
    rig.advance(0.5)
    counts = int.from_bytes(gyro.bus.read_i2c_block_data(0x68, 0x06, 2), "little", signed=True)
    assert counts == round(3.0 * 65.536)


def test_brownout_brings_back_reset_values():
    rig, gyro, _ = _rig([Fault("brownout", at_s=1.0)])
    assert gyro.bus.read_byte_data(0x68, 0x0F) == 0x03
    rig.advance(1.0)
    assert gyro.bus.read_byte_data(0x68, 0x0F) == 0x00
    assert gyro.bus.read_byte_data(0x68, 0x10) == 0x80  # BW reset value (spec 4.9)
    assert [e.kind for e in rig.faults.events] == ["brownout"]


def test_temperature_ramp_shows_in_temp_and_in_the_bias():
    fault = Fault("temperature_ramp", at_s=0.0, rate_c_per_s=2.0, duration_s=5.0,
                  tc_bias_dps_per_c=[0.0, 0.0, 0.02])
    rig, gyro, reader = _rig([fault])
    rates = _poll(rig, reader, 4.0)
    raw = gyro.bus.read_byte_data(0x68, 0x08)
    celsius = 23.0 + 0.5 * (raw - 256 if raw > 127 else raw)  # spec 5.2
    assert celsius == pytest.approx(23.0 + 8.0, abs=0.5)
    assert rates[-1, 2] == pytest.approx(3.0 + 0.02 * 8.0, abs=2 * LSB_250)


def test_random_faults_repeat_with_the_master_seed():
    def events(seed):
        rig, _, reader = _rig([Fault("nack", probability=0.05),
                               Fault("spike", probability=0.02, axis=0, amplitude_dps=9.0)],
                              seed=seed)
        _poll(rig, reader, 2.0)
        return [(e.kind, e.transaction) for e in rig.faults.events]

    first = events(8)
    assert first and first == events(8)
    assert first != events(9)


def test_bus_and_chip_faults_flag_the_next_output_sample_in_the_truth():
    rig, _, reader = _rig([Fault("nack", at_s=0.5), Fault("brownout", at_s=1.0)])
    for _ in range(30):
        rig.advance(0.05)
        reader.read_frames()
    truth = rig.truth(0)
    nack = truth.times_s[(truth.fault_flags & FAULT_FLAGS["nack"]) != 0]
    brownout = truth.times_s[(truth.fault_flags & FAULT_FLAGS["brownout"]) != 0]
    assert nack.size == 1 and 0.5 <= nack[0] <= 0.55 + 0.005
    # after a brown-out the chip restarts: the next sample comes after its start-up time
    assert brownout.size == 1 and brownout[0] > 1.0
    assert [e.kind for e in truth.events] == ["nack", "brownout"]
    assert reader.errors == 1


def test_scale_factor_error_scales_the_measured_rate():
    rig = GyroRig(Scenario.constant([10.0, 10.0, 0.0], 5.0),
                  [GyroSpec(noise=False, scale_factor_error=[0.01, 0.0, 0.0])], seed=0)
    gyro = rig.gyros[0]
    reader = FifoReader(gyro.bus, gyro.address, range_dps=250, bandwidth_code=4)
    reader.configure()
    rates = _poll(rig, reader, 1.0)
    assert rates[-1, 0] == pytest.approx(10.1, abs=LSB_250)
    assert rates[-1, 1] == pytest.approx(10.0, abs=LSB_250)


def test_inject_puts_one_fault_into_a_lone_chip_from_script_style_arguments():
    from bmg160_emu.adcs.faults import FaultError, inject
    from bmg160_emu.device.chip import BMG160

    chip = BMG160(seed=1, noise=False, true_rate=(0.0, 5.0, 0.0))
    chip.write(0x0F, b"\x03")  # +-250 deg/s
    chip.advance(0.1)
    schedule = inject(chip, "bias_step", "axis=y", "step_dps=1.5")
    chip.advance(0.1)
    y = int.from_bytes(chip.read(0x04, 2), "little", signed=True)
    assert y == round(6.5 * 131.072)
    assert schedule.events[0].kind == "bias_step"
    inject(chip, "seu", "register=0x0F", "bit=0")
    assert chip.peek(0x0F) & 7 == 2
    with pytest.raises(FaultError, match="bus fault"):
        inject(chip, "nack")
    with pytest.raises(FaultError, match="key=value"):
        inject(chip, "spike", "axis")
