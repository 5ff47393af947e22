"""Replay recorded FATEK frames: a PLC that answers exactly what a wire trace recorded.

A wire trace (``--hil-trace``, a ``traces/*.txt`` file; :func:`hil.io.trace.format_trace`) holds every frame
a test sent (``->``) and received (``<-``).  :class:`RecordedPlc` serves such a recording on loopback TCP: each
request must equal the next recorded one byte for byte, and gets the reply recorded after it (none where the PLC
did not answer, so the client times out as it did then).  The first request that differs is answered with
silence, closes the connection and is kept as a :class:`Mismatch` naming both frames; :meth:`RecordedPlc.verify`
raises :class:`ReplayMismatch` for it, or for recorded requests never sent.

Loop-backs (command 4E) are the transport's own, not the procedure's: the fence after a read (where reads are
fenced) and the resynchronisation after a fault (:mod:`hil.families.fbs.transport.fatek`) carry a nonce unique to
the run that sent them.  A recording keeps none of them, and the recorded PLC echoes each one it gets, as any
FATEK PLC does.

Uses: ``replay+fatek:///path/to/trace.txt`` is a target (:func:`hil.families.fbs.transport.open_transport`), so a
failing bench test's trace can be replayed through the device layer on a machine with no PLC;
``fixtures/frames/`` pins the exact frames of the device procedures (tests/test_replay.py), next to the manual's
test vectors.
"""

from __future__ import annotations

import re
import socket
import threading
from dataclasses import dataclass
from pathlib import Path

from hil.core.errors import HilError
from hil.families.fbs.protocol.fatek import ETX, STX, FrameError, Loopback, describe_frame, show_frame, split_frame


class ReplayError(HilError):
    """A recording that cannot be replayed (unreadable file, not a FATEK trace)."""


class ReplayMismatch(HilError):
    """The client did not send what the recording holds."""


@dataclass(frozen=True)
class Exchange:
    request: bytes
    reply: bytes | None  # None: the PLC did not answer (the client timed out)


@dataclass(frozen=True)
class Mismatch:
    index: int  # which recorded exchange (0-based)
    expected: bytes | None  # None: the recording had ended
    got: bytes

    def __str__(self) -> str:
        got = f"{show_frame(self.got)} ({describe_frame(self.got)})"
        if self.expected is None:
            return f"request {self.index + 1} {got} comes after the recording ended"
        return (f"request {self.index + 1} differs from the recording: sent {got}, recorded "
                f"{show_frame(self.expected)} ({describe_frame(self.expected)})")


_LINE = re.compile(r"^\S+ (->|<-) (.*?)  \| ")


def load_recording(path: str | Path) -> list[Exchange]:
    """The request/reply pairs of the FATEK wire trace in file ``path``."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise ReplayError(f"cannot read recording {path}: {exc.strerror or exc}") from None
    return parse_recording(text, str(path))


def parse_recording(text: str, where: str = "<recording>") -> list[Exchange]:
    """The request/reply pairs of a FATEK wire trace's text (``where`` names it in errors)."""
    kinds = re.findall(r"^# wire trace \(([^)]*)\)", text, re.MULTILINE)
    if kinds != ["fatek"]:
        found = f"a {', '.join(kinds)} trace" if kinds else "no '# wire trace (fatek)' line"
        raise ReplayError(f"{where} is not one FATEK wire trace ({found}); record one with --hil-trace all on a "
                          "fatek+… target, or take a traces/*.txt of a failed test")
    exchanges: list[Exchange] = []
    pending: bytes | None = None
    for number, line in enumerate(text.splitlines(), 1):
        match = _LINE.match(line)
        if match is None:
            continue  # comments, headers, calls
        arrow, rest = match.groups()
        frame = _frame_bytes(rest, where, number)
        if _is_loopback(frame):
            continue  # the transport's fence or resynchronisation, answered live (module docstring)
        if arrow == "->":
            if pending is not None:
                exchanges.append(Exchange(pending, None))
            pending = frame
        else:
            if pending is None:
                raise ReplayError(f"{where}:{number}: a reply with no request before it")
            exchanges.append(Exchange(pending, frame))
            pending = None
    if pending is not None:
        exchanges.append(Exchange(pending, None))
    if not exchanges:
        raise ReplayError(f"{where} holds no frames")
    return exchanges


def _is_loopback(frame: bytes) -> bool:
    try:
        return split_frame(frame).command == Loopback.code
    except FrameError:
        return False


def _frame_bytes(rest: str, where: str, number: int) -> bytes:
    """The frame of a trace line's body: ``HEX HEX … printable`` — n bytes take 3n − 1 characters of hex, then a
    space and n printable characters (which may themselves contain spaces), so the body is 4n long."""
    if len(rest) % 4:
        raise ReplayError(f"{where}:{number}: not a frame line (hex bytes, then their printable text)")
    n = len(rest) // 4
    try:
        return bytes.fromhex(rest[:3 * n - 1])
    except ValueError:
        raise ReplayError(f"{where}:{number}: unreadable hex {rest[:3 * n - 1]!r}") from None


class RecordedPlc:
    """Serves a recording on ``127.0.0.1``; ``address`` is ``host:port``.  One client at a time; a client that
    connects again continues where the recording stands (as a reopened transport would)."""

    def __init__(self, recording: list[Exchange], host: str = "127.0.0.1", port: int = 0) -> None:
        self.recording = list(recording)
        self.position = 0
        self.mismatch: Mismatch | None = None
        self._lock = threading.Lock()
        self._listener = socket.create_server((host, port))
        self._listener.settimeout(0.2)
        bound = self._listener.getsockname()  # (host, port), and more for IPv6
        self.address = f"{bound[0]}:{bound[1]}"
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="hil-recorded-plc", daemon=True)
        self._thread.start()

    # -- the PLC ------------------------------------------------------------------------------------------------
    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            with conn:
                self._talk(conn)

    def _talk(self, conn: socket.socket) -> None:
        conn.settimeout(0.2)
        buffer = b""
        while not self._stop.is_set():
            try:
                data = conn.recv(4096)
            except TimeoutError:
                continue
            except OSError:
                return
            if not data:
                return
            buffer += data
            while (end := buffer.find(bytes([ETX]))) >= 0:
                start = buffer.find(bytes([STX]))
                frame, buffer = buffer[max(start, 0):end + 1], buffer[end + 1:]
                if not self._answer(conn, frame):
                    return  # a mismatch: hang up, as the client must not carry on against a wrong recording

    def _answer(self, conn: socket.socket, frame: bytes) -> bool:
        if _is_loopback(frame):  # echoed, as the PLC does; not part of the recording (module docstring)
            conn.sendall(frame)
            return True
        with self._lock:
            if self.mismatch is not None:
                return False
            index = self.position
            expected = self.recording[index] if index < len(self.recording) else None
            if expected is None or expected.request != frame:
                self.mismatch = Mismatch(index, expected.request if expected else None, frame)
                return False
            self.position += 1
        if expected.reply is not None:
            conn.sendall(expected.reply)
        return True

    # -- the verdict ----------------------------------------------------------------------------------------------
    def verify(self) -> None:
        """Raise :class:`ReplayMismatch` if a request differed from the recording or recorded ones were not sent."""
        with self._lock:
            if self.mismatch is not None:
                raise ReplayMismatch(str(self.mismatch))
            left = len(self.recording) - self.position
        if left:
            first = self.recording[self.position].request
            raise ReplayMismatch(f"{left} recorded request(s) never sent, the first {show_frame(first)} "
                                 f"({describe_frame(first)}), after {self.position} that matched")

    def close(self) -> None:
        self._stop.set()
        self._listener.close()
        self._thread.join(timeout=2)


__all__ = ["Exchange", "Mismatch", "RecordedPlc", "ReplayError", "ReplayMismatch", "load_recording",
           "parse_recording"]
