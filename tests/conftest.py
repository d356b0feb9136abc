"""The default test selection: quick by default, whole with ``--all`` (CI).

``python3 -m pytest`` leaves out the tests marked ``slow``, ``kernel``, ``firmware`` and
``umockdev`` (long statistical records, QEMU guests, the AVR tool chain, umockdev
sessions: minutes each) and says so in its header; ``python3 -m pytest --all`` (or
``BMG160_ALL_TESTS=1``) runs them, as .ci/run does. An explicit ``-m EXPR`` chooses by
itself (``pytest -m kernel`` runs the kernel tests). docs/contributing.md has the times.
Before each long test a line says what it is about to do, so a minute of silence is not
taken for a hang.
"""

from __future__ import annotations

import contextlib
import os

import pytest

# markers left out of the default run; their descriptions are in pyproject.toml
LONG = ("slow", "kernel", "firmware", "umockdev")
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


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
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
    marker = {"slow": "a long test", "kernel": "a Linux guest under QEMU",
              "firmware": "the AVR firmware in simavr", "umockdev": "a umockdev session"}[name]
    capture = request.config.pluginmanager.get_plugin("capturemanager")
    # out of the test's capture: the line must reach the terminal before the long part
    with capture.global_and_fixture_disabled() if capture else contextlib.nullcontext():
        reporter.ensure_newline()
        reporter.write_line(f"[{name}] {request.node.nodeid}: running {marker}...")
