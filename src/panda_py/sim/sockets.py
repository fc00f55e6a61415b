"""The simulator's sockets: accepting clients (one robot and one end-effector client,
the hand's or the pump's, at a time; a second one hears "robot busy"), non-blocking TCP
with bounded output queues and a per-tick request budget, and closing idle or
misbehaving connections. Nothing here ever waits."""

from __future__ import annotations

import logging
import select
import selectors
import socket
import time

from panda_py import fci
from panda_py.fci import (
    ConnectStatus,
    ProtocolError,
)
from panda_py.fci import vacuum as vp
from panda_py.sim.config import DATAGRAMS_PER_PASS
from panda_py.sim.connections import Client, GripperConnection, RobotConnection, VacuumConnection
from panda_py.sim.desk.link import accept_fci_connect
from panda_py.sim.parts import ServerState

log = logging.getLogger("panda_py.sim")


# A client may leave this much of its answers unread [bytes] (the largest answer, a model
# library, is about 21 kB); past it, it is disconnected: the loop never waits on a socket.
OUTPUT_LIMIT = 1 << 20
# Bytes read from one TCP socket per loop pass (a few of the longest requests).
READ_CHUNK = 4096
# Time the loop may spend on TCP requests per 1 ms tick [s]: a flood gets this share and
# no more, so the loop keeps time and, running SCHED_FIFO, never runs into the kernel's
# realtime throttling (which would stop it for up to 100 ms).
REQUEST_BUDGET = 0.00025
# Second clients waiting for their "robot busy" answer; beyond this, closed at once.
MAX_REFUSING = 8
# poll() events of a peer that closed or reset its end, even with data unread (0: the
# platform cannot tell, before that data is read)
_PEER_GONE = (
    select.POLLRDHUP | select.POLLHUP | select.POLLERR
    if hasattr(select, "POLLRDHUP") and hasattr(select, "poll")
    else 0
)


class Sockets(ServerState):
    """Listening, accepting, reading, queueing answers and closing."""

    def _listen(self, port: int) -> socket.socket:
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind((self.config.host, port))
        s.listen(4)
        s.setblocking(False)
        return s

    def _accept(self, robot: bool) -> None:
        """Accept an FCI (``robot``) or end-effector client; one of each at a time."""
        listener = self._robot_listener if robot else self._gripper_listener
        tool: type[GripperConnection] = GripperConnection if self.pump is None else VacuumConnection
        what = "FCI" if robot else ("gripper" if self.pump is None else "vacuum gripper")
        try:
            sock, addr = listener.accept()
        except OSError:
            return
        if robot and not accept_fci_connect(self.desk):
            log.warning("refusing the FCI client from %s:%d: the FCI is not active", *addr)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\1\0\0\0\0\0\0\0")
            sock.close()  # a reset, as from a robot whose FCI port is closed
            return
        current = self.robot_conn if robot else self.gripper_conn
        if current is not None and not self._alive(current):
            self._close_conn(current)
            current = None
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        conn: RobotConnection | GripperConnection
        if current is not None:
            log.warning(
                "robot busy: refusing a second %s client from %s:%d while %s:%d is connected",
                what, *addr, *current.addr,
            )  # fmt: skip
            if len(self._refusing) >= MAX_REFUSING:
                sock.close()
                return
            conn = RobotConnection(sock, addr) if robot else tool(sock, addr)
            self._refusing.append(conn)
            self._sel.register(sock, selectors.EVENT_READ, ("busy", conn))
            return
        if robot:
            conn = self.robot_conn = RobotConnection(sock, addr)
        else:
            conn = self.gripper_conn = tool(sock, addr)
        self._sel.register(sock, selectors.EVENT_READ, ("tcp", conn))
        log.info("%s client connected from %s:%d", what, *addr)

    def _read_refusing(self, conn: Client) -> None:
        """A second client: answer its Connect with "robot busy", then close."""
        data = self._recv(conn)
        if not data:
            return
        try:
            messages = conn.reader.feed(data)
        except ProtocolError:
            self._close_conn(conn)
            return
        if not messages:
            return
        cid = messages[0].command_id
        if isinstance(conn, RobotConnection):
            version = self.config.accepted_versions[-1]
            answer = fci.encode_connect_response(cid, ConnectStatus.ROBOT_BUSY, version)
        else:
            version = (
                vp.VACUUM_VERSION if isinstance(conn, VacuumConnection) else fci.GRIPPER_VERSION
            )
            answer = fci.encode_gripper_connect_response(
                cid, fci.GripperConnectStatus.ROBOT_BUSY, version=version
            )
        try:
            conn.sock.send(answer)  # 14-15 bytes into an empty socket buffer
        except OSError:
            pass
        self._close_conn(conn)

    def _drop(self, conn: Client, reason: str) -> None:
        """Disconnect a misbehaving client with one log line."""
        log.warning("disconnecting client %s:%d: %s", *conn.addr, reason)
        self.stats.clients_dropped += 1
        self._close_conn(conn)

    def _close_conn(self, conn: Client) -> None:
        if conn.closed:
            return
        conn.closed = True
        conn.out.clear()
        conn.backlog.clear()
        if conn in self._refusing:
            self._refusing.remove(conn)
        for s in (conn.sock, conn.udp):
            if s is None:
                continue
            try:
                self._sel.unregister(s)
            except (KeyError, ValueError):
                pass
            s.close()
        conn.udp = None
        if conn is self.robot_conn:
            self.robot_conn = None
            self.drop_commands = 0  # injected losses belong to the session that saw them
            self.core.client_lost()
            log.info("FCI client %s:%d disconnected", *conn.addr)
        elif conn is self.gripper_conn:
            self.gripper_conn = None
            for tool in (self.gripper, self.pump):
                if tool is not None:
                    tool.client_lost()
            log.info("end-effector client %s:%d disconnected", *conn.addr)

    @staticmethod
    def _alive(conn: RobotConnection | GripperConnection) -> bool:
        """Whether a connection is still open: its peer may have closed it unseen yet,
        also behind requests not read yet (a client that sent one and left: Linux's
        ``POLLRDHUP``; elsewhere such a client counts as connected until they are read)."""
        if _PEER_GONE:
            poller = select.poll()
            poller.register(conn.sock, _PEER_GONE)
            try:
                if poller.poll(0):
                    return False
            except OSError:
                return False
        try:
            return conn.sock.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) != b""
        except (BlockingIOError, InterruptedError):
            return True
        except OSError:
            return False

    def _recv(self, conn: Client) -> bytes | None:
        try:
            data = conn.sock.recv(READ_CHUNK)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError as exc:
            log.info("connection from %s:%d failed: %s", *conn.addr, exc)
            self._close_conn(conn)
            return None
        if not data:
            self._close_conn(conn)
            return None
        return data

    def _send_tcp(self, conn: Client, data: bytes) -> None:
        """Queue ``data`` for ``conn`` and send what the socket takes now (never waits);
        a client that lets more than :data:`OUTPUT_LIMIT` pile up is disconnected."""
        if conn.closed:
            return
        if not conn.out:
            try:
                sent = conn.sock.send(data)
            except (BlockingIOError, InterruptedError):
                sent = 0
            except OSError as exc:
                log.info("sending to %s:%d failed: %s", *conn.addr, exc)
                self._close_conn(conn)
                return
            if sent == len(data):
                return
            data = data[sent:]
        conn.out += data
        if len(conn.out) > OUTPUT_LIMIT:
            self._drop(conn, f"it leaves its answers unread ({len(conn.out)} bytes queued)")
            return
        self._watch(conn)

    def _watch(self, conn: Client) -> None:
        """Watch ``conn`` for what it needs: writability while answers are queued,
        readability unless requests wait in its backlog or the tick's budget is spent
        (so a flooding client neither gets read nor makes the loop spin)."""
        if conn.closed:
            return
        events = 0
        if conn.out:
            events |= selectors.EVENT_WRITE
        if not conn.backlog and self._budget > 0.0:
            events |= selectors.EVENT_READ
        if events == conn.events:
            return
        if conn.events == 0:
            self._sel.register(conn.sock, events, ("tcp", conn))
        elif events == 0:
            self._sel.unregister(conn.sock)
        else:
            self._sel.modify(conn.sock, events, ("tcp", conn))
        conn.events = events

    def _flush(self, conn: Client) -> None:
        """Send queued answers as far as the socket takes them."""
        if conn.closed or not conn.out:
            return
        try:
            sent = conn.sock.send(conn.out)
        except (BlockingIOError, InterruptedError):
            return
        except OSError as exc:
            log.info("sending to %s:%d failed: %s", *conn.addr, exc)
            self._close_conn(conn)
            return
        del conn.out[:sent]
        if not conn.out:
            self._watch(conn)

    def _read_tcp(self, conn: Client) -> None:
        """Cut what arrived into messages and handle them as time allows; a stream that
        cannot be cut (a size beyond the protocol's longest request) is closed. While
        requests wait in the backlog the socket is not read."""
        if conn.backlog:
            return
        data = self._recv(conn)
        if not data:
            return
        try:
            conn.backlog.extend(conn.reader.feed(data))
        except ProtocolError as exc:
            self._drop(conn, str(exc))
            return
        self._handle_backlog(conn)

    def _handle_backlog(self, conn: Client) -> None:
        """Handle queued requests while the tick's request budget lasts."""
        start = time.monotonic()
        while conn.backlog and not conn.closed and self._budget > 0.0:
            msg = conn.backlog.popleft()
            if conn is self.robot_conn and isinstance(conn, RobotConnection):
                self._handle_robot_message(conn, msg)
            elif conn is self.gripper_conn and isinstance(conn, VacuumConnection):
                self._handle_vacuum_message(conn, msg)
            elif conn is self.gripper_conn and isinstance(conn, GripperConnection):
                self._handle_gripper_message(conn, msg)
            else:
                return  # closed while handling an earlier message
            now = time.monotonic()
            self._budget -= now - start
            start = now
        self._watch(conn)

    def _refill_budget(self) -> None:
        """A new tick's time for requests; sockets left unwatched for lack of it are
        watched again."""
        spent = self._budget <= 0.0
        self._budget = REQUEST_BUDGET
        if spent:
            for client in (self.robot_conn, self.gripper_conn):
                if client is not None:
                    self._watch(client)

    def _backlogged(self) -> list[Client]:
        return [c for c in (self.robot_conn, self.gripper_conn) if c is not None and c.backlog]

    def _expire_idle(self, now: float) -> None:
        """Close connections that never sent Connect within ``connect_timeout`` (they
        would hold the robot) and second clients that never asked."""
        limit = now - self.config.connect_timeout
        robot, gripper = self.robot_conn, self.gripper_conn
        if robot is not None and robot.dialect is None and robot.opened < limit:
            self._drop(robot, "no Connect request within the connect timeout")
        if gripper is not None and not gripper.connected and gripper.opened < limit:
            self._drop(gripper, "no Connect request within the connect timeout")
        for conn in [c for c in self._refusing if c.opened < limit]:
            self._close_conn(conn)

    @staticmethod
    def _drain(sock: socket.socket | None) -> None:
        if sock is None:
            return
        for _ in range(DATAGRAMS_PER_PASS):
            try:
                sock.recv(2048)
            except OSError:
                return


__all__ = ["Sockets"]
