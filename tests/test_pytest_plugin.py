"""The pytest plugin's fixtures, marker and ini options, run in a separate suite (pytester)."""

from __future__ import annotations

import inspect

import pytest

from bmg160_emu.device.chip import BMG160
from bmg160_emu.pytest_plugin import PLUGIN_KEYS, chip_option_names

pytest_plugins = ["pytester"]

# pytester's in-process runs drop the modules first imported inside them, and numpy's C
# extensions cannot be loaded twice in one process: load everything a noisy chip uses here.
BMG160(seed=1).advance(0.01)

ARGS = ("-p", "no:cacheprovider", "--strict-markers")


def run(pytester, source, *extra, ini=None):
    if ini is not None:
        pytester.makeini(ini)
    pytester.makepyfile(test_suite=source)
    return pytester.runpytest(*ARGS, *extra)


def test_virtual_time_makes_a_monotonic_timeout_loop_expire_in_virtual_time(pytester):
    # A driver that waits on time.monotonic(): with bmg160_virtual_time the 5 s timeout
    # passes in virtual time; with bmg160_virtual_sleep alone the same loop only ends by its
    # iteration guard, because monotonic() does not move.
    result = run(pytester, """
        import time

        def wait_until_timeout(limit_s, max_polls):
            deadline = time.monotonic() + limit_s
            polls = 0
            while time.monotonic() < deadline and polls < max_polls:
                time.sleep(0.01)
                polls += 1
            return polls

        def test_clocks_follow(bmg160_virtual_time, bmg160_chip):
            t0, p0, w0 = time.monotonic(), time.perf_counter(), time.time()
            assert wait_until_timeout(5.0, 10_000) in (500, 501)
            assert abs(bmg160_chip.time - 5.0) < 0.02
            for before, now in ((t0, time.monotonic()), (p0, time.perf_counter()),
                                (w0, time.time())):
                assert 4.99 < now - before < 5.02

        def test_sleep_only(bmg160_virtual_sleep, bmg160_chip):
            assert wait_until_timeout(5.0, 50) == 50
            assert abs(bmg160_chip.time - 0.5) < 1e-9
    """)
    result.assert_outcomes(passed=2)


def test_prefixed_fake_fixtures_and_their_old_aliases(pytester):
    result = run(pytester, """
        def test_new_names(bmg160_fake_smbus, bmg160_fake_spidev):
            assert bmg160_fake_smbus.read_byte_data(0x68, 0x00) == 0x0F
            assert bmg160_fake_spidev.xfer2([0x80, 0]) == [0, 0x0F]

        def test_old_names_are_the_same_objects(fake_smbus, bmg160_fake_smbus,
                                                fake_spidev, bmg160_fake_spidev):
            assert fake_smbus is bmg160_fake_smbus and fake_spidev is bmg160_fake_spidev
    """)
    result.assert_outcomes(passed=2)


def test_spidev_fixture_yields_the_device_node_not_the_chip(pytester):
    result = run(pytester, """
        import pytest

        def test_node(bmg160_spidev, bmg160_chip):
            import spidev  # injected by the fixture (the C module is rarely installed)

            assert bmg160_spidev.chip is bmg160_chip
            assert bmg160_spidev.path == "/dev/spidev0.0"
            assert spidev.SpiDev(0, 0).xfer2([0x80, 0]) == [0, 0x0F]
            with bmg160_spidev.open() as spi:
                assert spi.xfer2([0x80, 0]) == [0, 0x0F]
                assert spi.log.kinds() == ["spi_read"]

        def test_the_node_is_not_the_chip(bmg160_spidev):
            # 0.1's use of the fixture as the chip ended in 0.3.0 (CHANGELOG)
            with pytest.raises(AttributeError):
                bmg160_spidev.read(0x00)
    """)
    result.assert_outcomes(passed=2)


def test_smbus_fixture_yields_the_adapter_with_its_log(pytester):
    result = run(pytester, """
        import pytest
        import smbus2

        @pytest.mark.bmg160(bus=4)
        def test_adapter(bmg160_smbus, bmg160_chip):
            with smbus2.SMBus(4) as bus:
                bus.write_byte_data(0x68, 0x0F, 0x03)
            assert bmg160_smbus.number == 4 and bmg160_smbus.devices[0x68] is bmg160_chip
            [write] = bmg160_smbus.log.filter(kind="write_byte_data")
            assert write.register == 0x0F and write.written == bytes([0x03])
    """)
    result.assert_outcomes(passed=1)


def test_misspelled_marker_option_is_a_usage_error_listing_the_valid_keys(pytester):
    result = run(pytester, """
        import pytest

        @pytest.mark.bmg160(sed=3)
        def test_typo(bmg160_chip):
            pass
    """)
    # Checked at collection, as --strict-markers checks marker names: nothing runs.
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    err = result.stderr.str()
    assert "ERROR: test_suite.py::test_typo: unknown @pytest.mark.bmg160 option sed; " in err
    assert "; valid: " in err and ", address, bus, clock," in err  # sorted, all of them
    assert "Traceback" not in err and "TypeError" not in err + result.stdout.str()


def test_marker_value_the_chip_refuses_is_a_usage_error_with_the_chip_message(pytester):
    result = run(pytester, """
        import pytest

        @pytest.mark.bmg160(address=0x10)
        def test_bad_address(bmg160_chip):
            pass
    """)
    assert result.ret != 0
    assert "address must be 0x68 or 0x69" in result.stdout.str() + result.stderr.str()


def test_ini_seed_and_profile_apply_suite_wide_and_the_marker_overrides(pytester):
    ini = "[pytest]\nbmg160_seed = 11\nbmg160_profile = datasheet\n"
    result = run(pytester, """
        import pytest

        def test_suite_defaults(bmg160_chip):
            assert bmg160_chip.seed == 11
            assert bmg160_chip.state.path.noise.generator.profile.name == "datasheet"

        @pytest.mark.bmg160(seed=2, profile="paper")
        def test_marker_wins(bmg160_chip):
            assert bmg160_chip.seed == 2
            assert bmg160_chip.state.path.noise.generator.profile.name == "paper"
    """, ini=ini)
    result.assert_outcomes(passed=2)


def test_ini_profile_file_is_relative_to_the_ini_file(pytester):
    from importlib import resources

    shipped = resources.files("bmg160_emu.noise").joinpath("profiles", "datasheet.toml")
    text = shipped.read_text(encoding="utf-8").replace('name = "datasheet"', 'name = "mygyro"')
    text = text.replace("N = 0.009899494936611665  #", "N = 0.0321  #")  # x only: its own
    pytester.mkdir("profiles").joinpath("mygyro.toml").write_text(text, encoding="utf-8")
    ini = "[pytest]\nbmg160_profile = profiles/mygyro.toml\n"
    result = run(pytester, """
        def test_profile_from_file(bmg160_chip):
            profile = bmg160_chip.state.path.noise.generator.profile
            assert profile.name == "mygyro" and profile.axes[0].N == 0.0321
    """, ini=ini)
    result.assert_outcomes(passed=1)


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("bmg160_seed = seven", "bmg160_seed must be an integer >= 0 or none, not 'seven'"),
        # issue 24: -1 passed the start-up check and then failed every test at setup
        ("bmg160_seed = -1", "bmg160_seed must be an integer >= 0 or none, not '-1'"),
        ("bmg160_profile = nosuch", "bmg160_profile: unknown noise profile"),
    ],
)
def test_bad_ini_option_stops_the_run_with_one_line(pytester, line, message):
    result = run(pytester, "def test_x():\n    pass\n", ini=f"[pytest]\n{line}\n")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    assert message in result.stderr.str()
    assert "Traceback" not in result.stderr.str()


def test_documented_marker_options_are_exactly_the_chip_keywords():
    # docs/pytest-plugin.md lists every option the marker takes; a new BMG160 keyword must be
    # documented there (and one that went away removed).
    from pathlib import Path

    page = (Path(__file__).resolve().parent.parent / "docs" / "pytest-plugin.md").read_text()
    section = page.split("## Marker options", 1)[1].split("\n## ", 1)[0]
    documented = set()
    for row in section.splitlines():
        if row.startswith("| `"):
            documented |= {name.strip("` ") for name in row.split("|")[1].split(",")}
    assert documented == set(chip_option_names()) | set(PLUGIN_KEYS)
    assert set(chip_option_names()) < set(inspect.signature(BMG160.__init__).parameters)
