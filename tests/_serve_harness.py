"""An in-process ``bmg160-emu serve`` for the protocol tests: a ServeServer in a thread on a
private socket, boards built from chip configs, the sessions kept for white-box checks."""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from bmg160_emu.clock import RealTimeClock, VirtualClock
from bmg160_emu.device.config import ChipConfig
from bmg160_emu.device.standin import StandinConfig
from bmg160_emu.io.standin_file import load_standin
from bmg160_emu.serve.server import ServeServer
from bmg160_emu.serve.session import Board, Session

TRUE_RATE_DPS = (20.0, -10.0, 5.0)


def gyro(address: int = 0x68, part: str = "bmg160", **options: Any) -> ChipConfig:
    options.setdefault("true_rate_dps", TRUE_RATE_DPS)
    return ChipConfig(address=address, part=part, **options)


def accel(address: int = 0x18) -> StandinConfig:
    return StandinConfig(load_standin("bmi088_accel"), address)


@contextmanager
def serving(tmp_path: Path, configs: Sequence[Any] = (), *, seed: int = 7,
            realtime: bool = False, max_clients: int = 16,
            on_start: Callable[[Session], None] | None = None) -> Iterator[tuple[str, ServeServer]]:
    """(socket path, server) for the duration of the block; every board from ``configs``."""
    configs = list(configs) or [gyro()]
    folder = tmp_path / "sock"
    folder.mkdir(mode=0o700, exist_ok=True)
    path = os.fspath(folder / "s.sock")

    def make_board(_number: int) -> Board:
        clock = RealTimeClock() if realtime else VirtualClock()
        chips = {c.address: c.build(seed, clock) for c in configs}
        return Board(chips, clock, {cs: chips[a] for cs, a in enumerate(sorted(chips))})

    server = ServeServer(make_board, realtime=realtime, max_clients=max_clients,
                         on_session_start=on_start)
    server.listen_unix(path)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        yield path, server
    finally:
        server.stop()
        thread.join(10)
        server.close()
