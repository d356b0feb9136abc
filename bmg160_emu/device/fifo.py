"""The BMG160 FIFO (spec 6.5): 100 frames, bypass/FIFO/stream, partial frames, empty pattern."""

from __future__ import annotations

from collections import deque

from bmg160_emu.device import spec_choices

BYPASS, FIFO, STREAM = 0, 1, 2
AXIS_SLICES = {0: slice(0, 6), 1: slice(0, 2), 2: slice(2, 4), 3: slice(4, 6)}  # 4.26


class Fifo:
    """Frames as bytes; the head frame may be partly read (``head_offset`` bytes)."""

    capacity = spec_choices.FIFO_CAPACITY_FRAMES

    def __init__(self) -> None:
        self.frames: deque[bytes] = deque()
        self.head_offset = 0
        self.overrun = False

    @property
    def count(self) -> int:
        return len(self.frames)

    def clear(self, *, overrun: bool = False) -> None:
        """Empty the FIFO; ``overrun=True`` also clears the overrun flag."""
        self.frames.clear()
        self.head_offset = 0
        if overrun:
            self.overrun = False

    def replace(self, frame: bytes) -> None:
        """Bypass mode: only the newest frame is held."""
        self.frames.clear()
        self.frames.append(frame)
        self.head_offset = 0

    def push(self, frame: bytes, mode: int) -> None:
        """Store one frame in FIFO (stop when full) or stream (drop oldest) mode."""
        if len(self.frames) < self.capacity:
            self.frames.append(frame)
            return
        self.overrun = True
        if mode == STREAM:
            self.frames.popleft()
            self.head_offset = 0
            self.frames.append(frame)

    def push_many(self, frames: list[bytes], mode: int, total: int | None = None) -> None:
        """Store ``total`` new frames in order, the same as ``push`` of each.

        ``frames`` may hold only the frames that can survive: the first ``room`` in FIFO
        mode, the last ``capacity`` in stream mode.
        """
        total = len(frames) if total is None else total
        room = self.capacity - len(self.frames)
        if total <= room:
            self.frames.extend(frames)
            return
        self.overrun = True
        if mode == STREAM:
            keep = frames[-self.capacity:]
            drop = len(self.frames) + len(keep) - self.capacity
            for _ in range(max(drop, 0)):
                self.frames.popleft()
            if drop > 0:
                self.head_offset = 0
            self.frames.extend(keep)
        else:
            self.frames.extend(frames[:room])

    def kept(self, k_first: int, n: int, mode: int) -> range:
        """Which of n new samples k_first.. end up stored: the first that fit in FIFO mode,
        the last ``capacity`` in stream mode (for ``push_many``)."""
        if mode == FIFO:
            room = max(self.capacity - self.count, 0)
            return range(k_first, k_first + min(n, room))
        k_last = k_first + n - 1
        return range(max(k_first, k_last - self.capacity + 1), k_last + 1)

    def read(self, n: int, axis_bytes: int, tagged: bool) -> bytes:
        """Pop ``n`` bytes; past the last frame, the empty pattern of the current format."""
        out = []
        frames = self.frames
        while n > 0 and frames:
            head = frames[0]
            if not self.head_offset and len(head) <= n:  # a whole frame (the usual burst)
                out.append(head)
                n -= len(head)
                frames.popleft()
                continue
            chunk = head[self.head_offset:self.head_offset + n]
            out.append(chunk)
            n -= len(chunk)
            self.head_offset += len(chunk)
            if self.head_offset >= len(head):
                frames.popleft()
                self.head_offset = 0
        if n > 0:
            out.append(empty_pattern(n, axis_bytes, tagged))
        return b"".join(out)

    def peek(self, axis_bytes: int, tagged: bool) -> int:
        """The next byte a read would return, without consuming it."""
        if self.frames:
            return self.frames[0][self.head_offset]
        return empty_pattern(1, axis_bytes, tagged)[0]

    def end_transaction(self) -> None:
        """Apply the partial-frame rule when a transaction stops inside a frame."""
        if self.head_offset and not spec_choices.FIFO_KEEP_PARTIAL_FRAME:
            self.frames.popleft()
            self.head_offset = 0


def empty_pattern(n: int, axis_bytes: int, tagged: bool) -> bytes:
    """Bytes read past the last frame: -32768 per word, tag bytes 0x00 (6.5)."""
    frame = spec_choices.FIFO_EMPTY_WORD * (axis_bytes // 2)
    if tagged:
        frame += bytes((spec_choices.FIFO_EMPTY_TAG,)) * 2
    reps = n // len(frame) + 1
    return (frame * reps)[:n]
