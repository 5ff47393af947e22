"""What a real Modbus RTU slave does before decoding: cut the line into frames at silences, drop bad CRCs.

pymodbus's RTU server framer keeps undecodable bytes and glues every later frame onto them, so one burst of
line noise silences the emulator for good.  The pty bridge passes the client's bytes through this gate: bytes
are collected until the line has been quiet for a frame gap, and only a chunk that ends in a valid frame (CRC
correct) reaches the server; noise in front of a frame and chunks with no valid frame are dropped and counted.
"""

from __future__ import annotations

import asyncio
import collections
from typing import Callable

FRAME_GAP = 0.004  # s: 3.5 characters at 9600 bit/s; on a pty a whole frame arrives in one write anyway
MIN_FRAME = 4  # unit, function, CRC


def crc16(data: bytes) -> int:
    """Modbus RTU CRC-16 (poly A001H, init FFFFH); sent low byte first."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


def is_frame(chunk: bytes) -> bool:
    return len(chunk) >= MIN_FRAME and crc16(chunk[:-2]) == int.from_bytes(chunk[-2:], "little")


def last_frame(chunk: bytes) -> tuple[bytes, int]:
    """The longest valid frame ending ``chunk`` (b"" if none) and how many bytes before it are noise."""
    for start in range(len(chunk) - MIN_FRAME + 1):
        if is_frame(chunk[start:]):
            return chunk[start:], start
    return b"", len(chunk)


class RtuGate:
    """Feed it bytes as they arrive; it calls ``forward(frame)`` once per clean frame after a line silence."""

    def __init__(self, loop: asyncio.AbstractEventLoop, forward: Callable[[bytes], None]) -> None:
        self.loop = loop
        self.forward = forward
        self.stats: collections.Counter[str] = collections.Counter()
        self._buffer = bytearray()
        self._timer: asyncio.TimerHandle | None = None

    def feed(self, data: bytes) -> None:
        self._buffer += data
        if is_frame(bytes(self._buffer)):  # a complete clean frame: no need to wait for the silence
            self._flush()
            return
        if self._timer is not None:
            self._timer.cancel()
        self._timer = self.loop.call_later(FRAME_GAP, self._flush)

    def _flush(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        chunk, self._buffer = bytes(self._buffer), bytearray()
        frame, noise = last_frame(chunk)
        if noise:
            self.stats["rtu_noise_bytes"] += noise
        if frame:
            self.stats["rtu_frames"] += 1
            self.forward(frame)

    def close(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
