"""Named FBs special registers and relays used by the device layer, the emulator and the suites.

Names only — never outcomes.  Suites state expected values literally from the manual.
"""

from __future__ import annotations

from hil.core.errors import InvalidValue

# Real-time clock (manual chapter 15)
RTC_SECOND = "R4128"
RTC_MINUTE = "R4129"
RTC_HOUR = "R4130"
RTC_DAY = "R4131"
RTC_MONTH = "R4132"
RTC_YEAR = "R4133"
RTC_WEEKDAY = "R4134"
RTC_HOUR_MINUTE = "R4135"
RTC_FIELDS = ("R4128", "R4129", "R4130", "R4131", "R4132", "R4133", "R4134")
RTC_HOLD = "M1952"  # 1: read-out frozen; falling edge: set the chip from R4128–R4134
RTC_ADJUST_30S = "M1953"  # rising edge: ±30 s correction
RTC_INSTALLED = "M1954"
RTC_SET_ERROR = "M1955"
RTC_CHIP = "D4053"  # 0 none, 1 HT1381, 2 ISL1208, 3 S-35390A
RTC_RATE_CODE = "D4054"

# Temperature and PID (manual chapter 20)
PID_SOURCE_KEY = "R4003"  # A55AH enables R4004
PID_SOURCE = "R4004"
PID_TIMING = "R4005"  # low byte: PID interval code, high byte: PWM period code
HEATER_LOOP_PERCENT = "R4006"
HEATER_LOOP_SECONDS = "R4007"
PREALARM_LIMIT = "R4008"
INSTALLED_LOW = "R4010"  # points 0–15
INSTALLED_HIGH = "R4011"  # points 16–31
PID_ENABLE_LOW = "R4012"
PID_ENABLE_HIGH = "R4013"

# Power-on values of the special registers the harness relies on (fbs-pid.md, fbs-temperature.md).
POWER_ON_DEFAULTS: dict[str, int] = {
    PID_TIMING: 0x0102,
    HEATER_LOOP_PERCENT: 90,
    HEATER_LOOP_SECONDS: 600,
    PREALARM_LIMIT: 3500,
    INSTALLED_LOW: 0xFFFF,
    INSTALLED_HIGH: 0xFFFF,
    PID_ENABLE_LOW: 0xFFFF,
    PID_ENABLE_HIGH: 0xFFFF,
}


#: An FBs measures at most 32 temperature points (8 modules), numbered 0–31; FUN86 covers at most 32 from Sn.
MAX_POINTS = 32


def point_bit(index: int) -> tuple[int, int]:
    """Where point ``index`` (or a FUN86 bit counted from Sn) sits in a pair of 16-bit words: (0 for 0–15 or 1
    for 16–31, the bit in that word) — R4010/R4011, R4012/R4013, WR+0/1, WR+2/3, the break bits alike."""
    if not 0 <= index < MAX_POINTS:
        raise InvalidValue(f"temperature point {index} is outside 0–{MAX_POINTS - 1}")
    return divmod(index, 16)


def pair_bit(words: tuple[int, ...] | list[int], index: int) -> bool:
    """Point ``index``'s bit in a pair of 16-bit words (see :func:`point_bit`)."""
    word, bit = point_bit(index)
    return bool(words[word] >> bit & 1)


def with_bit(word: int, bit: int, on: bool) -> int:
    """``word`` with ``bit`` set or cleared."""
    return word | 1 << bit if on else word & ~(1 << bit)


def signed16(word: int) -> int:
    """A 16-bit register word as the signed value it holds (0.1° readings, SV, Os, Sn/Zn: −200.0 °C is 0xF830)."""
    return word - 0x10000 if word & 0x8000 else word
