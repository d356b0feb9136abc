"""The terminal view of ``bmg160-emu watch``, drawn with rich from the session's snapshots.

Per chip: the 64 registers by spec name (a register that changed stays highlighted for
``HIGHLIGHT_S``, and its decoded fields are listed), the three rates as sparklines of the last
``HISTORY`` snapshots, the FIFO level and the INT1/INT2 lines; for the session: transactions per
second and the last transactions.
"""

from __future__ import annotations

import contextlib
import os
import select
import sys
import time
from collections import deque
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from rich.console import Console, Group, RenderableType
from rich.live import Live
from rich.panel import Panel
from rich.table import Table
from rich.text import Text

from bmg160_emu.device.registers import REGISTERS, address_of, register

HISTORY = 48  # snapshots in a sparkline: about 5 s at ten snapshots a second
HIGHLIGHT_S = 2.0  # how long a changed register stays highlighted
DECODED_CHANGES = 6
FIFO_CAPACITY = 100  # frames (spec 6.5)
SPARK = "▁▂▃▄▅▆▇█"
# Below this many columns the side column (rates, FIFO, decoded changes) goes under the
# registers instead of beside them: the two-column register grid is 40 wide, the side ~62
# (a tmux pane split beside a session is often 64-80 columns).
SIDE_BY_SIDE_COLUMNS = 110
QUIT_KEYS = frozenset("qQ")  # leave the view (the session goes on)
CHANGED = "bold black on yellow"
LIVE = "cyan"
# Output and status registers change by themselves, with every sample: they are shown as
# live values (and as the rates, the FIFO level and the lines), not highlighted as changes,
# so what a driver configured stands out.
LIVE_REGISTERS = frozenset(
    address_of(name)
    for name in ("RATE_X_LSB", "RATE_X_MSB", "RATE_Y_LSB", "RATE_Y_MSB", "RATE_Z_LSB",
                 "RATE_Z_MSB", "TEMP", "INT_STATUS_0", "INT_STATUS_1", "INT_STATUS_2",
                 "INT_STATUS_3", "FIFO_STATUS", "FIFO_DATA")
)  # fmt: skip


def sparkline(values: list[float]) -> str:
    """Values as block characters scaled between their own minimum and maximum."""
    if not values:
        return ""
    low, high = min(values), max(values)
    if high - low < 1e-12:
        return SPARK[0] * len(values)
    top = len(SPARK) - 1
    return "".join(SPARK[round((v - low) / (high - low) * top)] for v in values)


class ChipView:
    """What the view remembers of one chip between snapshots. It starts from the reset
    values, so a view attached late still shows what the driver changed since reset."""

    def __init__(self) -> None:
        self.rates: list[deque[float]] = [deque(maxlen=HISTORY) for _ in range(3)]
        self.registers: list[int] = [reg.reset for reg in REGISTERS]
        self.changed_at = [float("-inf")] * len(REGISTERS)
        self.changes: deque[int] = deque(maxlen=DECODED_CHANGES)

    def update(self, chip: dict[str, Any], now: float) -> None:
        for axis, value in zip(self.rates, chip["rate_dps"]):
            axis.append(float(value))
        new = chip["registers"]
        for address, (old, value) in enumerate(zip(self.registers, new)):
            if old != value and address not in LIVE_REGISTERS:
                self.changed_at[address] = now
                if address in self.changes:
                    self.changes.remove(address)
                self.changes.append(address)
        self.registers = list(new)


class WatchView:
    """Turns snapshots into one renderable; ``update`` then ``render``."""

    def __init__(self) -> None:
        self.chips: dict[str, ChipView] = {}
        self.snapshot: dict[str, Any] | None = None
        self.now = 0.0

    def update(self, snapshot: dict[str, Any], now: float | None = None) -> None:
        self.now = time.monotonic() if now is None else now
        self.snapshot = snapshot
        for chip in snapshot["chips"]:
            self.chips.setdefault(chip["name"], ChipView()).update(chip, self.now)

    def render(self, width: int | None = None) -> RenderableType:
        """The view for a terminal ``width`` columns wide (None: wide)."""
        if self.snapshot is None:
            return Text("waiting for the session's first snapshot ...")
        snap = self.snapshot
        head = Text.assemble(
            ("bmg160-emu watch", "bold"), f"  {snap.get('title') or 'session'}",
            f"  pid {snap.get('pid')}  ", (f"{snap['transactions_per_s']:.0f} tx/s", "bold cyan"),
            f"  ({snap['transactions']} transactions)", ("   q quits the view", "dim"),
        )  # fmt: skip
        parts: list[RenderableType] = [head]
        for chip in snap["chips"]:
            parts.append(self._chip_panel(chip, self.chips[chip["name"]], width))
        last = Text("\n".join(snap["last"]) or "(none yet)", overflow="ellipsis", no_wrap=True)
        parts.append(Panel(last, title="last transactions", title_align="left"))
        return Group(*parts)

    def _chip_panel(self, chip: dict[str, Any], view: ChipView, width: int | None) -> Panel:
        narrow = width is not None and width < SIDE_BY_SIDE_COLUMNS
        # in a narrow pane the sparkline gets what the panel leaves after 'x  +10.132 °/s '
        spark = HISTORY if width is None else max(8, min(HISTORY, width - 4 - 16))
        side = Table.grid(padding=(0, 1))
        side.add_column()
        side.add_row(self._rates(chip, view, spark))
        side.add_row(self._fifo_and_lines(chip))
        side.add_row(self._decoded(chip, view))
        body = Table.grid(padding=(0, 2))
        body.add_column()
        if narrow:  # registers, then the rest underneath
            body.add_row(self._register_grid(chip, view))
            body.add_row(side)
        else:
            body.add_column()
            body.add_row(self._register_grid(chip, view), side)
        title = (
            f"BMG160 {chip['name']}  t = {chip['time_s']:.3f} s  ODR {chip['odr_hz']:g} Hz  "
            f"{chip.get('power_mode', '')}"
        )
        return Panel(body, title=title, title_align="left")

    def _register_grid(self, chip: dict[str, Any], view: ChipView) -> Table:
        grid = Table.grid(padding=(0, 1))
        for _ in range(2):
            grid.add_column(no_wrap=True)
        half = len(REGISTERS) // 2
        cells = []
        for reg in REGISTERS:
            value = chip["registers"][reg.address]
            if reg.address in LIVE_REGISTERS:
                style = LIVE
            elif self.now - view.changed_at[reg.address] < HIGHLIGHT_S:
                style = CHANGED
            else:
                style = ""
            cells.append(Text(f"{reg.address:02X} {reg.name[:13]:<13} {value:02X}", style=style))
        for row in range(half):
            grid.add_row(cells[row], cells[row + half])
        return grid

    def _rates(self, chip: dict[str, Any], view: ChipView, points: int = HISTORY) -> Table:
        table = Table.grid(padding=(0, 1))
        table.add_column(no_wrap=True)
        table.add_column(justify="right", no_wrap=True)
        table.add_column(no_wrap=True)
        for axis, value, history in zip("xyz", chip["rate_dps"], view.rates):
            recent = list(history)[-points:]
            table.add_row(axis, f"{value:+9.3f} °/s", Text(sparkline(recent), "green"))
        return table

    def _fifo_and_lines(self, chip: dict[str, Any]) -> Text:
        frames = int(chip["fifo_frames"])
        filled = round(frames / FIFO_CAPACITY * 20)
        text = Text(f"FIFO {frames:3d}/{FIFO_CAPACITY} ")
        text.append("█" * filled + "░" * (20 - filled), "magenta")
        for pin in ("int1", "int2"):
            active = chip[pin]
            text.append(f"  {pin.upper()} ")
            text.append("● on" if active else "○ off", "bold red" if active else "dim")
        return text

    def _decoded(self, chip: dict[str, Any], view: ChipView) -> Text:
        if not view.changes:
            return Text("all registers at their reset values", style="dim")
        text = Text("changed since reset or lately, newest first:\n", style="bold")
        lines = [register(a).describe(chip["registers"][a]) for a in reversed(view.changes)]
        text.append("\n".join(lines))
        text.overflow, text.no_wrap = "ellipsis", True
        return text


@contextlib.contextmanager
def keyboard(stream: IO[str] | None) -> Iterator[int | None]:
    """The terminal's keys one at a time, unechoed (cbreak mode; Ctrl-C still interrupts),
    as a file descriptor to ``select`` on; the terminal's mode is restored on the way out.
    None when ``stream`` is not a terminal (the view then ends with the session or Ctrl-C)."""
    if stream is None or not stream.isatty():
        yield None
        return
    import termios
    import tty

    fd = stream.fileno()
    saved = termios.tcgetattr(fd)
    tty.setcbreak(fd)
    try:
        yield fd
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)


def run_viewer(path: Path, console: Console | None = None, keys: IO[str] | None = None,
               timeout_s: float = 5.0) -> int:
    """Show the session behind the socket ``path`` until it ends, ``q`` is pressed on ``keys``
    (default: standard input, when it is a terminal) or Ctrl-C; the session goes on."""
    from bmg160_emu.watch.session import SnapshotConnection, WatchError

    console = console or Console()
    view = WatchView()
    ended = False
    with SnapshotConnection(path) as connection, keyboard(keys or sys.stdin) as key_fd, \
            Live(view.render(console.width), console=console, auto_refresh=False, screen=False) as live:
        waiting = [connection] + ([key_fd] if key_fd is not None else [])
        heard = time.monotonic()
        try:
            while True:
                ready, _, _ = select.select(waiting, [], [], 0.25)
                if key_fd is not None and key_fd in ready:
                    pressed = os.read(key_fd, 64).decode(errors="replace")
                    if QUIT_KEYS & set(pressed):
                        break
                    if not pressed:  # the terminal hung up: the view ends with the session
                        waiting.remove(key_fd)
                if connection in ready:
                    snapshots = connection.read()
                    if snapshots is None:
                        ended = True
                        break
                    if snapshots:
                        heard = time.monotonic()
                        view.update(snapshots[-1])
                        live.update(view.render(console.width), refresh=True)
                elif time.monotonic() - heard > timeout_s:
                    raise WatchError(f"{path}: the session stopped answering")
        except KeyboardInterrupt:
            pass
    if ended:
        console.print(f"bmg160-emu watch: the session behind {path} ended")
    else:
        console.print("bmg160-emu watch: left the view; the session goes on")
    return 0
