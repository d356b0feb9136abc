"""Bus faults from the pytest plugin: the marker's faults= and the bmg160_faults fixture put
the rigs' seeded FaultSchedule on the plugin's own bus (one fault model), triggered by
transaction index, time, register or address."""

from __future__ import annotations

import errno

import pytest
import smbus2

from bmg160_emu.faults import FaultError, inject

pytest_plugins = ["pytester"]


def outcomes(bus, calls):
    out = []
    for call in calls:
        try:
            out.append(call(bus))
        except OSError as exc:
            out.append(errno.errorcode[exc.errno])
    return out


CHIP_ID = lambda bus: bus.read_byte_data(0x68, 0x00)


@pytest.mark.bmg160(faults=[{"kind": "nack", "on_transaction": 1}])
def test_a_nack_by_transaction_index(bmg160_smbus, bmg160_faults):
    with smbus2.SMBus(1) as bus:
        assert outcomes(bus, [CHIP_ID] * 3) == [0x0F, "EREMOTEIO", 0x0F]
    assert [e.kind for e in bmg160_faults.events] == ["nack"]
    assert bmg160_faults.events[0].transaction == 1
    assert [t.error for t in bmg160_smbus.log] == [None, "EREMOTEIO", None]


@pytest.mark.bmg160(faults=[{"kind": "timeout", "on_transaction": 0, "stall_s": 0.5}])
def test_a_timeout_takes_the_adapter_s_time(bmg160_smbus, bmg160_chip):
    with smbus2.SMBus(1) as bus:
        assert outcomes(bus, [CHIP_ID]) == ["ETIMEDOUT"]
    assert bmg160_chip.time == pytest.approx(0.5)


@pytest.mark.bmg160(faults=[{"kind": "stuck_bus", "at_s": 0.2}])
def test_a_stuck_bus_by_time_fails_everything_after_it(bmg160_smbus, bmg160_virtual_sleep):
    import time

    with smbus2.SMBus(1) as bus:
        before = outcomes(bus, [CHIP_ID, lambda b: b.read_byte_data(0x69, 0)])
        time.sleep(0.25)
        after = outcomes(bus, [CHIP_ID, CHIP_ID, lambda b: b.read_byte_data(0x69, 0)])
    assert before == [0x0F, "EREMOTEIO"]  # nobody at 0x69
    assert after == ["EBUSY"] * 3  # every address: SDA is held low


@pytest.mark.bmg160(noise=False, true_rate=(0.0, 0.0, 0.0),
                    faults=[{"kind": "corrupt_byte", "on_register": 0x02, "byte": 1, "bit": 6}])
def test_a_corrupted_byte_on_one_register(bmg160_smbus, bmg160_chip):
    bmg160_chip.advance(0.05)
    with smbus2.SMBus(1) as bus:
        assert bus.read_i2c_block_data(0x68, 0x00, 2) == [0x0F, 0x00]  # other registers: clean
        corrupted = bus.read_i2c_block_data(0x68, 0x02, 6)
        clean = bus.read_i2c_block_data(0x68, 0x02, 6)  # once (no duration)
    assert clean == [0] * 6
    assert corrupted == [0, 0x40, 0, 0, 0, 0]  # RATE_X_MSB bit 6: +16384 counts
    kinds = bmg160_smbus.log.kinds()
    assert kinds[1] == "fault:corrupt_byte"  # logged where it acted, before the read


@pytest.mark.bmg160(faults=[{"kind": "brownout", "on_transaction": 2}])
def test_a_chip_reset_between_transactions(bmg160_smbus):
    with smbus2.SMBus(1) as bus:
        bus.write_byte_data(0x68, 0x0F, 0x03)  # RANGE
        assert bus.read_byte_data(0x68, 0x0F) == 0x03
        assert bus.read_byte_data(0x68, 0x0F) == 0x00  # reset before transaction 2


@pytest.mark.bmg160(faults=[{"kind": "nack", "address": 0x69, "probability": 1.0}])
def test_a_fault_by_address_leaves_the_other_devices_alone(bmg160_smbus):
    with smbus2.SMBus(1) as bus:
        assert outcomes(bus, [CHIP_ID] * 3) == [0x0F] * 3


def test_the_fixture_adds_faults_from_now_on(bmg160_smbus, bmg160_faults):
    with smbus2.SMBus(1) as bus:
        assert CHIP_ID(bus) == 0x0F
        bmg160_faults.add("nack", duration_s=1.0)  # every transaction for 1 s of chip time
        assert outcomes(bus, [CHIP_ID] * 2) == ["EREMOTEIO"] * 2
        bmg160_faults.remove()
        assert CHIP_ID(bus) == 0x0F


def _failures(pytester, seed):
    pytester.makepyfile(test_seeded=f"""
        import pytest, smbus2

        @pytest.mark.bmg160(faults=[{{"kind": "nack", "probability": 0.3}}], fault_seed={seed})
        def test_x(bmg160_smbus, bmg160_faults):
            with smbus2.SMBus(1) as bus:
                for _ in range(40):
                    try:
                        bus.read_byte_data(0x68, 0)
                    except OSError:
                        pass
            with open("failed_at.txt", "w") as out:
                out.write(repr([e.transaction for e in bmg160_faults.events]))
    """)
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(passed=1)
    return (pytester.path / "failed_at.txt").read_text()


def test_random_faults_repeat_with_their_seed(pytester):
    first, again, other = _failures(pytester, 4), _failures(pytester, 4), _failures(pytester, 5)
    assert first == again != other
    assert first.count(",") >= 5  # ~12 of 40 at probability 0.3


@pytest.mark.parametrize(("faults", "message"), [
    ('[{"kind": "nope"}]', "faults: fault 1: fault kind must be one of"),
    ('{"kind": "nack"}', "faults= takes a list of faults"),
    ('[{"kind": "nack", "address": 300}]', "address must be a 7-bit address"),
])
def test_a_bad_fault_in_the_marker_stops_the_run_naming_the_test(pytester, faults, message):
    pytester.makepyfile(test_bad=f"""
        import pytest

        @pytest.mark.bmg160(faults={faults})
        def test_x(bmg160_smbus):
            pass
    """)
    result = pytester.runpytest("-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    assert "test_bad.py::test_x" in result.stderr.str() and message in result.stderr.str()


def test_inject_takes_a_bus_fault_with_the_bus_and_says_so_without(bmg160_chip, bmg160_smbus):
    with pytest.raises(FaultError, match=r"inject\(chip, 'nack', bus=\.\.\.\)"):
        inject(bmg160_chip, "nack")
    inject(bmg160_chip, "nack", bus=bmg160_smbus)
    with smbus2.SMBus(1) as bus:
        assert outcomes(bus, [CHIP_ID] * 2) == ["EREMOTEIO", 0x0F]
