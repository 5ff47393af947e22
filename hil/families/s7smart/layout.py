"""The profile sections of an S7-200 SMART bench: ``[s7]`` (CPU and Modbus map) and ``[s7rtc]`` (where the
test program on the PLC keeps its clock triggers, buffers and results).

The clock is not memory-mapped: a small test program runs READ_RTC / SET_RTC / SET_RTC_I on rising edges of
trigger bits and leaves the buffers, ENO and the error code in V memory.  Its layout belongs to the bench, like
the FUN86 layout of an FBs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from hil.core.errors import AddressError, InvalidValue, ProfileError
from hil.families.s7smart.address import S7Address, parse_s7, parse_s7_range

#: CPUs without a real-time clock (no RTC, no super capacitor): the time is lost at every power cycle.
NO_RTC_CPUS = ("CR40", "CR60")
CPUS = ("SR20", "ST20", "SR30", "ST30", "SR40", "ST40", "SR60", "ST60", "CR40", "CR60", "CR20s", "CR30s",
        "CR40s", "CR60s")


@dataclass(frozen=True)
class S7Settings:
    cpu: str = "ST40"
    hold_start: int = 0  # V byte of holding register 40001 (MBUS_SLAVE HoldStart, conventionally VB0)
    max_hold: int = 1000  # holding registers mapped (MBUS_SLAVE MaxHold)
    start: str = "host"  # the emulator's clock at build: "host" time or "power-loss" (2000-01-01 00:00:00)

    @property
    def has_rtc(self) -> bool:
        return self.cpu not in NO_RTC_CPUS


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
_REQUIRED = ("set_trigger", "read_trigger", "set_buffer", "read_buffer", "eno", "error")


def parse_s7_settings(table: dict[str, Any], where: str) -> S7Settings:
    table = dict(table)
    out: dict[str, Any] = {}
    cpu = table.pop("cpu", "ST40")
    if cpu not in CPUS:
        raise ProfileError(f"{where}: [s7] cpu = {cpu!r} is not an S7-200 SMART CPU ({', '.join(CPUS)})")
    out["cpu"] = cpu
    if "hold_start" in table:
        raw = table.pop("hold_start")
        try:
            a = parse_s7(raw)
        except (AddressError, TypeError) as exc:
            raise ProfileError(f"{where}: [s7] hold_start: {exc}") from None
        if a.area != "V" or a.is_bit or a.size != 1:
            raise ProfileError(f"{where}: [s7] hold_start must be a V byte such as 'VB0', not {raw!r}")
        out["hold_start"] = a.byte
    if "max_hold" in table:
        n = table.pop("max_hold")
        if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= 10240:
            raise ProfileError(f"{where}: [s7] max_hold must be 1–10240 registers, not {n!r}")
        out["max_hold"] = n
    if "start" in table:
        start = table.pop("start")
        if start not in ("host", "power-loss"):
            raise ProfileError(f"{where}: [s7] start must be 'host' or 'power-loss', not {start!r}")
        out["start"] = start
    if table:
        raise ProfileError(f"{where}: unknown key(s) in [s7]: {', '.join(sorted(table))}")
    return S7Settings(**out)


def parse_s7rtc(table: dict[str, Any], where: str) -> S7RtcLayout:
    table = dict(table)
    out: dict[str, S7Address] = {}
    for key in _REQUIRED:
        if key not in table:
            raise ProfileError(f"{where}: [s7rtc] {key} is required")
    for key in (*_BITS, *_BUFFERS, "error"):
        if key not in table:
            continue
        raw = table.pop(key)
        try:
            a = parse_s7(raw)
        except (AddressError, TypeError) as exc:
            raise ProfileError(f"{where}: [s7rtc] {key}: {exc}") from None
        if a.area != "V":
            raise ProfileError(f"{where}: [s7rtc] {key} = {raw!r} must be in V memory (the harness reaches V)")
        want = "a bit such as 'V100.0'" if key in _BITS else ("a byte such as 'VB110' (8 bytes from it)"
                                                              if key in _BUFFERS else "a word such as 'VW104'")
        ok = a.is_bit if key in _BITS else (a.size == 1 if key in _BUFFERS else a.size == 2)
        if not ok or (not a.is_bit and key in _BITS):
            raise ProfileError(f"{where}: [s7rtc] {key} = {raw!r} must be {want}")
        if key in _BUFFERS:
            a = S7Address("V", a.byte, None, 1)
        out[key] = a
    if table:
        raise ProfileError(f"{where}: unknown key(s) in [s7rtc]: {', '.join(sorted(table))}")
    if ("set_i_trigger" in out) != ("set_i_buffer" in out):
        raise ProfileError(f"{where}: [s7rtc] set_i_trigger and set_i_buffer go together")
    layout = S7RtcLayout(**out)
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
            bits = k1 in _BITS and k2 in _BITS
            if s1 < e2 and s2 < e1 and not bits:
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
