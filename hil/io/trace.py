"""Wire traces: every frame sent and received, with a timestamp and what it means.

:class:`WireTrace` attaches to a transport once and records into whichever test is current:

* FATEK (:class:`~hil.families.fbs.transport.fatek.FatekTransport`): its ``observers`` see each frame; decoded with
  the decoder the family registered in :data:`DESCRIBERS` (``hil.families.fbs.protocol.fatek.describe_frame``);
* Modbus (:class:`~hil.io.modbus_client.ModbusWire`, whose client was built with pymodbus's ``trace_packet=``
  hook): its ``observers`` see the raw ADU bytes as they go out and come in, decoded to function, address and
  quantity;
* no wire (the in-process ``emulator`` target, an S7 in-process io): the transport calls themselves.

Recording is cheap (a tuple per frame) and bounded per test; formatting happens only for traces that are kept.
"""

from __future__ import annotations

import struct
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

#: frame decoders of the families' own protocols, by trace kind (a family registers its own)
DESCRIBERS: dict[str, Callable[..., str]] = {}
#: trace kinds whose frames are ASCII text (shown beside the hex); a family registers its own
PRINTABLE: set[str] = set()
#: bits a character takes on the serial line, by trace kind (start + data + parity + stop), for the time a run's
#: bytes would take at 9600 bit/s (hil.plugin.perf); Modbus RTU is always 8E1, a family registers its own
CHAR_BITS: dict[str, int] = {"modbus-rtu": 11}
MAX_ENTRIES = 20_000  # per test: a virtual day of polling stays bounded; the oldest frames are dropped first


@dataclass(frozen=True)
class TraceEntry:
    t: float  # wall-clock seconds since the epoch
    direction: str  # "tx", "rx" or "call"
    data: bytes  # the frame ("call": empty)
    meaning: str

    @property
    def hex(self) -> str:
        return self.data.hex(" ").upper()


class WireTrace:
    """Records frames into the current test's buffer (``start``/``stop``); frames outside a test are dropped."""

    def __init__(self, max_entries: int = MAX_ENTRIES) -> None:
        self.max_entries = max_entries
        self.kind = "none"  # "fatek", "modbus-tcp", "modbus-rtu", "calls" once attached
        self._raw: deque[tuple[float, str, bytes, Any]] | None = None
        self.dropped = 0
        self._detach: list[Callable[[], None]] = []

    # -- per test -------------------------------------------------------------------------------------------------
    def start(self) -> None:
        self._raw = deque(maxlen=self.max_entries)
        self.dropped = 0

    def stop(self) -> list[TraceEntry]:
        raw, self._raw = self._raw, None
        return [TraceEntry(t, d, data, self._meaning(d, data, extra)) for t, d, data, extra in (raw or ())]

    def _record(self, direction: str, data: bytes, extra: Any = None) -> None:
        raw = self._raw
        if raw is None:
            return
        if len(raw) == raw.maxlen:
            self.dropped += 1
        raw.append((time.time(), direction, bytes(data), extra))

    # -- attaching ------------------------------------------------------------------------------------------------
    def attach(self, transport: Any) -> WireTrace:
        """Hook into ``transport`` (the raw one, under the guard).  Idempotent per recorder."""
        if self._detach:
            return self
        observers = getattr(transport, "observers", None)
        if isinstance(observers, list):
            self.kind = getattr(transport, "trace_kind", "frames")
            observer = lambda direction, frame: self._record(direction, frame)  # noqa: E731
            observers.append(observer)
            self._detach.append(lambda: observers.remove(observer))
        else:
            self.kind = "calls"
            self._wrap_calls(transport)
        return self

    def detach(self) -> None:
        while self._detach:
            self._detach.pop()()

    def _wrap_calls(self, transport: Any) -> None:
        """No wire: record each primitive call on the instance (arguments and result)."""
        names = [n for n in ("_read_words", "_write_words", "_read_bits", "_write_bits", "_read_many",
                             "_write_many", "_status", "_read_v", "_write_v") if hasattr(transport, n)]
        for name in names:
            original = getattr(transport, name)

            def wrapped(*args: Any, _original: Callable = original, _name: str = name) -> Any:
                result = _original(*args)
                self._record("call", b"", (_name.lstrip("_"), args, result))
                return result

            setattr(transport, name, wrapped)
            self._detach.append(partial(transport.__dict__.pop, name, None))

    # -- meaning ----------------------------------------------------------------------------------------------------
    def _meaning(self, direction: str, data: bytes, extra: Any) -> str:
        try:
            if direction == "call":
                name, args, result = extra
                shown = ", ".join(_short(a) for a in args)
                return f"{name}({shown})" + ("" if result is None else f" → {_short(result)}")
            if self.kind in DESCRIBERS:
                return DESCRIBERS[self.kind](data, reply=direction == "rx")
            if self.kind.startswith("modbus"):
                return describe_modbus(data, rtu=self.kind == "modbus-rtu", reply=direction == "rx")
        except Exception as exc:  # noqa: BLE001 - a trace never breaks a test
            return f"(not decoded: {type(exc).__name__})"
        return ""


def _item(value: Any) -> str:
    if isinstance(value, tuple) and len(value) == 2 and not isinstance(value[0], (int, float)):
        return f"{value[0]}={value[1]}"  # (Address, value) of a mixed write
    return str(value)


def _short(value: Any, limit: int = 100) -> str:
    if isinstance(value, (list, tuple)):
        text = "[" + ", ".join(_item(v) for v in value[:16]) + (", …" if len(value) > 16 else "") + "]"
    else:
        text = str(value)
    return text if len(text) <= limit else text[:limit - 1] + "…"


_FUNCTIONS = {1: "read coils", 2: "read discrete inputs", 3: "read holding registers", 4: "read input registers",
              5: "write coil", 6: "write register", 15: "write coils", 16: "write registers"}


def describe_modbus(data: bytes, *, rtu: bool, reply: bool) -> str:
    """Function, unit, address and quantity of a Modbus ADU (TCP: MBAP header; RTU: unit … CRC)."""
    if rtu:
        if len(data) < 4:
            return "partial RTU frame"
        unit, pdu = data[0], data[1:-2]
        head = f"unit {unit}"
    else:
        if len(data) < 8:
            return "partial TCP frame"
        tid, _, _, unit = struct.unpack(">HHHB", data[:7])
        pdu = data[7:]
        head = f"tid {tid} unit {unit}"
    fc = pdu[0]
    if fc & 0x80:
        code = pdu[1] if len(pdu) > 1 else None
        return f"{head} exception reply to FC{fc & 0x7F:02d}: code {code}"
    name = _FUNCTIONS.get(fc, "function")
    if reply:
        if fc in (1, 2, 3, 4) and len(pdu) >= 2:
            body = pdu[2:2 + pdu[1]]
            if fc in (3, 4):
                words = [int.from_bytes(body[i:i + 2], "big") for i in range(0, len(body) - 1, 2)]
                return f"{head} FC{fc:02d} {name} reply: {_short(words)}"
            return f"{head} FC{fc:02d} {name} reply: {len(body)} byte(s) {body.hex().upper()}"
        if fc in (5, 6, 15, 16) and len(pdu) >= 5:
            address, quantity = struct.unpack(">HH", pdu[1:5])
            return f"{head} FC{fc:02d} {name} done at {address} ×{quantity}"
        return f"{head} FC{fc:02d} reply"
    if len(pdu) >= 5:
        address, quantity = struct.unpack(">HH", pdu[1:5])
        if fc in (5, 6):
            return f"{head} FC{fc:02d} {name} at {address} = {quantity}"
        if fc == 16 and len(pdu) >= 6:
            values = [int.from_bytes(pdu[6 + i:8 + i], "big") for i in range(0, 2 * quantity, 2)]
            return f"{head} FC16 {name} at {address} ×{quantity}: {_short(values)}"
        return f"{head} FC{fc:02d} {name} at {address} ×{quantity}"
    return f"{head} FC{fc:02d} {name}"


def format_trace(entries: list[TraceEntry], *, dropped: int = 0, kind: str = "") -> str:
    """Plain text, one frame a line: time, direction, hex, meaning."""
    lines = [f"# wire trace ({kind or 'unknown'}): {len(entries)} entries"
             + (f", {dropped} older dropped" if dropped else "")]
    for e in entries:
        stamp = time.strftime("%H:%M:%S", time.localtime(e.t)) + f".{int(e.t * 1000) % 1000:03d}"
        arrow = {"tx": "->", "rx": "<-", "call": "=="}[e.direction]
        hexpart = f" {e.hex}" if e.data else ""
        printable = ""
        if e.data and kind in PRINTABLE:
            printable = " " + "".join(chr(b) if 0x20 <= b < 0x7F else "." for b in e.data)
        lines.append(f"{stamp} {arrow}{hexpart}{printable}  | {e.meaning}")
    return "\n".join(lines) + "\n"


__all__ = ["CHAR_BITS", "DESCRIBERS", "PRINTABLE", "TraceEntry", "WireTrace", "describe_modbus", "format_trace"]
