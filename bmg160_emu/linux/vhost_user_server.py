"""Serving vhost-user devices: private sockets, one event loop for messages, kicks and timers.

Why one thread: the model is not re-entrant across devices (a GPIO line follows the same
chip the I2C requests reach), and a single ``selectors`` loop keeps every guest transfer
ordered with the interrupt lines' updates without locks on the hot path.

:class:`Connection` reads each vhost-user message (header, payload, file descriptors) from
the socket, has the device answer it, and sends the reply. Sockets live in a directory of
the user's own, closed to others (created 0700 when missing); the back end refuses a
directory or socket another user owns, and a socket some back end still listens on.
"""

from __future__ import annotations

import collections
import errno
import logging
import math
import os
import select
import socket
import stat
import struct
import time
from collections.abc import Callable

from bmg160_emu.linux.vhost_user import (
    FLAG_NEED_REPLY,
    FLAG_REPLY,
    HEADER,
    MAX_FDS,
    MAX_PAYLOAD,
    MESSAGE_NAMES,
    PROTOCOL_F_REPLY_ACK,
    U64,
    VERSION,
    VhostUserDevice,
    VhostUserError,
)

log = logging.getLogger(__name__)

class Connection:
    """One front end (QEMU) on a connected socket, for one device."""

    def __init__(self, sock: socket.socket, device: VhostUserDevice,
                 before_reply: Callable[[], None] | None = None) -> None:
        self.sock = sock
        self.device = device
        self.messages = 0
        self.before_reply = before_reply  # e.g. the calendar's last word before a kick's reply

    def receive(self) -> bool:
        """Read and answer one message; False when the front end has gone."""
        try:
            head, fds, _flags, _addr = socket.recv_fds(self.sock, HEADER.size, MAX_FDS)
        except ConnectionResetError:
            return False
        if not head:
            return False
        try:
            if len(head) < HEADER.size:
                head += self._exactly(HEADER.size - len(head))
            request, flags, size = HEADER.unpack(head)
            if flags & 0x3 != VERSION:
                raise VhostUserError(f"vhost-user version {flags & 3}, expected {VERSION}")
            if size > MAX_PAYLOAD:
                raise VhostUserError(f"message {request} of {size} bytes is too long")
            payload = self._exactly(size) if size else b""
        except BaseException:
            for fd in fds:
                os.close(fd)
            raise
        self.messages += 1
        self.answer(request, flags, payload, fds)
        return True

    def _exactly(self, size: int) -> bytes:
        data = b""
        while len(data) < size:
            chunk = self.sock.recv(size - len(data))
            if not chunk:
                raise VhostUserError("front end closed the socket inside a message")
            data += chunk
        return data

    def answer(self, request: int, flags: int, payload: bytes, fds: list[int]) -> None:
        device = self.device
        name = MESSAGE_NAMES.get(request, str(request))
        log.debug("%s: %s (%d bytes, %d fds)", device.name, name, len(payload), len(fds))
        status = 0
        reply: bytes | None = None
        try:
            reply = device.handle(request, payload, fds)
        except OSError as exc:
            for fd in fds:  # fds the handler did not take
                try:
                    os.close(fd)
                except OSError:
                    pass
            log.warning("%s: %s failed: %s", device.name, name, exc)
            status = exc.errno or errno.EIO
        except struct.error as exc:
            raise VhostUserError(f"{name}: malformed payload ({exc})") from None
        if reply is None and flags & FLAG_NEED_REPLY and (
                device.protocol_features >> PROTOCOL_F_REPLY_ACK & 1):
            reply = U64.pack(status)
        if reply is not None:
            # the front end waits for this reply (UML reading only it and its calendar):
            # the one moment the calendar may add a word of its own
            if self.before_reply is not None:
                self.before_reply()
            self._send(request, reply)

    def _send(self, request: int, payload: bytes) -> None:
        self.sock.sendall(HEADER.pack(request, VERSION | FLAG_REPLY, len(payload)) + payload)

    def close(self) -> None:
        self.device.reset()
        self.sock.close()


class SocketPathError(Exception):
    """A socket path the back end will not serve on (one line, for the command line)."""


# A UNIX socket's address holds at most this many bytes of path (Linux's sockaddr_un:
# sun_path[108], the last byte the terminating NUL; unix(7)); bind() is given the path as
# the user wrote it, relative or absolute.
SUN_PATH_MAX = 107


def check_socket_path(path: str) -> None:
    """Make sure ``path`` can be served privately: short enough for a socket address, its
    directory ours and closed to others (created 0700 if missing, and only after the
    length is known to fit: a path past the limit leaves no folders behind); an existing
    file there is a stale socket of ours."""
    size = len(os.fsencode(path))
    if size > SUN_PATH_MAX:
        shown = path if len(path) <= 60 else path[:28] + "..." + path[-28:]
        raise SocketPathError(f"{shown}: a UNIX socket's path holds at most {SUN_PATH_MAX} "
                              f"bytes (sun_path, unix(7)); this one has {size}: use a "
                              "shorter path (a folder nearer /)")
    directory = os.path.dirname(os.path.abspath(path))
    uid = os.getuid()
    if not os.path.exists(directory):
        try:
            os.makedirs(directory, mode=0o700)
        except OSError as exc:
            raise SocketPathError(f"cannot create {directory}: {exc.strerror}") from None
    info = os.stat(directory)
    if info.st_uid != uid:
        raise SocketPathError(
            f"{directory} belongs to user {info.st_uid}, not to you ({uid}): "
            "the socket must live in a directory of your own"
        )
    if info.st_mode & 0o077:
        raise SocketPathError(
            f"{directory} is open to other users (mode {info.st_mode & 0o777:o}): "
            "use a private directory (chmod 700)"
        )
    try:
        existing = os.lstat(path)
    except FileNotFoundError:
        return


    if existing.st_uid != uid:
        raise SocketPathError(f"{path} belongs to user {existing.st_uid}, not to you ({uid})")
    if not stat.S_ISSOCK(existing.st_mode):
        raise SocketPathError(f"{path} exists and is not a socket")
    probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        probe.connect(path)
    except OSError:
        os.unlink(path)  # nobody listens: a stale socket of an earlier run
    else:
        raise SocketPathError(f"{path}: another back end is already serving on it")
    finally:
        probe.close()


def listen(path: str) -> socket.socket:
    """A listening UNIX socket at ``path`` (checked with :func:`check_socket_path`), mode 0600."""
    check_socket_path(path)
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    old = os.umask(0o177)
    try:
        sock.bind(path)
    finally:
        os.umask(old)
    sock.listen(1)
    return sock


Poller = Callable[[float], "float | None"]  # poll(now_s) -> next deadline (monotonic s) or None


class Server:
    """Listen on one socket per device; serve messages, kicks and pollers until stopped.

    The loop is ``epoll`` with one handler per file descriptor: a guest's kick costs one
    wait, one eventfd read and the device's :meth:`~VhostUserDevice.kick`. A kick fd is
    watched through a duplicate of our own, so it leaves the epoll set exactly when we
    stop watching it, whenever the device closes its copy (the front end still holds the
    eventfd: a registration of a closed descriptor would otherwise keep firing).
    """

    def __init__(self) -> None:
        self._epoll = select.epoll()
        self._handlers: dict[int, Callable[[], None]] = {}
        self.pollers: list[Poller] = []
        self._stop = False
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._watch(self._wake_r, self._drain_wake)
        self.listeners: list[tuple[socket.socket, str]] = []
        self.connections: dict[VhostUserDevice, Connection] = {}
        self.before_reply: Callable[[], None] | None = None  # every connection's (calendar)
        self._kicks: dict[VhostUserDevice, list[int]] = {}  # our duplicates of its kick fds
        self._deadlines: dict[Poller, float] = {}  # {poller: monotonic time to call it}
        self._next_due = math.inf  # the earliest of them
        self._calls: collections.deque[Callable[[], None]] = collections.deque()

    def _watch(self, fd: int, handler: Callable[[], None]) -> None:
        self._epoll.register(fd, select.EPOLLIN)
        self._handlers[fd] = handler

    def _unwatch(self, fd: int) -> None:
        if self._handlers.pop(fd, None) is not None:
            self._epoll.unregister(fd)

    watch = _watch  # for what shares the loop (the time-travel calendar)
    unwatch = _unwatch

    def add(self, path: str, device: VhostUserDevice) -> None:
        sock = listen(path)
        self.listeners.append((sock, path))
        self._watch(sock.fileno(), lambda: self._accept(sock, device))
        device.on_fds_changed = lambda d=device: self._update_kicks(d)

    def stop(self) -> None:
        """Safe from a signal handler: ends :meth:`run` at its next turn."""
        self._stop = True
        try:
            os.write(self._wake_w, b"x")
        except OSError:
            pass

    def call_soon(self, action: Callable[[], None]) -> None:
        """Run ``action`` on the loop's thread at its next turn (safe from any thread)."""
        self._calls.append(action)
        try:
            os.write(self._wake_w, b"c")
        except BlockingIOError:
            pass  # the pipe is full of wake-ups already: the loop will look

    def _drain_wake(self) -> None:
        try:
            os.read(self._wake_r, 4096)
        except BlockingIOError:
            pass
        while self._calls:
            self._calls.popleft()()

    def _update_kicks(self, device: VhostUserDevice) -> None:
        for fd in self._kicks.pop(device, []):
            self._unwatch(fd)
            os.close(fd)
        watched = []
        for fd, index in device.kick_fds().items():
            ours = os.dup(fd)
            self._watch(ours, self._kick_handler(device, index, ours))
            watched.append(ours)
        self._kicks[device] = watched

    def _kick_handler(self, device: VhostUserDevice, index: int, fd: int) -> Callable[[], None]:
        kick = device.kick
        eventfd_read = os.eventfd_read

        def on_kick() -> None:
            try:
                eventfd_read(fd)
            except BlockingIOError:
                pass
            try:
                kick(index)
            except VhostUserError as exc:  # the guest broke the ring: stop serving this one
                log.error("%s: queue %d: %s; closing the connection", device.name, index, exc)
                connection = self.connections.get(device)
                if connection is not None:
                    self._drop(connection)

        return on_kick

    def _accept(self, listener: socket.socket, device: VhostUserDevice) -> None:
        sock, _ = listener.accept()
        if device in self.connections:  # one front end at a time per device
            log.warning("%s: a second front end connected; refused", device.name)
            sock.close()
            return
        connection = Connection(sock, device, self.before_reply)
        self.connections[device] = connection
        self._watch(sock.fileno(), lambda: self._message(connection))
        log.info("%s: front end connected", device.name)

    def _drop(self, connection: Connection) -> None:
        device = connection.device
        self._unwatch(connection.sock.fileno())
        self.connections.pop(device, None)
        connection.close()
        self._update_kicks(device)
        log.info("%s: front end disconnected", device.name)

    def schedule(self, poller: Poller, at_s: float | None) -> None:
        """Call ``poller`` at monotonic time ``at_s`` or before (None: no change)."""
        if at_s is None:
            return
        current = self._deadlines.get(poller)
        if current is None or at_s < current:
            self._deadlines[poller] = at_s
            self._next_due = min(self._next_due, at_s)

    def _run_due(self, now: float) -> None:
        deadlines = self._deadlines
        for poller, deadline in list(deadlines.items()):
            if deadline <= now:
                del deadlines[poller]
                self.schedule(poller, poller(now))
        self._next_due = min(deadlines.values(), default=math.inf)

    def run(self, duration_s: float | None = None) -> None:
        """Serve until :meth:`stop` (or ``duration_s``). A poller returns the monotonic
        time it wants to be called again, or None: only when :meth:`schedule` asks."""
        end = math.inf if duration_s is None else time.monotonic() + duration_s
        for poller in self.pollers:
            if poller not in self._deadlines:
                self.schedule(poller, 0.0)
        poll = self._epoll.poll
        handlers = self._handlers
        monotonic = time.monotonic
        while not self._stop:
            timeout = -1.0
            if self._next_due != math.inf or end != math.inf:
                now = monotonic()
                if now >= end:
                    break
                if now >= self._next_due:
                    self._run_due(now)
                due = min(self._next_due, end)
                if due != math.inf:  # (the pollers may want no call any more)
                    timeout = max(due - now, 0.0)
            for fd, _ in poll(timeout):
                handler = handlers.get(fd)
                if handler is not None:  # (one handled earlier in this batch may drop it)
                    handler()

    def _message(self, connection: Connection) -> None:
        try:
            alive = connection.receive()
        except VhostUserError as exc:
            log.error("%s: %s; closing the connection", connection.device.name, exc)
            alive = False
        except OSError as exc:
            log.error("%s: socket error %s; closing the connection", connection.device.name, exc)
            alive = False
        if not alive:
            self._drop(connection)

    def close(self) -> None:
        for connection in list(self.connections.values()):
            self._drop(connection)
        for sock, path in self.listeners:
            self._unwatch(sock.fileno())
            sock.close()
            try:
                os.unlink(path)
            except FileNotFoundError:
                pass
        self.listeners = []
        for device in list(self._kicks):
            for fd in self._kicks.pop(device):
                self._unwatch(fd)
                os.close(fd)
        self._unwatch(self._wake_r)
        os.close(self._wake_r)
        os.close(self._wake_w)
        self._epoll.close()
