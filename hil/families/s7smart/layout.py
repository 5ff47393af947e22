"""The profile sections of an S7-200 SMART bench: ``[s7]`` (CPU and Modbus map) and ``[s7rtc]`` (where the
test program on the PLC keeps its clock triggers, buffers and results).

The clock is not memory-mapped: a small test program runs READ_RTC / SET_RTC / SET_RTC_I on rising edges of
trigger bits and leaves the buffers, ENO and the error code in V memory.  Its layout belongs to the bench, like
the FUN86 layout of an FBs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from hil.bench.schema import Key, Section
from hil.core.errors import InvalidValue, ProfileError
from hil.families.s7smart.address import S7Address, parse_s7, parse_s7_range

#: CPUs without a real-time clock (no RTC, no super capacitor): the time is lost at every power cycle.
NO_RTC_CPUS = ("CR40", "CR60")
CPUS = ("SR20", "ST20", "SR30", "ST30", "SR40", "ST40", "SR60", "ST60", "CR40", "CR60", "CR20s", "CR30s",
        "CR40s", "CR60s")


@dataclass(frozen=True)
class S7RtcLayout:
    set_trigger: S7Address  # rising edge → SET_RTC set_buffer
    read_trigger: S7Address  # rising edge → READ_RTC read_buffer
    set_buffer: S7Address  # VB: 8 bytes
    read_buffer: S7Address  # VB: 8 bytes
    eno: S7Address  # bit: ENO of the clock instruction last executed
    error: S7Address  # VW: error code after it (GET_ERROR): 0000H, 0007H …
    set_i_trigger: S7Address | None = None  # rising edge → SET_RTC_I set_i_buffer (library instruction)
    set_i_buffer: S7Address | None = None
    sm4_3: S7Address | None = None  # bit: copy of SM4.3 (colliding clock access)

    def triggers(self) -> list[S7Address]:
        return [a for a in (self.set_trigger, self.read_trigger, self.set_i_trigger) if a is not None]


_BITS = ("set_trigger", "read_trigger", "eno", "set_i_trigger", "sm4_3")
_BUFFERS = ("set_buffer", "read_buffer", "set_i_buffer")
_WANT = {"bit": "a bit such as 'V100.0'", "buffer": "a byte such as 'VB110' (8 bytes from it)",
         "word": "a word such as 'VW104'"}


def _hold_start(raw: Any) -> int:
    a = _operand(raw)
    if a.area != "V" or a.is_bit or a.size != 1:
        raise InvalidValue(f"hold_start must be a V byte such as 'VB0', not {raw!r}")
    return a.byte


def _operand(raw: Any) -> S7Address:
    try:
        return parse_s7(raw)
    except TypeError as exc:
        raise InvalidValue(str(exc)) from None


def _v(shape: str) -> dict[str, Any]:
    """The check and conversion of a V operand of ``shape`` (bit, buffer: its first byte, word)."""
    def check(raw: Any) -> bool | str:
        a = _operand(raw)
        if a.area != "V":
            return "must be in V memory (the harness reaches V)"
        ok = a.is_bit if shape == "bit" else (not a.is_bit and a.size == (2 if shape == "word" else 1))
        return ok or f"must be {_WANT[shape]}"

    def convert(raw: Any) -> S7Address:
        a = _operand(raw)
        return S7Address("V", a.byte, None, 1) if shape == "buffer" else a
    return {"check": check, "convert": convert}


S7 = Section("s7", "The S7-200 SMART CPU and its Modbus server (MBUS_SLAVE).", (
    Key("cpu", str, "The CPU model (CR40/CR60: no real-time clock).", "ST40", choices=CPUS,
        hint=f"is not an S7-200 SMART CPU ({', '.join(CPUS)})"),
    Key("hold_start", str, "MBUS_SLAVE HoldStart: the V byte of holding register 40001.", "VB0",
        convert=_hold_start),
    Key("max_hold", int, "MBUS_SLAVE MaxHold: holding registers mapped.", 1000, low=1, high=10240,
        hint="must be 1–10240 registers"),
    Key("start", str, "The emulator's clock at power-on: \"host\" time or \"power-loss\" (2000-01-01).", "host",
        choices=("host", "power-loss"), hint="must be 'host' or 'power-loss'", live=False),
), family="s7-200smart")

_TRIGGER = "rising edge → "
S7RTC = Section("s7rtc", "Where the test program on the PLC keeps its clock triggers, buffers and results "
                "(V memory).", (
    Key("set_trigger", str, _TRIGGER + "SET_RTC set_buffer (a bit).", required=True, **_v("bit"),
        example="V100.0"),
    Key("read_trigger", str, _TRIGGER + "READ_RTC read_buffer (a bit).", required=True, **_v("bit"),
        example="V100.1"),
    Key("set_buffer", str, "8 bytes, BCD, SET_RTC's input.", required=True, **_v("buffer"), example="VB110"),
    Key("read_buffer", str, "8 bytes, BCD, READ_RTC's output.", required=True, **_v("buffer"),
        example="VB130"),
    Key("eno", str, "ENO of the clock instruction last executed (a bit).", required=True, **_v("bit"),
        example="V102.0"),
    Key("error", str, "GET_ERROR after it (a word): 0000H, 0007H …", required=True, **_v("word"),
        example="VW104"),
    Key("set_i_trigger", str, _TRIGGER + "SET_RTC_I set_i_buffer (a bit; with set_i_buffer).", **_v("bit"),
        example="V100.2"),
    Key("set_i_buffer", str, "8 bytes, plain integers, SET_RTC_I's input.", **_v("buffer"), example="VB120"),
    Key("sm4_3", str, "A copy of SM4.3 (colliding clock access), a bit.", **_v("bit"), example="V102.1"),
), family="s7-200smart")


@dataclass(frozen=True)
class S7Settings:
    """``[s7]`` (:data:`S7` describes each key)."""

    cpu: str = S7.default("cpu")
    hold_start: int = S7.default("hold_start")  # the V byte (VB0: 0)
    max_hold: int = S7.default("max_hold")
    start: str = S7.default("start")

    @property
    def has_rtc(self) -> bool:
        return self.cpu not in NO_RTC_CPUS


def parse_s7_settings(table: dict[str, Any], where: str) -> S7Settings:
    return S7Settings(**S7.read(table, where))


def parse_s7rtc(table: dict[str, Any], where: str) -> S7RtcLayout:
    layout = S7RtcLayout(**S7RTC.read(table, where))
    if (layout.set_i_trigger is None) != (layout.set_i_buffer is None):
        raise ProfileError(f"{where}: [s7rtc] set_i_trigger and set_i_buffer go together")
    _check_overlaps(layout, where)
    return layout


def _check_overlaps(layout: S7RtcLayout, where: str) -> None:
    """Buffers (8 bytes) and results must not overlap, or the program would clobber its own inputs."""
    spans: list[tuple[str, int, int]] = []
    for key in _BUFFERS:
        a = getattr(layout, key)
        if a is not None:
            spans.append((key, a.byte, a.byte + 8))
    spans.append(("error", layout.error.byte, layout.error.end))
    for key in _BITS:
        a = getattr(layout, key)
        if a is not None:
            spans.append((key, a.byte, a.byte + 1))
    for i, (k1, s1, e1) in enumerate(spans):
        for k2, s2, e2 in spans[i + 1:]:
            both_bits = k1 in _BITS and k2 in _BITS
            if s1 < e2 and s2 < e1 and not both_bits:
                raise ProfileError(f"{where}: [s7rtc] {k1} and {k2} overlap in V memory")
    bits = [getattr(layout, k) for k in _BITS if getattr(layout, k) is not None]
    if len(set(bits)) != len(bits):
        raise ProfileError(f"{where}: [s7rtc] two bits share one address")


def check_s7_ranges(value: list) -> bool:
    """[safety] writable/volatile for an S7 bench: ranges such as 'VB100-VB139' or 'Q0.0-Q0.7'."""
    for item in value:
        if not isinstance(item, str):
            raise InvalidValue(f"{item!r} is not an S7 range like 'VB100-VB139'")
        parse_s7_range(item)
    return True
