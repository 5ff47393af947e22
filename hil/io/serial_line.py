"""Serial line settings both protocols share: a pseudo-terminal is not a real line."""

from __future__ import annotations

import os


def is_pty(device: str) -> bool:
    """True for a pseudo-terminal slave (``/dev/pts/N``): Unix98 pty slaves have majors 136–143."""
    if "://" in device:
        return False
    try:
        return 136 <= os.major(os.stat(device).st_rdev) <= 143
    except OSError:
        return False


def line_coding(device: str, bytesize: int, parity: str, stopbits: int) -> tuple[int, str, int]:
    """The (bytesize, parity, stopbits) to open ``device`` with: as given for a real line, 8N1 for a pty.

    A pty has no line coding, and recent Linux kernels refuse (EINVAL) to change CS7/PARENB on one whose settings a
    previous client already applied — pyserial sets them again on every reconfigure.  FATEK's 7-bit ASCII frames
    and Modbus RTU bytes pass through 8N1 unchanged."""
    return (8, "N", 1) if is_pty(device) else (bytesize, parity, stopbits)


def char_bits(bytesize: int, parity: str, stopbits: int) -> int:
    """Bits one character takes on the line: start, data, parity, stop (7E1: 10, 8E1: 11, 8N1: 10)."""
    return 1 + bytesize + (parity.upper() != "N") + stopbits
