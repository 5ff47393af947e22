"""What a real Modbus RTU slave does before decoding: cut the line into frames at silences, drop bad CRCs.

pymodbus's RTU server framer keeps undecodable bytes and glues every later frame onto them, so one burst of
line noise silences the emulator for good.  The pty bridge passes the client's bytes through this gate: bytes
are collected until the line has been quiet for a frame gap, and only a chunk that ends in a valid frame (CRC
correct) reaches the server; noise in front of a frame and chunks with no valid frame are dropped and counted.

Junk costs linear time and bounded memory (issue 15: a flood must not starve the emulator's other clients, which
share its event loop): a frame is at most :data:`MAX_FRAME` bytes, so only the last ones before a silence are
kept, and the frame that ends a chunk is found in one backward pass over them (:func:`last_frame`).
"""

from __future__ import annotations

import asyncio
import collections
from collections.abc import Callable

from pymodbus.framer.rtu import FramerRTU

FRAME_GAP = 0.004  # s: 3.5 characters at 9600 bit/s; on a pty a whole frame arrives in one write anyway
MIN_FRAME = 4  # unit, function, CRC
MAX_FRAME = 256  # the RTU ADU limit: unit, PDU (≤ 253) and CRC


_TABLE = FramerRTU.crc16_table  # the Modbus RTU CRC-16 (poly A001H) table pymodbus computes its CRCs with
# The high bytes of the table's entries are all different, so a CRC step can be run backwards (last_frame).
_BY_HIGH = {entry >> 8: index for index, entry in enumerate(_TABLE)}
assert len(_BY_HIGH) == 256


def is_frame(chunk: bytes) -> bool:
    return len(chunk) >= MIN_FRAME and FramerRTU.check_CRC(chunk[:-2], int.from_bytes(chunk[-2:], "big"))


def last_frame(chunk: bytes) -> tuple[bytes, int]:
    """The longest valid frame ending ``chunk`` (b"" if none) and how many bytes before it are noise.

    A frame with its CRC appended runs the CRC register from FFFFH to 0.  Running the steps backwards from 0 over
    the chunk's bytes, last to first, gives at each start the register a frame from there would have needed at
    its beginning: where that is FFFFH, a valid frame starts — every start in one pass instead of a CRC each."""
    crc, start = 0, -1
    for i in range(len(chunk) - 1, -1, -1):
        index = _BY_HIGH[crc >> 8]
        crc = ((crc ^ _TABLE[index]) & 0xFF) << 8 | (index ^ chunk[i])
        if crc == 0xFFFF and len(chunk) - i >= MIN_FRAME:
            start = i
    if start < 0:
        return b"", len(chunk)
    return chunk[start:], start


class RtuGate:
    """Feed it bytes as they arrive; it calls ``forward(frame)`` once per clean frame after a line silence."""

    def __init__(self, loop: asyncio.AbstractEventLoop, forward: Callable[[bytes], None]) -> None:
        self.loop = loop
        self.forward = forward
        self.stats: collections.Counter[str] = collections.Counter()
        self._buffer = bytearray()
        self._noisy = False  # the buffer lost its start to noise: only the silence can end a frame now
        self._timer: asyncio.TimerHandle | None = None
        self._last = 0.0  # loop time of the last bytes

    def feed(self, data: bytes) -> None:
        self._buffer += data
        if len(self._buffer) > MAX_FRAME:  # a frame ends at a silence: what came before its last 256 bytes is noise
            excess = len(self._buffer) - MAX_FRAME
            del self._buffer[:excess]
            self.stats["rtu_noise_bytes"] += excess
            self._noisy = True
        if not self._noisy and is_frame(bytes(self._buffer)):  # a clean frame: no need to wait for the silence
            self._flush()
            return
        self._last = self.loop.time()
        if self._timer is None:  # one timer, not one per read: a flood is thousands of reads
            self._timer = self.loop.call_later(FRAME_GAP, self._quiet)

    def _quiet(self) -> None:
        self._timer = None
        wait = self._last + FRAME_GAP - self.loop.time()
        if wait > 0:  # bytes came since the timer was set: the silence is not long enough yet
            self._timer = self.loop.call_later(wait, self._quiet)
        else:
            self._flush()

    def _flush(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        chunk, self._buffer, self._noisy = bytes(self._buffer), bytearray(), False
        frame, noise = last_frame(chunk)
        if noise:
            self.stats["rtu_noise_bytes"] += noise
        if frame:
            self.stats["rtu_frames"] += 1
            self.forward(frame)

    def close(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
