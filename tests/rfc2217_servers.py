"""RFC 2217 servers for tests and benchmarks: a serial device (the emulator's pty) exported on loopback, as a
labgrid exporter exports a bench's port 0.

* :func:`ser2net` — the real thing (Debian's ser2net, what labgrid exporters run): a YAML config in a temp file,
  ports the OS chose, ``ser2net -n -d -c FILE``; optionally a second, raw TCP accepter on the same device (the
  baseline the benchmark compares against).
* :func:`port_manager` — pyserial's own RFC 2217 server (``serial.rfc2217.PortManager``, as pyserial's
  examples/rfc2217_server.py), for hosts without ser2net.
* :func:`rfc2217_server` — ser2net where it is installed, else the port manager.
"""

from __future__ import annotations

import contextlib
import os
import select
import shutil
import socket
import subprocess
import tempfile
import termios
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass

import serial
import serial.rfc2217

from hil.io.serial_line import is_pty
from tests import processes

SER2NET = shutil.which("ser2net") or shutil.which("ser2net", path="/usr/sbin:/usr/local/sbin:/sbin")
NO_SER2NET = "ser2net is not installed (Debian: apt-get install ser2net; .ci/run installs it)"


@dataclass(frozen=True)
class Exported:
    """Where a device is served: ``rfc2217`` is HOST:PORT of the RFC 2217 (telnet) accepter; ``raw`` of a plain
    TCP accepter (ser2net only, when asked for)."""

    kind: str  # "ser2net" or "pyserial"
    rfc2217: str
    raw: str | None = None
    process: subprocess.Popen | None = None


def free_port() -> int:
    """A loopback port the OS chose (closed again for the server to bind: a tiny window another process could
    take it in, which the server's start-up check reports)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_listening(port: int, proc: subprocess.Popen | None, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc is not None and proc.poll() is not None:
            raise RuntimeError(f"ser2net exited with {proc.returncode}: {proc.stderr.read() if proc.stderr else ''}")
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.02)
    raise RuntimeError(f"nothing listens on 127.0.0.1:{port} after {timeout} s")


@contextlib.contextmanager
def ser2net(device: str, line: str = "9600e71", *, raw_device: str | None = None,
            chardelay: bool = True) -> Iterator[Exported]:
    """ser2net exporting ``device`` (``line``: its initial settings, ser2net's spelling, e.g. 9600e71; the client
    sets its own over RFC 2217) on an RFC 2217 accepter, and ``raw_device`` on a raw TCP one.  (Not one device on
    both: ser2net opens the device per connection and keeps reading it for a moment after a client leaves, so a
    reply to the next client of the other accepter can go to the old connection.)

    ``chardelay``: ser2net's default, holding what the device sends until the line has been quiet for a couple of
    characters at its baud rate (≈ 3 ms a reply at 9600) so that it goes out in one segment — as a labgrid
    exporter does; off, each read from the device is forwarded at once."""
    if SER2NET is None:
        raise RuntimeError(NO_SER2NET)
    raw = raw_device is not None
    ports = {"rfc2217": free_port(), "raw": free_port() if raw else None}
    options = "" if chardelay else "  options:\n    chardelay: false\n"
    config = [f"connection: &rfc2217\n  accepter: telnet(rfc2217),tcp,127.0.0.1,{ports['rfc2217']}\n"
              f"  connector: serialdev,{device},{line},local\n{options}"]
    if raw:
        config.append(f"connection: &raw\n  accepter: tcp,127.0.0.1,{ports['raw']}\n"
                      f"  connector: serialdev,{raw_device},{line},local\n{options}")
    with tempfile.TemporaryDirectory(prefix="hil-ser2net-") as tmp:
        path = os.path.join(tmp, "ser2net.yaml")
        with open(path, "w") as f:
            f.write("".join(config))
        proc = processes.spawn([SER2NET, "-n", "-d", "-c", path, "-P", os.path.join(tmp, "ser2net.pid")],
                                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                text=True)
        try:
            for port in ports.values():
                if port:
                    _wait_listening(port, proc)
            yield Exported("ser2net", f"127.0.0.1:{ports['rfc2217']}",
                           f"127.0.0.1:{ports['raw']}" if raw else None, proc)
        finally:
            if proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()


class _PtyPort(serial.Serial):
    """The server's side of a pty, which is not a line: it has no line coding — Linux refuses (EINVAL) to set
    CS7/PARENB on one again once it has kept CS8, so a setting the kernel refuses is kept in this object and
    reported back to the client, as ser2net's is (its tcsetattr on a pty succeeds and the pty stays 8N1) — and no
    modem lines (ioctl TIOCMGET/TIOCMBIS: ENOTTY): they read as off, DTR/RTS changes are accepted and dropped."""

    def _reconfigure_port(self, force_update: bool = False) -> None:
        try:
            super()._reconfigure_port(force_update)
        except termios.error:
            if not is_pty(self.port):
                raise

    def _update_dtr_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    cts = dsr = ri = cd = property(lambda self: False)


@contextlib.contextmanager
def port_manager(device: str) -> Iterator[Exported]:
    """pyserial's RFC 2217 port manager exporting ``device`` on a loopback port the OS chose, one client at a time
    (threads: accept, then socket → port and port → socket)."""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            ready, _, _ = select.select([listener], [], [], 0.05)
            if not ready:
                continue
            conn, _ = listener.accept()
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            port = _PtyPort(device, timeout=0)
            try:
                _session(conn, port, stop)
            finally:
                port.close()
                conn.close()

    thread = threading.Thread(target=serve, name="rfc2217 port manager", daemon=True)
    thread.start()
    try:
        yield Exported("pyserial", f"127.0.0.1:{listener.getsockname()[1]}")
    finally:
        stop.set()
        thread.join(5)
        listener.close()


class _Connection:
    """What PortManager writes its telnet answers to (it wants ``.write``)."""

    def __init__(self, conn: socket.socket) -> None:
        self.write = conn.sendall


def _session(conn: socket.socket, port: serial.Serial, stop: threading.Event) -> None:
    manager = serial.rfc2217.PortManager(port, _Connection(conn))
    while not stop.is_set():
        ready, _, _ = select.select([conn, port.fileno()], [], [], 0.05)
        if port.fileno() in ready:
            data = port.read(4096)
            if data:
                conn.sendall(b"".join(manager.escape(data)))
        if conn in ready:
            try:
                data = conn.recv(4096)
            except OSError:
                return
            if not data:
                return  # the client went away: wait for the next one
            port.write(b"".join(manager.filter(data)))


@contextlib.contextmanager
def rfc2217_server(device: str, line: str = "9600e71", *, chardelay: bool = True) -> Iterator[Exported]:
    """ser2net where installed, else pyserial's port manager (which forwards each read at once)."""
    with (ser2net(device, line, chardelay=chardelay) if SER2NET else port_manager(device)) as exported:
        yield exported


#: RFC 2217 COM-PORT-OPTION commands (client → server; the server answers with the command + 100)
SET_BAUDRATE, SET_DATASIZE, SET_PARITY, SET_STOPSIZE, SET_CONTROL, PURGE_DATA = 1, 2, 3, 4, 5, 12
_IAC, _SB, _SE, _COM_PORT_OPTION = 255, 250, 240, 44


class TelnetTap:
    """A loopback TCP relay in front of an RFC 2217 server that records every COM-PORT-OPTION subnegotiation
    either way: ``records`` holds ("c"|"s", command, value bytes) — what the client asked and what the server
    answered — in the order seen.  Clients connect to :attr:`address`."""

    def __init__(self, upstream: str) -> None:
        self.upstream = upstream
        self.records: list[tuple[str, int, bytes]] = []
        self._listener = socket.socket()
        self._listener.bind(("127.0.0.1", 0))
        self._listener.listen(1)
        self.address = f"127.0.0.1:{self._listener.getsockname()[1]}"
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="rfc2217 tap", daemon=True)
        self._thread.start()

    def commands(self, side: str, after: int = 0) -> list[tuple[int, bytes]]:
        return [(cmd, value) for s, cmd, value in self.records[after:] if s == side]

    def _serve(self) -> None:
        while not self._stop.is_set():
            ready, _, _ = select.select([self._listener], [], [], 0.05)
            if not ready:
                continue
            client, _ = self._listener.accept()
            host, _, port = self.upstream.rpartition(":")
            try:
                server = socket.create_connection((host, int(port)))
            except OSError:
                client.close()
                continue
            parsers = {client: self._parser("c"), server: self._parser("s")}
            peer = {client: server, server: client}
            with client, server:
                while not self._stop.is_set():
                    ready, _, _ = select.select([client, server], [], [], 0.05)
                    done = False
                    for sock in ready:
                        try:
                            data = sock.recv(4096)
                        except OSError:
                            data = b""
                        if not data:
                            done = True
                            break
                        parsers[sock](data)
                        peer[sock].sendall(data)
                    if done:
                        break

    def _parser(self, side: str):
        state = {"iac": False, "sb": None}

        def feed(data: bytes) -> None:
            for byte in data:
                if state["iac"]:
                    state["iac"] = False
                    if byte == _SB:
                        state["sb"] = bytearray()
                    elif byte == _SE and state["sb"] is not None:
                        sb = bytes(state["sb"])
                        state["sb"] = None
                        if len(sb) >= 2 and sb[0] == _COM_PORT_OPTION:
                            self.records.append((side, sb[1], sb[2:]))
                    elif byte == _IAC and state["sb"] is not None:
                        state["sb"].append(_IAC)
                elif byte == _IAC:
                    state["iac"] = True
                elif state["sb"] is not None:
                    state["sb"].append(byte)
        return feed

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self._listener.close()
