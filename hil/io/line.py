"""A serial line as the protocol clients use it, whichever way the bytes travel.

Two kinds, chosen by the port's URL (:func:`open_line`):

* :class:`LocalLine` — a device (``/dev/ttyUSB0``), a pty, or ``socket://HOST:PORT``: the port has a file
  descriptor, so waiting is ``select()`` on it and dropping stale input is ``reset_input_buffer()`` (a local
  ``tcflush`` / socket drain).
* :class:`Rfc2217Line` — ``rfc2217://HOST:PORT``, a serial port exported by an RFC 2217 server (ser2net, as labgrid
  exporters run it, or pyserial's port manager).  pyserial's client has no file descriptor (its reader thread
  fills a queue), every ``reset_input_buffer()`` is a purge the server must acknowledge (≥ 50 ms: pyserial polls
  for the answer every 50 ms), every change of ``.timeout`` renegotiates all line settings (≈ 160 ms; not in the
  labgrid fork), and ``write_timeout`` raises NotImplementedError.  So the read timeout is set once, at open, to a
  short slice; waiting is a read of one byte within that slice, "anything pending?" is ``in_waiting`` (the local
  queue) and stale input is drained from that queue, never purged on the server.

The protocol logic (FATEK framing, resynchronisation, pymodbus's RTU client) is written once against :class:`Line`.
Only what stock pyserial 3.5 and labgrid's fork ``pyserial-labgrid`` (which installs into the same ``serial``
package) both have is used: ``serial.rfc2217.Serial``, ``in_waiting``, ``read``, ``write``, the ``ign_set_control``
and ``timeout`` URL options, and — to close without pyserial's 0.3 s sleep and to tell a server that hung up at
once from one that is no RFC 2217 server — the client's ``_socket``, ``_thread`` and ``_read_buffer``, which the
fork leaves as they are (its changes: a ``.timeout`` change is no renegotiation, an unchanged subnegotiation is
not sent again).
"""

from __future__ import annotations

import contextlib
import errno
import re
import select
import socket
import termios
import threading
import time
import warnings
from abc import ABC, abstractmethod
from urllib.parse import parse_qsl, urlencode, urlsplit

import serial
import serial.rfc2217

from hil.core.errors import TransportError
from hil.io.hosts import unresolved
from hil.io.serial_line import line_coding

#: How long one wait of an RFC 2217 line may block for its first byte: a reply wakes it at once (a queue's
#: condition), so this only bounds how far a wait may overrun its deadline.
RFC2217_SLICE = 0.02

_OPEN_HINTS = {
    errno.ENOENT: "no such device — is the adapter plugged in? `python -m serial.tools.list_ports` lists ports",
    errno.EACCES: "permission denied — add your user to the dialout group (sudo usermod -aG dialout $USER, "
                  "then log in again)",
    errno.EPERM: "permission denied — add your user to the dialout group",
    errno.EBUSY: "device busy — another program (a terminal, ModemManager, another test run) holds the port",
    errno.ENXIO: "no device behind this path (a pty whose server is gone, or an unplugged adapter)",
}


class Line(ABC):
    """One open serial port.  Methods raise pyserial's/the OS's own errors: the protocol client decides what a
    failure means for the request in flight."""

    def __init__(self, port: serial.SerialBase, write_timeout: float | None) -> None:
        self.port = port  # the pyserial object (pymodbus's client keeps it as its .socket)
        self.write_timeout = write_timeout  # None: this kind of port cannot time out a write

    def write(self, data: bytes) -> None:
        self.port.write(data)

    @abstractmethod
    def receive(self, wait: float) -> bytes:
        """Whatever has arrived, waiting at most about ``wait`` seconds for the first byte (b"" if nothing did)."""

    @abstractmethod
    def pending(self) -> bool:
        """True when bytes have arrived that nobody has read yet (never waits)."""

    @abstractmethod
    def discard(self) -> None:
        """Drop whatever has arrived (a late reply to an abandoned request) before the next request."""

    def close(self) -> None:
        """Close without the 0.3 s sleep "for quick reconnects" of pyserial's socket:// and rfc2217:// close(): a
        request/response client has nothing in flight at close (and the server sees the connection end as soon as
        the socket shuts down); the RFC 2217 reader thread is joined, as close() does."""
        port = self.port
        sock, thread = getattr(port, "_socket", None), getattr(port, "_thread", None)
        if sock is None:
            port.close()
            return
        port.is_open = False
        with contextlib.suppress(OSError):
            sock.shutdown(socket.SHUT_RDWR)
        sock.close()
        if thread is not None:
            thread.join(2)
            port._thread = None  # noqa: SLF001
        port._socket = None  # noqa: SLF001


class LocalLine(Line):
    """A device, a pty or ``socket://``: a file descriptor to select() on; timeout 0 (reads return what is there)."""

    def receive(self, wait: float) -> bytes:
        ready, _, _ = select.select([self.port.fileno()], [], [], max(wait, 0.0))
        return self.port.read(4096) if ready else b""

    def pending(self) -> bool:
        ready, _, _ = select.select([self.port.fileno()], [], [], 0)
        return bool(ready)

    def discard(self) -> None:
        self.port.reset_input_buffer()


class Rfc2217Line(Line):
    """``rfc2217://HOST:PORT``: line settings sent once over the protocol, the read timeout set once
    (:data:`RFC2217_SLICE`), input drained from pyserial's local queue."""

    def receive(self, wait: float) -> bytes:
        """As :meth:`Line.receive`, but an empty wait lasts the slice whatever ``wait`` is (the timeout is fixed):
        the caller's loop overruns its deadline by at most :data:`RFC2217_SLICE`."""
        port = self.port
        if not port.in_waiting:
            first = port.read(1)  # blocks up to the slice; raises once the reader thread has died
            if not first:
                return b""
            return first + self._take()
        return self._take()

    def _take(self) -> bytes:
        # read(n) of what the queue already holds returns at once (even with the timeout the slice): no wait
        waiting = self.port.in_waiting
        return self.port.read(waiting) if waiting else b""

    def pending(self) -> bool:
        return self.port.in_waiting > 0

    def discard(self) -> None:
        while self.port.in_waiting:
            self.port.read(self.port.in_waiting)


def is_rfc2217(url: str) -> bool:
    return url.startswith("rfc2217://")


def open_line(url: str, *, baudrate: int, bytesize: int, parity: str, stopbits: int, timeout: float,
              write_timeout: float | None = None, exclusive: bool | None = None, name: str | None = None) -> Line:
    """Open the port ``url`` names with these line settings (8N1 on a pty: :func:`~hil.io.serial_line.line_coding`).
    ``name``: what errors call it — the user's own target (``fatek+tcp://HOST:500``) rather than pyserial's
    ``socket://`` form of it.

    ``timeout`` bounds how long an RFC 2217 server may take to acknowledge the settings at open; ``write_timeout``
    is for local ports only (an RFC 2217 port has none).  Raises :class:`TransportError` naming the cause."""
    bytesize, parity, stopbits = line_coding(url, bytesize, parity, stopbits)
    settings = {"baudrate": baudrate, "bytesize": bytesize, "parity": parity, "stopbits": stopbits}
    try:
        if is_rfc2217(url):
            return Rfc2217Line(_open_rfc2217(url, timeout, settings), None)
        extra = {} if exclusive is None else {"exclusive": exclusive}
        # timeout=0: reads return what has arrived; the client waits with select() up to its own deadline.
        return LocalLine(serial.serial_for_url(url, timeout=0, write_timeout=write_timeout, **settings,
                                                    **extra), write_timeout)
    except (serial.SerialException, OSError, ValueError, termios.error) as exc:
        shown = name or url
        nameless = unresolved(urlsplit(url).hostname) if url.startswith(("socket://", "rfc2217://")) else None
        if nameless is not None:
            raise TransportError(f"cannot open {shown}: {nameless}") from exc
        hint = open_hint(url, exc)
        known = hint in _OPEN_HINTS.values()  # a known cause is the whole message (pyserial repeats the path)
        detail = re.sub(r"^Could not open port \S+: ", "", str(exc))  # the URL again, with hil's own options
        raise TransportError(f"cannot open {shown}: " + (hint if known else f"{detail} — {hint}")) from exc


def _open_rfc2217(url: str, timeout: float, settings: dict) -> serial.SerialBase:
    """pyserial's RFC 2217 client on ``url``.  A server that accepts and closes at once (the port is in use — ser2net
    serves one connection per port and says "Port already in use" — or it is still releasing its device from the
    previous client, as it opens the device per connection) is tried again for up to ``timeout``."""
    _quiet_reader_deaths()
    deadline = time.monotonic() + max(timeout, 1.0)
    while True:
        port = _Client(None, timeout=RFC2217_SLICE, **settings)
        port.port = _rfc2217_options(url, timeout)
        try:
            with warnings.catch_warnings():  # pyserial 3.5 names its reader thread with setDaemon()/setName()
                warnings.filterwarnings("ignore", r"set(Daemon|Name)\(\) is deprecated", DeprecationWarning)
                port.open()
            return port
        except (serial.SerialException, OSError) as exc:
            if not port.ended and getattr(exc, "errno", None) not in (errno.EPIPE, errno.ECONNRESET):
                raise
            if time.monotonic() >= deadline:
                said = port.said
                raise ClosedAtOnce("the server closed the connection at once" +
                                   (f" saying {said!r}" if said else "")) from exc
        time.sleep(0.05)


class ClosedAtOnce(serial.SerialException):
    """An RFC 2217 server accepted the connection and closed it before the options were negotiated."""


class _Client(serial.rfc2217.Serial):
    """pyserial's RFC 2217 client, noting at close whether the connection had already ended (``ended``: the reader
    thread is gone — the server hung up, or pyserial's reader died of a write to it while answering an option) and
    what the server had said (``said``: the text left in the queue, e.g. ser2net's "Port already in use").  Only
    the class's own attributes, the same in pyserial and its labgrid fork."""

    ended = False
    said = ""

    def close(self) -> None:
        thread, queue = getattr(self, "_thread", None), getattr(self, "_read_buffer", None)
        self.ended = thread is not None and not thread.is_alive()
        items = list(getattr(queue, "queue", ()))
        self.said = b"".join(item for item in items if item).decode("ascii", "replace").strip()
        super().close()


_READER = "pySerial RFC 2217 reader thread"  # the name pyserial (and its labgrid fork) gives the client's thread


def _quiet_reader_deaths() -> None:
    """pyserial's RFC 2217 reader thread dies with a traceback on stderr when the server drops the connection while
    it answers a telnet option (a busy port: one per attempt).  The client sees the connection gone and hil says
    why, so that death says nothing more: it is not printed.  Every other thread exception goes to the previous
    hook.  Installed once, at the first RFC 2217 open."""
    previous = threading.excepthook
    if getattr(previous, "hil_quiet_rfc2217", False):
        return

    def hook(args: threading.ExceptHookArgs) -> None:
        if (args.thread is not None and args.thread.name.startswith(_READER)
                and issubclass(args.exc_type, (BrokenPipeError, ConnectionResetError))):
            return
        previous(args)

    hook.hil_quiet_rfc2217 = True  # type: ignore[attr-defined]
    threading.excepthook = hook


def _rfc2217_options(url: str, timeout: float) -> str:
    """The URL pyserial's RFC 2217 client opens: ``ign_set_control`` (no ser2net answer to SET_CONTROL satisfies
    pyserial's check: without it the open fails after the network timeout, "timeout while waiting for option
    'control'"; with it pyserial waits 0.1 s instead) and the network ``timeout`` (how long to wait for each
    acknowledgement at open: the transport's own, not pyserial's 3 s)."""
    parts = urlsplit(url)
    options = dict(parse_qsl(parts.query, keep_blank_values=True))
    options.setdefault("ign_set_control", "")
    options.setdefault("timeout", f"{max(timeout, 0.5):g}")
    return f"rfc2217://{parts.netloc}?{urlencode(options)}"  # pyserial keeps blank values: ign_set_control=


def line_check(url: str) -> str:
    """What to check first when the line ``url`` names fails (the start of a hint a client completes)."""
    if is_rfc2217(url):
        return (f"is the RFC 2217 server (ser2net, a labgrid exporter) running at {url[len('rfc2217://'):]}, and "
                f"does it export the PLC's port?")
    return f"does {url} exist, and is no other program holding it open?"


def open_hint(url: str, exc: BaseException) -> str:
    """What to check when ``url`` could not be opened."""
    code = getattr(exc, "errno", None)
    if code in _OPEN_HINTS:
        return _OPEN_HINTS[code]
    text = str(exc).lower()
    if "permission denied" in text:
        return _OPEN_HINTS[errno.EACCES]
    if "no such file" in text:
        return _OPEN_HINTS[errno.ENOENT]
    if is_rfc2217(url):
        if isinstance(exc, ClosedAtOnce):
            return ("another client holds the port (ser2net serves one connection per port: a labgrid console, "
                    "another run?) or the server cannot open its device")
        if "does not seem to support rfc2217" in text or "does not accept parameter" in text:
            return ("something answered at that port but not as an RFC 2217 server — is it ser2net's "
                    "telnet(rfc2217) accepter (a raw tcp accepter is reached with a …+tcp:// target or socket://)?")
        return ("nothing accepted the connection — is the RFC 2217 server (ser2net, a labgrid exporter) running, "
                "and is this its port?")
    if url.startswith("socket://"):
        return ("nothing accepted the connection — check host and port (the scheme's default port unless the URL "
                "names one) and that the PLC's Ethernet module has a client connection free")
    return "check the port name and its settings"


__all__ = ["Line", "LocalLine", "Rfc2217Line", "RFC2217_SLICE", "is_rfc2217", "line_check", "open_line", "open_hint"]
