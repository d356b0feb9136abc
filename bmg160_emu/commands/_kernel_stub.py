"""Runs INSIDE the guest for ``bmg160-emu kernel run --route stub``: the chips the host's
command line described, kept in the guest kernel's i2c-stub memory until SIGTERM.

Why the options travel pickled: the chips must be built in the guest (i2c-stub's memory is
only reachable there, through /dev/i2c-N) exactly as the host's parser understood them;
the parsed ``argparse.Namespace`` is what :func:`chips_from_args` takes.

Usage: ``python -m bmg160_emu.commands._kernel_stub OPTIONS.pickle BUS READY_FILE``.
"""

from __future__ import annotations

import pickle
import signal
import sys
import threading
from pathlib import Path
from typing import Any


def serve(options: Path, bus: int, ready: Path) -> int:
    from bmg160_emu.commands._chip_options import chips_from_args
    from bmg160_emu.device.contract import RateSensor
    from bmg160_emu.linux.i2c_stub import I2CStubAdapter
    from bmg160_emu.linux.i2c_stub_standin import StandinStubAdapter

    args = pickle.loads(options.read_bytes())  # written by commands/kernel.py, same host
    chips = chips_from_args(args, default_bus=bus, announce=False)
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    adapters: list[Any] = [
        StandinStubAdapter(chip, bus, address) if not isinstance(chip, RateSensor)  # a stand-in
        else I2CStubAdapter(chip, bus, address) for address, chip in chips.items()]
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
