"""The uml engine: its command line keeps the engine contract (hostfs root read-only, the
back ends as virtio_uml devices, the agent as init, the script's environment on the kernel
command line, the calendar's socket for virtual time), it says what is missing in one line
each, and it registers ahead of QEMU."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bmg160_emu.linux.guest import agent, uml, uml_build
from bmg160_emu.linux.guest import engine as engine_module
from bmg160_emu.linux.guest.engine import AgentBoot, Boot, EngineError

needs_gcc = pytest.mark.skipif(bool(agent.missing()), reason="; ".join(agent.missing()))


@pytest.fixture
def built(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> uml_build.UmlKernel:
    """A cache holding a finished build's marks (no kernel binary is run here)."""
    monkeypatch.setenv("BMG160_EMU_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(uml_build, "source_version", lambda: "6.1.176-1")
    root = uml_build.build_root()
    assert root is not None
    kernel = uml_build.UmlKernel(root)
    kernel.vio.mkdir(parents=True)
    (kernel.vio / "ready").write_text("")
    (root / "ready").write_text(json.dumps({"release": "6.1.176", "fp_area_bytes": 12288}))
    return kernel


@needs_gcc
def test_the_command_line_serves_both_back_ends_on_a_read_only_host_root(
        built: uml_build.UmlKernel, tmp_path: Path) -> None:
    boot = Boot(script=tmp_path / "run.sh", results=tmp_path / "out",
                i2c_socket=tmp_path / "i2c.sock", gpio_socket=tmp_path / "gpio.sock",
                environment={"READS": "100"}, modules=("bmg160_i2c", tmp_path / "my.ko"),
                memory_mb=256)
    command = uml.engine().command(boot)
    assert command[0] == str(built.binary)
    words = command[1:]
    for word in ("mem=256M", "rootfstype=hostfs", "rootflags=/", "ro", f"init={agent.binary()}",
                 f"virtio_uml.device={tmp_path / 'i2c.sock'}:34",
                 f"virtio_uml.device={tmp_path / 'gpio.sock'}:41",
                 f"guest_script={tmp_path / 'run.sh'}", f"guest_out={tmp_path / 'out'}",
                 f"guest_vio={built.vio}", f"guest_modroot={built.modules_root}",
                 f"guest_modules=bmg160_i2c,{tmp_path / 'my.ko'}", "READS=100"):
        assert word in words, word
    writable = uml.engine().command(Boot(script=boot.script, results=boot.results,
                                         host_root_readonly=False))
    assert "rw" in writable and "ro" not in writable
    assert not any(w.startswith(("virtio_uml.device=", "guest_vio=", "time-travel"))
                   for w in writable)
    # the harness's guests: the agent serves a folder on two virtio-gpio lines, and in
    # virtual time the calendar's socket is UML's clock (time-travel=ext)
    served = uml.engine().command(Boot(results=boot.results, time_travel=tmp_path / "t.sock",
                                       agent=AgentBoot(tmp_path / "out" / ".agent", "4", "5")))
    assert f"guest_agent={tmp_path / 'out' / '.agent'},4,5" in served
    assert f"time-travel=ext:{tmp_path / 't.sock'}" in served
    assert not any(w.startswith("guest_script=") for w in served)
    with pytest.raises(EngineError, match="a script or the agent"):
        uml.engine().command(Boot(results=boot.results))


@needs_gcc
@pytest.mark.parametrize("environment", [{"lower": "1"}, {"KEY": "two words"}])
def test_an_environment_word_the_command_line_cannot_carry_is_refused(
        built: uml_build.UmlKernel, tmp_path: Path, environment: dict[str, str]) -> None:
    with pytest.raises(EngineError, match="environment word"):
        uml.engine().command(Boot(script=tmp_path / "s", results=tmp_path / "o",
                                  environment=environment))


@needs_gcc
def test_more_than_one_cpu_is_refused(built: uml_build.UmlKernel, tmp_path: Path) -> None:
    with pytest.raises(EngineError, match="one CPU"):
        uml.engine().command(Boot(script=tmp_path / "s", results=tmp_path / "o", cpus=2))


def test_without_a_build_it_says_how_to_make_one(tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BMG160_EMU_CACHE", str(tmp_path))
    monkeypatch.setattr(uml_build, "missing_packages", list)
    monkeypatch.setattr(uml, "host_xsave_bytes", lambda: 2432)
    assert uml.engine().missing() == [
        f"no UML kernel in {tmp_path} yet (run: bmg160-emu kernel prepare --engine uml)"]
    with pytest.raises(EngineError, match="kernel prepare --engine uml"):
        uml.engine().command(Boot(script=tmp_path / "s", results=tmp_path / "o"))


def test_missing_packages_and_a_large_fpu_state_are_one_line_each(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BMG160_EMU_CACHE", str(tmp_path))
    monkeypatch.setattr(uml_build, "missing_packages", lambda: ["flex", "linux-source-6.1"])
    monkeypatch.setattr(uml, "host_xsave_bytes", lambda: 20480)
    lines = uml.engine().missing()
    assert lines[:2] == ["flex is missing (Debian package flex)",
                         "linux-source-6.1 is missing (Debian package linux-source-6.1)"]
    assert len(lines) == 3 and "20480 bytes" in lines[2]
    with pytest.raises(EngineError, match="20480 bytes"):
        uml.engine().prepare(lambda _: None)


def test_uml_is_registered_ahead_of_qemu() -> None:
    available = engine_module.engines()
    assert "uml" in available
    assert isinstance(available["uml"], engine_module.Engine)
    names = list(available)
    if "qemu" in names:
        assert names.index("uml") < names.index("qemu")
