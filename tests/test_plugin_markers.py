"""The plugin's marker as a driver author meets it: parts and devices, markers merged from
module to test, faults without a trigger, clear errors, and assert_wrote on every stack."""

from __future__ import annotations

import pytest

from bmg160_emu.device.chip import BMG160

pytest_plugins = ["pytester"]

BMG160(seed=1).advance(0.01)  # numpy loaded once, before pytester's in-process runs

ARGS = ("-p", "no:cacheprovider", "--strict-markers")


def run(pytester, source, *extra, ini=None):
    if ini is not None:
        pytester.makeini(ini)
    pytester.makepyfile(test_suite=source)
    return pytester.runpytest(*ARGS, *extra)


def test_a_bmi088_with_its_accelerometer_stand_in_without_internal_imports(pytester):
    result = run(pytester, """
        import pytest
        import smbus2

        pytestmark = pytest.mark.bmg160(part="bmi088_gyro", devices=["bmi088_accel@0x18"])

        def test_both_answer(bmg160_smbus, bmg160_devices, bmg160_chip):
            with smbus2.SMBus(1) as bus:
                assert bus.read_byte_data(0x68, 0x00) == 0x0F   # GYRO_CHIP_ID
                assert bus.read_byte_data(0x18, 0x00) == 0x1E   # ACC_CHIP_ID
            assert sorted(bmg160_devices) == [0x18, 0x68]
            assert type(bmg160_chip).__name__ == "Bmi088Gyro"
    """)
    result.assert_outcomes(passed=1)


def test_part_and_devices_from_the_ini_file(pytester):
    result = run(pytester, """
        def test_ini(bmg160_devices, bmg160_chip):
            assert type(bmg160_chip).__name__ == "Bmi055Gyro"
            assert sorted(bmg160_devices) == [0x10, 0x68]
    """, ini="[pytest]\nbmg160_part = bmi055_gyro\nbmg160_devices =\n    bmm150@0x10\n")
    result.assert_outcomes(passed=1)


@pytest.mark.parametrize(("marker", "message"), [
    ('part="bmi099"', ("part must be one of bmg160, bmi055_gyro, bmx055_gyro, bmi088_gyro, not "
                      "'bmi099'")),
    ('devices="bmi088_accel@0x18"', "devices= takes a list of NAME@ADDRESS"),
    ('devices=["bmi088_accel@0x68"]', "a bmi088_accel answers at 0x18, 0x19 only"),
    ('devices=["toaster@0x20"]', "unknown device 'toaster'"),
    ('devices=["bmi088_accel"]', "give NAME@ADDRESS with a 7-bit address"),
    ('faults=[{"kind": "nack", "register": 0x0F}]',
     ("a nack fault takes no register (to select transactions naming a register, give "
     "on_register)")),
    ('faults=[{"kind": "nack", "regster": 0x0F}]',
     ("unknown key regster; a nack fault takes kind, at_s, on_transaction, probability, "
     "on_register, address, gyro, max_count, duration_s")),
])
def test_a_bad_marker_is_one_line_naming_the_test(pytester, marker, message):
    result = run(pytester, f"""
        import pytest

        @pytest.mark.bmg160({marker})
        def test_x(bmg160_smbus):
            pass
    """)
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    err = result.stderr.str()
    assert "test_suite.py::test_x" in err and message in err
    assert "Traceback" not in err


def test_module_class_and_test_markers_merge_the_closest_winning(pytester):
    result = run(pytester, """
        import pytest

        pytestmark = pytest.mark.bmg160(bus=0, seed=3, noise=False)

        @pytest.mark.bmg160(seed=5)
        class TestGroup:
            @pytest.mark.bmg160(true_rate=(1.0, 2.0, 3.0))
            def test_merged(self, bmg160_smbus, bmg160_chip):
                assert bmg160_smbus.number == 0          # from the module
                assert bmg160_chip.seed == 5             # the class's, closer than the module's
                bmg160_chip.advance(0.05)                # noiseless (the module's): exact
                rate = bmg160_chip.read(0x02, 6)
                assert [int.from_bytes(rate[i:i + 2], "little", signed=True)
                        for i in (0, 2, 4)] == [16, 33, 49]  # 1, 2, 3 deg/s at 16.384 LSB

        def test_module_only(bmg160_smbus, bmg160_chip):
            assert bmg160_smbus.number == 0 and bmg160_chip.seed == 3
    """)
    result.assert_outcomes(passed=2)


def test_stuck_bus_without_a_trigger_in_the_marker_and_in_add_agree(pytester):
    result = run(pytester, """
        import errno
        import pytest
        import smbus2

        @pytest.mark.bmg160(faults=[{"kind": "stuck_bus"}])
        def test_marker(bmg160_smbus):
            with smbus2.SMBus(1) as bus, pytest.raises(OSError) as info:
                bus.read_byte_data(0x68, 0x00)   # from the start
            assert info.value.errno == errno.EBUSY

        def test_add(bmg160_smbus, bmg160_faults):
            with smbus2.SMBus(1) as bus:
                bus.read_byte_data(0x68, 0x00)
                bmg160_faults.add("stuck_bus")   # from now on
                with pytest.raises(OSError) as info:
                    bus.read_byte_data(0x68, 0x00)
            assert info.value.errno == errno.EBUSY
    """)
    result.assert_outcomes(passed=2)


def test_machine_i2c_of_another_bus_says_where_the_chip_is(pytester):
    result = run(pytester, """
        import pytest

        def test_zero(bmg160_machine):
            with pytest.raises(ValueError) as info:
                bmg160_machine.I2C(0)
            assert str(info.value) == (
                "I2C(0) doesn't exist: the chip is on I2C(1); to reach it as I2C(0), mark the "
                "test @pytest.mark.bmg160(bus=0)")

        @pytest.mark.bmg160(bus=0)
        def test_moved(bmg160_machine):
            assert bmg160_machine.I2C(0).scan() == [0x68]
    """)
    result.assert_outcomes(passed=2)


def test_assert_wrote_is_the_same_on_every_stack(pytester):
    result = run(pytester, """
        import pytest
        import smbus2

        def configure_smbus2():
            with smbus2.SMBus(1) as bus:
                bus.write_byte_data(0x68, 0x0F, 0x03)          # RANGE
                bus.write_i2c_block_data(0x68, 0x10, [0x07])   # BW

        def configure_machine(machine):
            i2c = machine.I2C(1)
            i2c.writeto_mem(0x68, 0x0F, b"\\x03")
            i2c.writeto(0x68, b"\\x10\\x07")

        def test_smbus2(bmg160_smbus):
            configure_smbus2()
            bmg160_smbus.assert_wrote(RANGE=0x03, before="BW")
            assert bmg160_smbus.writes() == [(0x0F, 0x03), (0x10, 0x07)]

        def test_machine(bmg160_machine, bmg160_i2c_bus):
            configure_machine(bmg160_machine)
            bmg160_i2c_bus.assert_wrote(RANGE=0x03, BW=0x07, before="BW")

        def test_the_failure_lists_the_writes(bmg160_smbus):
            configure_smbus2()
            with pytest.raises(AssertionError) as info:
                bmg160_smbus.assert_wrote(BW=0x07, before="RANGE")
            assert str(info.value) == ("BW = 0x07 was not written before RANGE; its writes: "
                                       "0x0f=0x03, 0x10=0x07")

        @pytest.mark.bmg160(part="bmi088_gyro", devices=["bmi088_accel@0x18"])
        def test_a_part_and_a_stand_in_by_their_names(bmg160_smbus):
            with smbus2.SMBus(1) as bus:
                bus.write_byte_data(0x68, 0x0F, 0x01)   # GYRO_RANGE
                bus.write_byte_data(0x18, 0x41, 0x02)   # ACC_RANGE
            bmg160_smbus.assert_wrote(GYRO_RANGE=0x01)
            bmg160_smbus.assert_wrote(address=0x18, ACC_RANGE=0x02)
    """)
    result.assert_outcomes(passed=4)
