"""The i2c-stub route of ``bmg160-emu kernel run --route stub``: the chips live in the guest,
kept in the guest kernel's i2c-stub memory by the adapters of :mod:`bmg160_emu.linux.i2c_stub`.

Why the chips are built inside the guest: i2c-stub's memory is only reachable there (through
/dev/i2c-N). The host describes them as :class:`~bmg160_emu.device.config.ChipConfig` (or
stand-in) entries, the format trace headers carry (``to_dict``), with the session's seed;
:func:`serve` builds the same devices from them (``from_dict``), so every chip option of the
command line arrives as it was parsed, and an option that cannot travel is refused on the
host, in one line.

Host side: :func:`start` (load i2c-stub and i2c-dev, start the adapters in the background,
wait for them), :func:`stop`. Guest side: ``python -m bmg160_emu.linux.guest.stub_route
CHIPS.json BUS READY_FILE`` serves until SIGTERM.
"""

from __future__ import annotations

import json
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bmg160_emu.linux.guest import agent
from bmg160_emu.linux.guest.engine import EngineError

STUB_NAME = "SMBus stub driver"  # i2c-stub's adapter name (drivers/i2c/i2c-stub.c)
START_S = 120.0  # the adapters' start in the guest: Python and numpy imports under ptrace


def describe(configs: Sequence[Any], seed: int | None) -> str:
    """The chips as the guest will build them: JSON with the seed and each config's entry
    (a function-valued option cannot travel: ValueError, naming it)."""
    return json.dumps({"seed": seed, "chips": [config.to_dict() for config in configs]})


def configs(text: str) -> tuple[int | None, list[Any]]:
    """The seed and configs :func:`describe` wrote."""
    from bmg160_emu.device.config import ChipConfig
    from bmg160_emu.device.standin import StandinConfig
    from bmg160_emu.io.standin_file import spec_from_dict

    description = json.loads(text)
    out: list[Any] = []
    for i, entry in enumerate(description["chips"]):
        if "standin" in entry:
            out.append(StandinConfig(spec_from_dict(entry["standin"], f"chips[{i}].standin"),
                                     int(entry["address"]), entry.get("bus")))
        else:
            out.append(ChipConfig.from_dict(entry))
    return description["seed"], out


def start(guest: Any, chip_configs: Sequence[Any], seed: int | None) -> int:
    """Load i2c-stub with the chips' addresses (and i2c-dev), start the adapters in the
    guest and wait until they have preloaded the registers; the stub's bus number."""
    addresses = ",".join(f"0x{c.address:02x}" for c in chip_configs)
    folder = guest.agent_dir
    replies = guest.call([agent.modprobe("i2c-stub", f"chip_addr={addresses}"),
                          agent.modprobe("i2c-dev"),
                          agent.glob("/sys/bus/i2c/devices/i2c-*/name")])
    if replies[0].status or replies[1].status:
        bad = replies[0] if replies[0].status else replies[1]
        raise EngineError(f"i2c-stub did not load in the guest: {bad.error()}")
    names = replies[2].text.split()
    found = [r.text for r in guest.call([agent.read(n) for n in names])]
    buses = [int(n.split("/i2c-")[1].split("/")[0]) for n, text in zip(names, found)
             if text.startswith(STUB_NAME)]
    if not buses:
        raise EngineError("i2c-stub loaded, but no bus of it appeared in the guest")
    description = folder / "stub-chips.json"
    description.write_text(describe(chip_configs, seed))
    ready, log = folder / "stub.ready", folder / "stub.log"
    started = guest.call([
        agent.run("/", f'"$BMG160_PY" -m {__name__} {description} {buses[0]} {ready} '
                       f"> {log} 2>&1 & echo $! > {folder / 'stub.pid'}",
                  folder / "stub-start.out", folder / "stub-start.err", check=True),
        agent.wait(str(ready), START_S)], timeout_s=START_S + 60)
    if started[0].status or started[1].status:
        tail = log.read_text(errors="replace").strip().splitlines()[-1:] if log.exists() else []
        raise EngineError("the i2c-stub adapters did not start in the guest"
                          + (f": {tail[0]}" if tail else ""))
    return buses[0]


def stop(guest: Any) -> None:
    """SIGTERM to the adapters (they end at their next refresh)."""
    pid = guest.agent_dir / "stub.pid"
    guest.run(f"kill -TERM $(cat {pid}) 2>/dev/null", check=False)


def serve(description: Path, bus: int, ready: Path) -> int:
    """Inside the guest: build the chips, keep them in i2c-stub's memory until SIGTERM."""
    from bmg160_emu.clock import RealTimeClock
    from bmg160_emu.device.contract import RateSensor
    from bmg160_emu.linux.i2c_stub import I2CStubAdapter
    from bmg160_emu.linux.i2c_stub_standin import StandinStubAdapter

    seed, chip_configs = configs(description.read_text())
    clock = RealTimeClock()  # the guest's own clock (in virtual time, the chips' calendar's)
    adapters: list[Any] = []
    for config in chip_configs:
        device = config.build(seed, clock)
        # a gyro's adapter refreshes its data at the output rate; a stand-in's applies writes
        adapter_type = I2CStubAdapter if isinstance(device, RateSensor) else StandinStubAdapter
        adapters.append(adapter_type(device, bus, config.address))
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    for adapter in adapters:
        adapter.preload()
    threads = [threading.Thread(target=adapter.run,
                                kwargs={"should_stop": stop.is_set, "preload": False})
               for adapter in adapters]
    for thread in threads:
        thread.start()
    ready.write_text("ready\n")
    while not stop.wait(0.2):
        if not all(thread.is_alive() for thread in threads):
            stop.set()
            return 1
    for thread in threads:
        thread.join()
    return 0


if __name__ == "__main__":
    raise SystemExit(serve(Path(sys.argv[1]), int(sys.argv[2]), Path(sys.argv[3])))
