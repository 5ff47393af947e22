"""FatekExchange: one FATEK request at a time over pyserial — a serial device, a pty, ``socket://host:port`` or an
RFC 2217 server's ``rfc2217://host:port`` (through :mod:`hil.io.line`, which hides how each kind waits and drains).

One exchange = flush stale input, send one request, collect bytes until a reply frame for our station and
command arrives (or the deadline passes).  Frames that do not match are discarded but remembered, so a timeout
can say "I did hear something, and it was wrong".  Reads are retried; writes never are: a write whose reply
was lost may or may not have happened, and repeating it could be wrong (e.g. a counter preset), so the caller
is told the outcome is unknown.  FATEK replies carry no transaction id, so a late or repeated reply to an earlier
request of the same command would be taken for the answer; what guards against it depends on the line (``fence``):

* ``"trouble"`` (a direct serial line, TCP to the PLC's own Ethernet module): a reply is never repeated, and one
  that comes late comes after a timeout — so after anything odd (a timeout, a retry, a stray frame, a reconnect)
  the next request is preceded by a resynchronising loop-back, and a read whose reply had anything after it is
  repeated.  A clean read costs one round trip.
* ``"reads"`` (a gateway, a protocol converter, a line the profile says repeats replies; every emulator wire with
  a wire-fault plan): every read is fenced as well (:meth:`FatekExchange.fence`), two round trips a read.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable
from typing import Any, TypedDict, TypeVar

import serial

from hil.core.errors import InvalidValue, PlcErrorReply, ProtocolError, ReplyTimeout, TransportError
from hil.families.fbs.protocol.fatek import (
    BROADCAST,
    Command,
    DetailedStatus,
    FrameAssembler,
    FrameError,
    Loopback,
    MixedRead,
    ReadBits,
    ReadEnableState,
    ReadRegisters,
    ShortStatus,
    check_reply,
    describe_frame,
    encode_request,
    show_frame,
)
from hil.families.fbs.transport.base import Transport
from hil.io.line import Line, open_line
from hil.io.request_policy import RequestPolicy, Resync
from hil.io.serial_line import char_bits, is_pty
from hil.io.shared_line import SharedLine
from hil.io.trace import CHAR_BITS, DESCRIBERS, PRINTABLE

#: Commands that only read: safe to repeat after a lost reply.
READ_COMMANDS: tuple[type[Command[Any]], ...] = (ShortStatus, DetailedStatus, ReadEnableState, ReadBits,
                                                 ReadRegisters, MixedRead, Loopback)

Observer = Callable[[str, bytes], None]
_R = TypeVar("_R")  # what a command's reply decodes to

DESCRIBERS["fatek"] = describe_frame  # wire traces of this transport decode FATEK frames
PRINTABLE.add("fatek")  # its frames are ASCII
CHAR_BITS["fatek"] = 10  # 7E1 with its start bit


class FatekOptions(TypedDict, total=False):
    """The settings of a FATEK client that a target's query may give (:class:`FatekExchange`'s keywords)."""

    station: int
    baudrate: int
    bytesize: int
    parity: str
    stopbits: int
    timeout: float
    retries: int
    backoff: float


class FatekExchange(Transport):
    """The FATEK protocol's exchange on one line: a request sent, its reply found among what arrives and trusted
    (or the request retried, the line resynchronised, the outcome of a write said to be unknown).  ``port_url``:
    ``/dev/ttyUSB0``, a pty path, ``socket://host:port`` or ``rfc2217://host:port``.  What is asked over it is
    :class:`~hil.families.fbs.transport.fatek.FatekTransport`'s."""

    trace_kind = "fatek"  # how wire traces decode its frames (hil.io.trace.DESCRIBERS)

    def __init__(self, port_url: str, *, station: int = 1, baudrate: int = 9600, bytesize: int = 7,
                 parity: str = "E", stopbits: int = 1, timeout: float = 1.0, retries: int = 2,
                 backoff: float = 0.05, description: str | None = None, fence: str = "trouble",
                 paced: bool | None = None, line_name: str | None = None) -> None:
        """``fence``: "trouble" (a direct line) or "reads" (a line that may repeat replies: every read fenced);
        ``paced``: the port has a line rate (None: a device or RFC 2217 port has, a pty or socket has not)."""
        if not 0 <= station <= 0xFE:
            raise InvalidValue(f"station {station} outside 1–254 (0 = broadcast)")
        if timeout <= 0:
            raise InvalidValue(f"timeout must be positive, not {timeout}")
        if retries < 0:
            raise InvalidValue(f"retries must be 0 or more, not {retries}")
        if fence not in ("trouble", "reads"):
            raise InvalidValue(f"fence must be 'trouble' or 'reads', not {fence!r}")
        super().__init__(description or f"FATEK station {station} on {port_url}")
        self.port_url = port_url
        #: what messages call the line: the user's target for a TCP line (not pyserial's socket:// form of it)
        self.line_name = line_name or port_url
        self.station = station
        self.timeout = float(timeout)
        self.retries = retries
        self.baudrate = baudrate
        self._coding = (bytesize, parity, stopbits)  # the character frame a reopened line is set to again
        self.observers: list[Observer] = []  # called as (direction "tx"/"rx", frame) for wire traces
        self.discarded: list[tuple[bytes, str]] = []  # bad frames of the last exchange, with the reason
        # Neither a socket nor a pty has a real line rate (unless the emulator paces it): no transmission time to
        # add to the deadline.
        self._virtual_line = not paced if paced is not None else (port_url.startswith("socket://")
                                                                  or is_pty(port_url))
        self._char_bits = char_bits(bytesize, parity, stopbits)
        self.fence_every_read = fence == "reads"
        self.backoff = float(backoff)
        self.policy = RequestPolicy(retries, float(backoff))  # one rule for every wire (hil.io.request_policy)
        self.dirty = False  # True: the line may hold a late reply; resynchronise before the next request
        self._broken = False  # True: the connection is gone; reopen before the next request
        self._nonce = 0
        self.resyncs = 0  # loop-back resynchronisations done
        self.fenced_out = 0  # of which found a stale frame before the read's reply: the read was repeated
        self.reconnects = 0
        # before a request, after a fault: reconnect a lost connection, resynchronise with a loop-back (_probe)
        self._resync = Resync(needed=lambda: self._broken or self.dirty, probe=self._probe, failed=self._not_sent)
        self._command: Command[Any] = Loopback("")  # the request in hand (what a resync failure names)
        if "://" not in port_url:  # a device or a pty: other processes (a run's lanes) may take turns on it
            self._lock = SharedLine(port_url, taken=self._line_taken, leaving=lambda: self.dirty)
        # opened in this client's turn: pyserial's open flushes the tty's input queue (tcflush), which on a shared
        # line is also the other lanes' — a reply on its way to the lane holding the line would be lost
        with self._lock:
            self._line: Line = self.new_line()

    def _line_taken(self, suspect: bool) -> None:
        """The shared line is ours: the lane before us may have left a late reply on its way (hil.io.shared_line)."""
        if suspect:
            self.dirty = True

    def new_line(self) -> Line:
        """The line this client talks over, opened (a serial port, a pty, TCP or RFC 2217 by its URL; a subclass
        brings another kind: :class:`~hil.families.fbs.transport.udp.FatekUdpTransport`)."""
        bytesize, parity, stopbits = self._coding
        return open_line(self.port_url, baudrate=self.baudrate, bytesize=bytesize, parity=parity, stopbits=stopbits,
                         timeout=self.timeout, write_timeout=self.timeout + 1.0, name=self.line_name)

    def _close(self) -> None:
        self._line.close()
        if isinstance(self._lock, SharedLine):
            self._lock.close()

    # -- the exchange -------------------------------------------------------------------------------------------
    def _exchange(self, command: Command[_R]) -> _R:
        """One command under the request policy (:mod:`hil.io.request_policy`): this wire supplies one try
        (:meth:`_once`, and for a read its fence), what counts as lost (a timeout, a broken connection, a reply
        that cannot be trusted) and the resynchronising loop-back (:meth:`_probe`)."""
        frame = encode_request(self.station, command)
        is_read = isinstance(command, READ_COMMANDS)
        if self.station == BROADCAST:
            if is_read:
                raise TransportError(f"{command.describe()} to station 00 (broadcast): a broadcast is never "
                                     f"answered, so nothing can be read")
            self._command = command
            self.policy.run("", lambda n, tries: self._send(frame), write=True, lost=_LOST, resync=self._resync)
            return command.decode("")  # never answered: what a reply without data decodes to (None)

        def attempt(n: int, tries: int) -> _R:
            result = self._once(command, frame, n, tries)
            if is_read and not self._trusted():  # something stale came with the reply: not this request's answer
                raise _Stale(f"{command.describe()} to {self._where()}: something else came before or right after "
                             f"the reply (a late or repeated reply to an earlier request, or no loop-back "
                             f"echo in time), so the value was not trusted (attempt {n} of {tries})")
            return result
        self._command = command
        return self.policy.run("", attempt, write=not is_read, lost=_LOST, timeouts=(ReplyTimeout,),
                               resync=self._resync, one_try=self.timeout)

    def budget(self, write: bool = False) -> float:
        """The longest one request (one protocol frame) can take, retries, backoff and resynchronising
        included — a call that runs longer is a harness bug."""
        wait = self.timeout + self._wire_time(len(encode_request(1, Loopback("X" * 12))))
        # a try: the request (and a read's fence), and the flush and send's own timeout
        return self.policy.budget(wait + self.timeout + (0 if write else wait), write, probe=wait)

    def _not_sent(self, last: str) -> str:
        """Why the request in hand was not sent: the line could not be resynchronised (:meth:`_probe`).

        FATEK replies carry no transaction id, so a reply that comes late (after we gave up on it) looks
        exactly like the answer to our next request of the same shape.  A slave answers in order, so after a
        timeout or a stray frame we send a loop-back with a fresh nonce and discard everything until its echo:
        from then on the next reply is the answer to the next request.
        """
        return (f"{self._command.describe()} not sent to {self._where()}: the request before it went unanswered "
                f"(or was answered garbled) and so did a loop-back — {_CHECK} ({last})")

    def _probe(self, attempt: int, attempts: int) -> None:
        """One resynchronising loop-back (the connection reopened first when it is gone)."""
        if self._broken:
            self.reopen()
        probe = self._loopback()
        try:
            self._once(probe, encode_request(self.station, probe), attempt, attempts)
        except _Lost:
            self.reopen()
            raise
        self.resyncs += 1

    def reopen(self) -> None:
        """Close and reopen the port (a new TCP connection, the serial device opened again)."""
        with self._lock:
            with contextlib.suppress(serial.SerialException, OSError):  # a line already gone is closed
                self._line.close()
            self._line = self.new_line()
            self._broken = False
            self.dirty = True  # a late reply may still come on a serial line
            self.reconnects += 1

    def _loopback(self) -> Loopback:
        """A loop-back with a fresh nonce (this process's and a counter's): only its own echo matches it."""
        self._nonce += 1
        return Loopback(f"HIL{os.getpid() % 0x10000:04X}{self._nonce:06X}")

    def _once(self, command: Command[_R], frame: bytes, attempt: int, attempts: int, *,
              flush: bool = True) -> _R:
        """One request and its reply; whatever else arrives first is kept in :attr:`discarded`.  ``flush``: drop
        what waits on the line first (a late reply must not answer this request) — the fence must not."""
        self.discarded = []
        if flush:
            try:
                self._line.discard()
            except (serial.SerialException, OSError, ValueError) as exc:
                self._broken = True
                raise _Lost(f"{self._where()}: cannot flush input: {exc}") from exc
        started = time.monotonic()
        # Suspect until our reply is in: an exchange cut short (a timeout, pytest-timeout's signal, Ctrl-C)
        # leaves its reply on the way, and the next request must resynchronise first.
        self.dirty = True
        self._send(frame)
        wait = self.timeout + self._wire_time(len(frame))
        deadline = started + wait
        assembler = FrameAssembler()
        while (remaining := deadline - time.monotonic()) > 0:
            replies = assembler.feed(self._receive(remaining))
            for n, reply in enumerate(replies):
                self._notify("rx", reply)
                try:
                    data = check_reply(reply, self.station, command.code)
                    result = command.decode(data)
                except PlcErrorReply as exc:
                    self.dirty = False  # an error reply is still our reply: the line is in step
                    self._settle(replies[n + 1:], assembler)
                    raise PlcErrorReply(exc.code, exc.meaning, f"{command.describe()} sent to station "
                                        f"{self.station:02X} on {self.line_name}") from None
                except (FrameError, ProtocolError) as exc:
                    self.discarded.append((reply, f"{type(exc).__name__}: {exc}"))
                    continue
                self.dirty = False
                self._settle(replies[n + 1:], assembler)
                return result
        self.dirty = True  # whatever we asked may still be answered, late
        raise ReplyTimeout(self._timeout_message(command, frame, wait, attempt, attempts, assembler))

    @property
    def requests_per_read(self) -> int:
        """Round trips a clean read takes: 2 where every read is fenced, else 1."""
        return 2 if self.fence_every_read else 1

    def _trusted(self) -> bool:
        """After a read's reply: may its value be returned?  On a line that may repeat replies, only after the
        fence; on a direct line, when nothing came with or after it (:meth:`_settle` left the line clean) — a
        late reply there follows a timeout, and the loop-back before the next request has dropped it."""
        return self.fence() if self.fence_every_read else not self.dirty

    def fence(self) -> bool:
        """After every read, before its value is returned: True when nothing stale came before its reply.

        FATEK replies carry no transaction id, so a reply repeated late (a delayed duplicate) is taken for the
        answer to the next request of the same shape.  The fence is a loop-back (command 4E) with a fresh nonce,
        sent *without* flushing the input first: replies come in order, so if the read took a stale frame, its
        own reply is still on the way and arrives before the echo.  Anything but our echo first → False (the
        read is repeated); the line is then in step again after the echo.  A second round trip rather than the
        loop-back sent in the same write as the request: a FATEK master waits for each reply (a 2-wire RS-485
        line is half-duplex, and ports 0/1/3/4 and the Ethernet modules' serial side take one request per
        scan), and on the emulator's wires it costs ≈ 10 % of the suites' wall time (docs/safety.md)."""
        with self._lock:
            if self._broken or self.dirty or self.station == BROADCAST:
                return False
            probe = self._loopback()
            try:
                self._once(probe, encode_request(self.station, probe), 1, 1, flush=False)
            except PlcErrorReply:  # an error reply of an earlier request came first: ours is still on the way
                self.dirty = True
                return False
            except (ReplyTimeout, _Lost):
                return False
            if self.discarded:  # a frame came before the echo: a late or repeated reply the read may have taken
                self.fenced_out += 1
                return False
            return True

    def _settle(self, after: list[bytes], assembler: FrameAssembler) -> None:
        """After the accepted reply: anything more on the line (a duplicate, a stray frame) makes it suspect."""
        if after or assembler.pending or self.discarded:
            self.dirty = True
            return
        try:
            if self._line.pending():
                self.dirty = True
        except (OSError, ValueError, serial.SerialException):
            pass  # the next request finds out

    def _send(self, frame: bytes) -> None:
        self._notify("tx", frame)
        try:
            self._line.write(frame)
        except serial.SerialTimeoutException as exc:
            self.dirty = True
            raise ReplyTimeout(f"could not send {show_frame(frame)} to {self._where()} within "
                               f"{self._line.write_timeout or 0:.2f} s (output blocked)") from exc
        except (serial.SerialException, OSError) as exc:
            self._broken = True
            raise _Lost(f"{self._where()}: sending {show_frame(frame)} failed: {exc}") from exc

    def _receive(self, remaining: float) -> bytes:
        """Whatever has arrived, waiting at most ``remaining`` seconds for the first byte."""
        try:
            return self._line.receive(remaining)
        except (serial.SerialException, OSError, ValueError) as exc:
            self._broken = True
            raise _Lost(f"{self._where()}: connection lost while waiting for a reply: {exc}") from exc

    def _wire_time(self, request_len: int) -> float:
        """Time a real serial line needs to carry the request and a longest reply (nothing over a socket)."""
        if self._virtual_line:
            return 0.0
        return (request_len + 508) * self._char_bits / self.baudrate

    def _timeout_message(self, command: Command[Any], frame: bytes, wait: float, attempt: int, attempts: int,
                         assembler: FrameAssembler) -> str:
        parts = [f"no reply from station {self.station:02X} on {self.line_name} to {command.describe()} "
                 f"within {wait:.2f} s (attempt {attempt} of {attempts}); sent {show_frame(frame)}"]
        if self.discarded:
            bad = "; ".join(f"{show_frame(f)} ({why})" for f, why in self.discarded[:3])
            more = f" and {len(self.discarded) - 3} more" if len(self.discarded) > 3 else ""
            parts.append(f"discarded {len(self.discarded)} bad frame(s): {bad}{more}")
        if assembler.dropped or assembler.pending:
            parts.append(f"ignored {assembler.dropped} stray byte(s), {assembler.pending} byte(s) of an "
                         f"unfinished frame")
        return "; ".join(parts) + f" — {_CHECK}"

    def _notify(self, direction: str, frame: bytes) -> None:
        for observer in self.observers:
            observer(direction, frame)

    def _where(self) -> str:
        return f"station {self.station:02X} on {self.line_name}"

#: what to check when a FATEK PLC does not answer
_CHECK = "check the station number, the wiring or address and serial settings, and that the PLC is powered"


class _Lost(TransportError):
    """The connection failed mid-exchange (reopened before the next request)."""


class _Stale(TransportError):
    """A read's reply could not be told from a late or repeated reply to an earlier request (repeated)."""


#: what the request policy counts as a request whose reply never came (or could not be trusted)
_LOST = (ReplyTimeout, _Lost, _Stale)


__all__ = ["READ_COMMANDS", "FatekExchange", "FatekOptions", "Observer"]
