"""The serve loop: accept simulators on a socket, read their messages, answer each in turn.

Why one thread and one ``selectors`` loop: every client has a board of its own, so nothing
is shared between them but the loop; a request is answered before the next is read, which
keeps a simulator's transfers and its line levels in order without locks.

Robustness (issue 33): a message the server cannot follow (unknown type, wrong size, a
length past MAX_PAYLOAD, no HELLO first) ends that connection with an ERROR message and
one line on the log; a client that goes away, also in the middle of a message, ends its
session with a one-line note. Either way the session's trace keeps every transfer it
served (``on_session_end`` closes it); the other clients go on.

Real-time sessions (chips on wall time) get EVENT messages pushed when a line changes: a
timer per session wakes at the chips' next possible change.
"""

from __future__ import annotations

import errno
import logging
import math
import os
import selectors
import socket
import time
from collections.abc import Callable
from typing import Any

from bmg160_emu.clock import NS_PER_S
from bmg160_emu.linux.vhost_user_server import check_socket_path
from bmg160_emu.serve import protocol as p
from bmg160_emu.serve.session import Board, Session

log = logging.getLogger(__name__)

RECV_SIZE = 1 << 16
MAX_CLIENTS = 16  # default cap on simultaneous clients; one more is refused with ERROR


class _Refused:
    """A client over the limit: told why, closed when it speaks or goes."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock


def _drain(sock: socket.socket) -> None:
    """Read what the peer already sent (and drop it), so that closing does not reset."""
    try:
        sock.shutdown(socket.SHUT_WR)
    except OSError:
        pass
    sock.setblocking(False)
    try:
        while sock.recv(RECV_SIZE):
            pass
    except OSError:
        pass


class Connection:
    """One client socket: what it sent so far, what is still to send, its session."""

    def __init__(self, sock: socket.socket, session: Session) -> None:
        self.sock = sock
        self.session = session
        self.inbox = bytearray()
        self.outbox = bytearray()
        self.wake_at = math.inf  # real time: monotonic time of the next line check
        self.pushed_levels: int | None = None

    @property
    def name(self) -> str:
        client = self.session.client_name
        return f"client {self.session.number}" + (f" ({client})" if client else "")


class ServeServer:
    """Serve boards made by ``make_board(n)`` to every client that connects.

    ``on_session_start(session)`` is called when a client connects (attach a trace to
    ``session.log`` there) and ``on_session_end(session)`` when its connection ends, for
    whatever reason (close the trace there). ``realtime``: the boards' chips run on wall
    time (their factory gives them a RealTimeClock) and line changes are pushed.
    """

    def __init__(self, make_board: Callable[[int], Board], *, realtime: bool = False,
                 max_clients: int = MAX_CLIENTS,
                 on_session_start: Callable[[Session], None] | None = None,
                 on_session_end: Callable[[Session], None] | None = None) -> None:
        self.make_board = make_board
        self.realtime = realtime
        self.max_clients = max_clients
        self.on_session_start = on_session_start
        self.on_session_end = on_session_end
        self.selector = selectors.DefaultSelector()
        self.listeners: list[tuple[socket.socket, str | None]] = []
        self.connections: dict[int, Connection] = {}
        self.sessions: list[Session] = []  # every session so far, ended or not
        self.refused = 0
        self._stop = False
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self.selector.register(self._wake_r, selectors.EVENT_READ, None)

    # ---------------------------------------------------------------- sockets

    def listen_unix(self, path: str) -> None:
        """Listen on a UNIX socket in a private directory (mode 0600, see
        linux.vhost_user_server.check_socket_path); SocketPathError names the problem."""
        check_socket_path(path)
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        old = os.umask(0o177)
        try:
            sock.bind(path)
        finally:
            os.umask(old)
        self._listen(sock, path)

    def listen_tcp(self, port: int, host: str = "127.0.0.1") -> int:
        """Listen on a loopback TCP port (0: any free one); the port listened on."""
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((host, port))
        self._listen(sock, None)
        return int(sock.getsockname()[1])

    def _listen(self, sock: socket.socket, path: str | None) -> None:
        sock.listen(self.max_clients)
        sock.setblocking(False)
        self.listeners.append((sock, path))
        self.selector.register(sock, selectors.EVENT_READ, sock)

    def stop(self) -> None:
        """Safe from a signal handler: :meth:`run` returns at its next turn."""
        self._stop = True
        try:
            os.write(self._wake_w, b"x")
        except OSError:
            pass

    # ---------------------------------------------------------------- the loop

    def run(self, duration_s: float | None = None) -> None:
        """Serve until :meth:`stop` or ``duration_s`` (wall time) has passed."""
        end = math.inf if duration_s is None else time.monotonic() + duration_s
        listeners = {id(s) for s, _ in self.listeners}
        while not self._stop:
            now = time.monotonic()
            if now >= end:
                break
            due = min([end] + [c.wake_at for c in self.connections.values()])
            timeout = None if due == math.inf else max(due - now, 0.0)
            for key, events in self.selector.select(timeout):
                target = key.data
                if target is None:
                    try:
                        os.read(self._wake_r, 64)
                    except BlockingIOError:
                        pass
                elif id(target) in listeners:
                    self._accept(target)
                elif isinstance(target, _Refused):
                    self.selector.unregister(target.sock)
                    _drain(target.sock)
                    target.sock.close()
                elif isinstance(target, Connection) and target.sock.fileno() in self.connections:
                    if events & selectors.EVENT_READ:
                        self._readable(target)
                    if events & selectors.EVENT_WRITE and target.sock.fileno() in self.connections:
                        self._flush(target)
            if self.realtime:
                self._push_events(time.monotonic())

    def _accept(self, listener: socket.socket) -> None:
        try:
            sock, _ = listener.accept()
        except (BlockingIOError, InterruptedError):
            return
        if len(self.connections) >= self.max_clients:
            self.refused += 1
            message = f"{self.max_clients} clients already connected"
            log.warning("a client refused: %s", message)
            try:
                sock.sendall(p.pack(p.ERROR, 0, 0, p.RESULT.pack(-errno.EBUSY, 0, 0, 0)[:8]
                                    + message.encode()))
                sock.shutdown(socket.SHUT_WR)
            except OSError:
                sock.close()
                return
            # closed once it has spoken or gone: closing on its unread HELLO would reset
            # the connection before it reads why
            sock.setblocking(False)
            self.selector.register(sock, selectors.EVENT_READ, _Refused(sock))
            return
        sock.setblocking(False)
        number = len(self.sessions) + 1
        session = Session(number, self.make_board(number), realtime=self.realtime)
        self.sessions.append(session)
        connection = Connection(sock, session)
        self.connections[sock.fileno()] = connection
        self.selector.register(sock, selectors.EVENT_READ, connection)
        if self.on_session_start is not None:
            self.on_session_start(session)
        log.info("%s connected", connection.name)

    def _readable(self, connection: Connection) -> None:
        try:
            chunk = connection.sock.recv(RECV_SIZE)
        except (BlockingIOError, InterruptedError):
            return
        except OSError as exc:
            self._end(connection, f"socket error: {exc.strerror or exc}")
            return
        if not chunk:
            inbox = connection.inbox
            if inbox:
                have = len(inbox)
                want = (p.HEADER.size + p.HEADER.unpack_from(inbox)[0]
                        if have >= p.HEADER.size else p.HEADER.size)
                self._end(connection, f"disconnected inside a message ({have} of its "
                                      f"{want} bytes); the transfers before it stand")
            else:
                self._end(connection, None)
            return
        connection.inbox += chunk
        try:
            self._process(connection)
        except p.ProtocolError as exc:
            connection.session.stats.protocol_error = str(exc)
            connection.outbox += p.pack(p.ERROR, 0, connection.session.now_ns(),
                                        p.RESULT.pack(-errno.EPROTO, 0, 0, 0)[:8]
                                        + str(exc).encode())
            self._flush(connection, blocking=True)
            self._end(connection, str(exc))
            return
        self._flush(connection)
        if connection.session.closing and connection.sock.fileno() in self.connections:
            self._flush(connection, blocking=True)
            self._end(connection, None)

    def _process(self, connection: Connection) -> None:
        """Answer every complete message in the inbox, in order."""
        inbox = connection.inbox
        session = connection.session
        offset = 0
        size = p.HEADER.size
        while len(inbox) - offset >= size and not session.closing:
            header = p.unpack_header(memoryview(inbox)[offset:offset + size])
            end = offset + size + header.length
            if len(inbox) < end:
                break
            payload = bytes(inbox[offset + size:end])
            offset = end
            if not session.greeted:
                if header.type != p.HELLO:
                    raise p.ProtocolError(f"message type 0x{header.type:02x} before HELLO")
                reply = session.hello(payload)
            else:
                reply = session.serve(header.type, header.time_ns, payload)
            connection.outbox += p.pack(header.type | p.REPLY, header.seq, session.now_ns(),
                                        reply)
            connection.pushed_levels = session.last_levels
        del inbox[:offset]
        if self.realtime and session.greeted:
            self._schedule(connection)

    def _flush(self, connection: Connection, blocking: bool = False) -> None:
        sock = connection.sock
        if blocking:
            sock.settimeout(5.0)
        try:
            while connection.outbox:
                sent = sock.send(connection.outbox)
                del connection.outbox[:sent]
        except (BlockingIOError, InterruptedError):
            pass
        except OSError as exc:
            connection.outbox.clear()
            if not blocking:
                self._end(connection, f"socket error: {exc.strerror or exc}")
            return
        finally:
            if blocking:
                sock.setblocking(False)
        wanted = selectors.EVENT_READ | (selectors.EVENT_WRITE if connection.outbox else 0)
        if sock.fileno() in self.connections:
            self.selector.modify(sock, wanted, connection)

    def _end(self, connection: Connection, why: str | None) -> None:
        """Close one connection and end its session (its trace is closed whole)."""
        fileno = connection.sock.fileno()
        if self.connections.pop(fileno, None) is None:
            return
        self.selector.unregister(connection.sock)
        if why and connection.session.stats.protocol_error:
            _drain(connection.sock)  # (unread input would reset the ERROR away)
        connection.sock.close()
        if why:
            log.warning("%s: %s; connection closed", connection.name, why)
        else:
            log.info("%s disconnected", connection.name)
        if self.on_session_end is not None:
            self.on_session_end(connection.session)

    # ---------------------------------------------------------------- real time

    def _schedule(self, connection: Connection) -> None:
        due_ns = connection.session.next_change_ns()
        if due_ns is None:
            connection.wake_at = math.inf
            return
        wait_s = max(due_ns - connection.session.now_ns(), 0) / NS_PER_S
        connection.wake_at = time.monotonic() + wait_s

    def _push_events(self, now: float) -> None:
        for connection in list(self.connections.values()):
            session = connection.session
            if connection.wake_at > now or not session.greeted:
                continue
            levels = session.levels()
            if levels != connection.pushed_levels:
                connection.pushed_levels = levels
                connection.outbox += p.pack(p.EVENT, 0, session.now_ns(), p.result(
                    0, 0, levels, session.next_change_ns()))
                self._flush(connection)
            if connection.sock.fileno() in self.connections:
                self._schedule(connection)

    # ---------------------------------------------------------------- the end

    def close(self) -> None:
        """End every session (traces closed whole), stop listening, remove the sockets."""
        for connection in list(self.connections.values()):
            self._end(connection, None)
        for key in list(self.selector.get_map().values()):
            if isinstance(key.data, _Refused):
                self.selector.unregister(key.fileobj)
                key.data.sock.close()
        for sock, path in self.listeners:
            self.selector.unregister(sock)
            sock.close()
            if path is not None:
                try:
                    os.unlink(path)
                except FileNotFoundError:
                    pass
        self.listeners = []
        self.selector.unregister(self._wake_r)
        os.close(self._wake_r)
        os.close(self._wake_w)
        self.selector.close()

    def stats(self) -> dict[str, Any]:
        return {"sessions": [{"client": s.client_name, **s.stats.as_dict()}
                             for s in self.sessions], "refused": self.refused}
