"""D4054, the S-35390A clock-rate code: the manual's table lookup and an exact decoder.

Sign convention (the manual's): a rate ``r`` > 0 means the PLC clock runs *fast* by ``r`` s/day, and the code
for ``r`` is the one that makes such a clock run true.  Decoding (fbs-rtc.md, checked against every row):
high byte 0x56; reverse the bits of the low byte (the chip is written LSB first); in the reversed byte bit 7 is
the mode (1 fine, 0 coarse) and bits 6–0 a 7-bit two's-complement step count; rate = steps × step size.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hil.core.errors import InvalidValue
from hil.families.fbs.d4054_table import ROWS as _PRINTED_ROWS

NO_CORRECTION = 0x0000
HIGH_BYTE = 0x56
FINE_STEP = 0.087890625  # s/day per step (1.01725 ppm, applied every 60 s)
COARSE_STEP = 0.263671875  # s/day per step (3.0518 ppm, applied every 20 s)
RATE_MIN = -16.88  # the manual's setting range, s/day
RATE_MAX = 16.61

# The manual's Table 1 has two misprints: the 2.05 row prints 5618H (that is the 6.36 row's code, 24 coarse
# steps) and the 1.63 row prints 56C8H (19 coarse steps = 5.01 s/day).  Both sit in the fine-mode run, where
# their neighbours step by one: the consistent codes are 5619H (24 fine steps = 2.11 s/day) and 56C9H
# (19 fine steps = 1.67 s/day).  This is the only place the printed table is corrected.
MISPRINTS: dict[float, tuple[int, int]] = {2.05: (0x5618, 0x5619), 1.63: (0x56C8, 0x56C9)}

#: (listed rate, code) with the misprints corrected, fastest first.
TABLE: tuple[tuple[float, int], ...] = tuple(
    (rate, MISPRINTS[rate][1] if rate in MISPRINTS and MISPRINTS[rate][0] == code else code)
    for rate, code in _PRINTED_ROWS)

# Listed rates in integer hundredths (they are printed with two decimals), so that distances and ties are
# decided exactly rather than by float rounding.
_HUNDREDTHS: tuple[tuple[int, int], ...] = tuple((round(rate * 100), code) for rate, code in TABLE)


@dataclass(frozen=True)
class RateCode:
    """What a D4054 code does: ``mode`` "fine" | "coarse" ("none" for 0000H), signed ``steps``, and the rate."""

    mode: str
    steps: int
    s_per_day: float

    @property
    def ppm(self) -> float:
        return self.s_per_day / 86400 * 1e6


def _reverse_byte(value: int) -> int:
    return int(f"{value & 0xFF:08b}"[::-1], 2)


def code_for_rate(s_per_day: float) -> int:
    """The manual's D4054 code for a clock that runs fast by ``s_per_day`` (negative = slow).

    Picks the row whose listed rate is nearest, as a reader of Table 1 would.  A value exactly halfway between
    two listed rates takes the one nearer zero (the smaller correction), so the choice is deterministic.
    Raises ValueError outside the setting range −16.88…+16.61 s/day.
    """
    rate = float(s_per_day)
    if not math.isfinite(rate):
        raise InvalidValue(f"clock error must be a finite number of s/day, not {s_per_day!r}")
    if not RATE_MIN - 1e-9 <= rate <= RATE_MAX + 1e-9:
        raise InvalidValue(f"clock error {rate:+.4f} s/day is outside the S-35390A setting range "
                         f"{RATE_MIN}…+{RATE_MAX} s/day (manual ch. 15); D4054 cannot correct it")
    x = rate * 100
    best = min(_HUNDREDTHS, key=lambda row: (round(abs(x - row[0]), 6), abs(row[0])))
    return best[1]


def rate_for_code(code: int) -> RateCode:
    """Decode a D4054 value exactly.  0000H = no correction; anything else must be 56xxH (ValueError)."""
    if isinstance(code, bool) or not isinstance(code, int):
        raise InvalidValue(f"a D4054 code is an integer 0000H or 5600H–56FFH, not {code!r}")
    if code == NO_CORRECTION:
        return RateCode("none", 0, 0.0)
    if not 0 <= code <= 0xFFFF:
        raise InvalidValue(f"D4054 code {code} does not fit a 16-bit register (0000H or 5600H–56FFH)")
    if code >> 8 != HIGH_BYTE:
        raise InvalidValue(f"D4054 code {code:04X}H is malformed: the high byte must be 56H (or the whole code "
                         f"0000H for no correction); the manual does not say what the PLC does with it")
    reversed_low = _reverse_byte(code)
    fine = bool(reversed_low & 0x80)
    steps = reversed_low & 0x7F
    steps -= 0x80 if steps & 0x40 else 0  # 7-bit two's complement
    step = FINE_STEP if fine else COARSE_STEP
    return RateCode("fine" if fine else "coarse", steps, steps * step)


def code_for_steps(mode: str, steps: int) -> int:
    """The D4054 code for ``steps`` (−64…+63) in ``mode`` "fine" | "coarse" (inverse of :func:`rate_for_code`)."""
    if mode not in ("fine", "coarse"):
        raise InvalidValue(f"mode must be 'fine' or 'coarse', not {mode!r}")
    if not -64 <= steps <= 63:
        raise InvalidValue(f"steps must be −64…+63 (7-bit two's complement), not {steps}")
    reversed_low = (0x80 if mode == "fine" else 0) | (steps & 0x7F)
    return HIGH_BYTE << 8 | _reverse_byte(reversed_low)


__all__ = ["RateCode", "code_for_rate", "rate_for_code", "code_for_steps", "TABLE", "MISPRINTS",
           "NO_CORRECTION", "FINE_STEP", "COARSE_STEP", "RATE_MIN", "RATE_MAX"]
