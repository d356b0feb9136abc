"""The default test selection: quick by default, whole with ``--all`` (CI).

``python3 -m pytest`` leaves out the tests marked ``slow``, ``docs``, ``kernel``,
``firmware`` and ``umockdev`` (long records and simulations, the documentation's examples
run as written, QEMU guests, the AVR tool chain, umockdev sessions) and says so in its
header; ``python3 -m pytest --all`` (or ``BMG160_ALL_TESTS=1``) runs them, as .ci/run
does. An explicit ``-m EXPR`` chooses by itself (``pytest -m kernel`` runs the kernel
tests). The tests long by their time alone are listed here, with the seconds measured,
rather than decorated in each file (LONG_TESTS). docs/contributing.md has the times.
Before each long test a line says what it is about to do, so a minute of silence is not
taken for a hang.
"""

from __future__ import annotations

import contextlib
import os
from importlib.metadata import entry_points
from pathlib import Path

import pytest

# the kernel fixture's plugin where the installed package predates its entry point
# (bmg160_emu_kernel in pyproject's pytest11; a reinstall registers it)
if not any(ep.name == "bmg160_emu_kernel" for ep in entry_points(group="pytest11")):
    pytest_plugins = ["bmg160_emu.pytest_kernel"]

# markers left out of the default run; their descriptions are in pyproject.toml
LONG = ("slow", "docs", "kernel", "firmware", "umockdev")

# Tests left out of the quick run for their time: node id (or its start) -> marker and the
# seconds --durations=0 measured for it in the whole quick suite (3 December 2026, two cores
# at load 6-7 from other jobs: 1702 s then, about 2.5x a quiet machine's time). A renamed
# test left in this list is an error when the whole suite is collected.
LONG_TESTS = {
    "tests/test_docs_run.py::": ("docs", 421.2),  # every page's examples, 48 pages
    "tests/test_chip_error_budget.py::test_over_an_orbit_the_bias_follows_its_polynomial": (
        "slow", 200.7),
    "tests/test_basilisk_module.py::test_chip_time_is_basilisk_time_to_the_nanosecond_over_an_"
    "orbit": ("slow", 136.2),
    "tests/test_basilisk_montecarlo.py::test_campaign_is_identical_in_process_and_on_dask": (
        "slow", 93.6),
    "tests/test_examples.py::test_example_test_suite_passes": ("slow", 33.3),
    "tests/test_bus_properties.py::test_any_operation_sequence_matches_smbus2": ("slow", 33.2),
    "tests/test_thermal_fit.py::test_without_a_noise_model_the_residuals_give_one": (
        "slow", 29.7),
    "tests/test_plots.py::test_identify_figures_of_a_firmware_capture_are_written_whole": (
        "slow", 22.3),
    "tests/test_basilisk_detumble.py::test_report_and_figures_are_written": ("slow", 17.9),
    "tests/test_thermal_fit.py::test_block_covariance_matches_simulated_block_means": (
        "slow", 17.1),
    "tests/test_chip_properties.py::test_per_sample_engines_do_not_change_the_data": (
        "slow", 16.6),
    "tests/test_thermal_fit.py::test_the_thermal_command_fits_a_chamber_log_and_exports": (
        "slow", 16.5),
    "tests/test_identify_exports.py::test_units_rad_s_scales_every_rate_quantity": (
        "slow", 15.6),
    "tests/test_basilisk_detumble.py::test_the_documented_command_writes_report_summary": (
        "slow", 15.0),
    "tests/test_interrupted_commands.py::test_an_interrupted_generate_leaves_an_honest": (
        "slow", 12.6),
    "tests/test_basilisk_detumble.py::test_attitude_error_growth_between_fixes": ("slow", 11.2),
    "tests/test_identify_exports.py::test_skip_poles_and_flicker_options": ("slow", 11.2),
    "tests/test_identify_cli.py::test_progress_bar_only_on_a_terminal": ("slow", 10.9),
    "tests/test_identify_output_stage.py::test_a_curve_read_in_the_wrong_units_is_warned": (
        "slow", 10.2),
    # the longest left after that, from the quick suite on a fresh clone (load 6-8, 286 s)
    "tests/test_gmwm_estimator.py::test_selection_finds_two_poles_and_orders_them": (
        "slow", 18.7),
    "tests/test_identify_cli.py::test_summary_profile_and_adev_plot": ("slow", 7.3),
    "tests/test_identify_roundtrip.py::test_identified_profile_loads_back_into_the_generator": (
        "slow", 7.3),
    "tests/test_attitude.py::test_quaternions_stay_unit_norm_over_a_long_tumble": ("slow", 6.8),
    "tests/test_identify_exports.py::test_adev_out_read_back_as_a_curve_gives_the_same_fit": (
        "slow", 5.9),
    "tests/test_gmwm_theory.py::test_finite_covariance_is_the_quadratic_forms_covariance[model5-"
    "params5-1500]": ("slow", 5.9),
    "tests/test_gmwm_theory.py::test_finite_covariance_is_the_quadratic_forms_covariance[model4-"
    "params4-1500]": ("slow", 5.3),
}
ALL_ENV = "BMG160_ALL_TESTS"


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--all", action="store_true", dest="bmg160_all", default=False,
        help=f"also run the tests marked {', '.join(LONG)} (CI does; also {ALL_ENV}=1)",
    )


def _everything(config: pytest.Config) -> bool:
    return bool(config.getoption("bmg160_all")) or os.environ.get(ALL_ENV, "") not in ("", "0")


def _long_marker(item: pytest.Item) -> str | None:
    return next((name for name in LONG if item.get_closest_marker(name) is not None), None)


def _mark_long_tests(config: pytest.Config, items: list[pytest.Item]) -> None:
    used = set()
    for item in items:
        for start, (marker, _seconds) in LONG_TESTS.items():
            if item.nodeid.startswith(start):
                item.add_marker(getattr(pytest.mark, marker))
                used.add(start)
    whole = [Path(a).resolve() for a in config.args] == [config.rootpath / "tests"]
    # a file skipped whole (Basilisk not installed) collects nothing: not a stale entry
    files = {item.nodeid.partition("::")[0] for item in items}
    stale = sorted(start for start in set(LONG_TESTS) - used
                   if start.partition("::")[0] in files
                   or not (config.rootpath / start.partition("::")[0]).is_file())
    if whole and stale:
        raise pytest.UsageError(f"tests/conftest.py LONG_TESTS names tests that no longer "
                                f"exist: {', '.join(stale)}")


@pytest.hookimpl(tryfirst=True)  # before -m and -k select: `pytest -m slow` sees the marks
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    _mark_long_tests(config, items)
    if _everything(config) or config.getoption("markexpr"):
        return
    keep, left = [], []
    for item in items:
        (left if _long_marker(item) else keep).append(item)
    if left:
        config.hook.pytest_deselected(items=left)
        items[:] = keep
        config.stash[_LEFT_OUT] = len(left)


_LEFT_OUT = pytest.StashKey[int]()


def pytest_report_header(config: pytest.Config) -> str:
    if _everything(config):
        return "bmg160-emu: the whole suite (--all)"
    if config.getoption("markexpr"):
        return "bmg160-emu: tests chosen by -m"
    return (f"bmg160-emu: the quick suite; tests marked {', '.join(LONG)} are left out "
            "(python3 -m pytest --all runs them)")


def pytest_terminal_summary(terminalreporter, exitstatus: int, config: pytest.Config) -> None:
    left = config.stash.get(_LEFT_OUT, 0)
    if left:
        terminalreporter.write_line(
            f"bmg160-emu: {left} long tests ({', '.join(LONG)}) left out; "
            "python3 -m pytest --all runs everything")


@pytest.fixture(autouse=True)
def _say_what_a_long_test_does(request: pytest.FixtureRequest) -> None:
    name = _long_marker(request.node)
    if name is None:
        return
    reporter = request.config.pluginmanager.get_plugin("terminalreporter")
    if reporter is None:
        return
    marker = {"slow": "a long test", "docs": "a page's examples as written",
              "kernel": "a Linux guest (user-mode Linux or QEMU)",
              "firmware": "the AVR firmware in simavr", "umockdev": "a umockdev session"}[name]
    capture = request.config.pluginmanager.get_plugin("capturemanager")
    # out of the test's capture: the line must reach the terminal before the long part
    with capture.global_and_fixture_disabled() if capture else contextlib.nullcontext():
        reporter.ensure_newline()
        reporter.write_line(f"[{name}] {request.node.nodeid}: running {marker}...")
