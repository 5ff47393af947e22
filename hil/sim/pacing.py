"""A serial line's real rate on the emulator's ptys: every character takes its bits' time, both directions.

A pty moves bytes as fast as the host copies them, so without pacing a suite meets on CI a line hundreds of times
faster than port 0 at 9600 bit/s.  :class:`LineRate` is the line's setting (``"9600 7E1"``: 1 start bit, 7 data
bits, even parity, 1 stop bit = 10 bits a character, 1.04 ms); :class:`PacedSender` hands bytes on no faster than
that, in slices of at most :data:`SLICE` seconds, each when its last character would have arrived.  The pace is
kept on the ideal clock (each slice's time is the previous one's plus its characters), so an event loop woken late
on a loaded host delays a slice but not the line's average rate.

Pacing is wall-clock time.  With ``hil emulate`` in real time the PLC's clock is the wall clock (× the time scale),
so a character costs the PLC what it costs on a bench; an in-process emulator on virtual time does not see the
line's time at all (its clock moves one scan per request and by the bench's waits): there the pace only shows the
client the line's timing (its deadlines, partial frames), at the cost of wall time.
"""

from __future__ import annotations

import asyncio
import collections
import re
from collections.abc import Callable
from dataclasses import dataclass

from hil.core.errors import InvalidValue
from hil.io.serial_line import char_bits

#: longest run of characters handed on at once: a reader sees a frame arrive in pieces, as from a UART
SLICE = 0.002
#: characters waiting to go out before more are dropped (a UART's buffer overflows; a flood must not grow memory)
MAX_QUEUED = 64 * 1024

_FRAME = re.compile(r"^\s*(\d+)\s*[ ,/]?\s*([5-8])([NEO])([12])\s*$", re.IGNORECASE)


@dataclass(frozen=True)
class LineRate:
    """A serial line's setting: baud rate and character frame."""

    baudrate: int
    bytesize: int = 8
    parity: str = "N"
    stopbits: int = 1

    def __post_init__(self) -> None:
        if not 50 <= self.baudrate <= 4_000_000:
            raise InvalidValue(f"baud rate {self.baudrate} outside 50–4000000")
        if self.bytesize not in (5, 6, 7, 8) or self.parity not in ("N", "E", "O") or self.stopbits not in (1, 2):
            raise InvalidValue(f"character frame {self.bytesize}{self.parity}{self.stopbits}: data bits 5–8, "
                               f"parity N/E/O, stop bits 1 or 2")

    @classmethod
    def parse(cls, text: str) -> LineRate:
        """``"9600 7E1"`` (also ``9600,7E1``, ``9600/8E1``)."""
        match = _FRAME.match(text)
        if not match:
            raise InvalidValue(f"serial line {text!r}: write it as BAUD FRAME, e.g. \"9600 7E1\" or \"115200 8E1\"")
        baud, bits, parity, stop = match.groups()
        return cls(int(baud), int(bits), parity.upper(), int(stop))

    @property
    def bits(self) -> int:
        """Bits on the line per character: start, data, parity, stop (7E1: 10, 8E1: 11)."""
        return char_bits(self.bytesize, self.parity, self.stopbits)

    @property
    def char_time(self) -> float:
        """Seconds one character takes on the line."""
        return self.bits / self.baudrate

    def __str__(self) -> str:
        return f"{self.baudrate} {self.bytesize}{self.parity}{self.stopbits}"


class PacedSender:
    """Hands bytes to ``write`` at ``rate``'s character time, in order (create and use on ``loop``)."""

    def __init__(self, loop: asyncio.AbstractEventLoop, rate: LineRate, write: Callable[[bytes], None]) -> None:
        self.loop = loop
        self.rate = rate
        self.write = write
        self.dropped = 0  # bytes refused because MAX_QUEUED were already waiting
        self._queue: collections.deque[bytes] = collections.deque()
        self._queued = 0
        self._per_slice = max(1, int(SLICE / rate.char_time))
        self._free_at = 0.0  # loop time at which the line has carried everything handed on so far
        self._timer: asyncio.TimerHandle | None = None
        self.closed = False

    def send(self, data: bytes) -> None:
        if self.closed or not data:
            return
        room = MAX_QUEUED - self._queued
        if len(data) > room:
            self.dropped += len(data) - max(room, 0)
            data = data[:max(room, 0)]
            if not data:
                return
        self._queue.append(bytes(data))
        self._queued += len(data)
        if self._timer is None:
            self._free_at = max(self._free_at, self.loop.time())  # an idle line starts now
            self._next()

    def _next(self) -> None:
        piece = bytearray()
        while self._queue and len(piece) < self._per_slice:
            head = self._queue.popleft()
            take = self._per_slice - len(piece)
            piece += head[:take]
            if len(head) > take:
                self._queue.appendleft(head[take:])
        self._queued -= len(piece)
        self._free_at += len(piece) * self.rate.char_time
        self._timer = self.loop.call_at(self._free_at, self._deliver, bytes(piece))

    def _deliver(self, piece: bytes) -> None:
        self._timer = None
        if self.closed:
            return
        self.write(piece)
        if self._queue:
            self._next()

    @property
    def idle(self) -> bool:
        return self._timer is None

    def close(self) -> None:
        self.closed = True
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        self._queue.clear()
        self._queued = 0


__all__ = ["LineRate", "PacedSender", "SLICE", "MAX_QUEUED"]
