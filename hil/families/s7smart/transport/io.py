"""How the harness reaches an S7-200 SMART's memory: V bytes, and Q/I bits — in process, or over Modbus.

Why not :class:`hil.families.fbs.transport.base.Transport`: that API is keyed by FBs element names all the way down
(parse, value checks, request splitting, the guard's allow-list and the Modbus map decode FBs names), and S7 operands
(VB110, V100.0) would have to bend every one of them.  This layer is the S7 counterpart, deliberately small: byte-run
primitives plus name helpers, with the same error types, the same guard (:class:`hil.bench.guard.Guard`, given the S7
address model here) and the same "an address the wire cannot reach is an error naming both" rule.  Over Modbus it maps
operands to register/coil runs through :class:`~hil.families.s7smart.protocol.modbus_map.S7ModbusMap` and sends them
through the one Modbus client, :class:`~hil.io.modbus_client.ModbusWire`.

Over Modbus, V is reached in 16-bit holding registers: writing one byte (or one V bit) reads the register and
writes it back whole, so the other byte of that word must not be something the PLC program writes meanwhile —
keep trigger bits in a word of their own (the shipped layouts do).
"""

from __future__ import annotations

import datetime as dt
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING, Protocol, TypeVar, runtime_checkable

from hil.bench.guard import GuardedLink
from hil.core.errors import InvalidValue, TransportError
from hil.core.link import Link
from hil.families.s7smart.address import S7Address, expand_s7, parse_s7, units
from hil.families.s7smart.faces import S7IO
from hil.families.s7smart.protocol.modbus_map import (
    MAX_READ_BITS,
    MAX_READ_REGISTERS,
    MAX_WRITE_REGISTERS,
    S7ModbusMap,
    from_words,
    to_words,
)
from hil.io.modbus_client import COILS, DISCRETE_INPUTS, HOLDING, ModbusWire, OverModbusWire, Probe
from hil.io.status import PlcStatus

if TYPE_CHECKING:
    from hil.families.s7smart.sim.cpu import S7Emulator
    from hil.families.s7smart.sim.memory import S7Memory

T = TypeVar("T")  # what a request run in the emulator returns
#: the MBUS_SLAVE library's defaults (HoldStart VB0, MaxHold 1000 …): a profile's [s7] says otherwise
DEFAULT_MAP = S7ModbusMap()


class S7Io(Link, ABC):
    """Base: name helpers over four primitives.  One request on the wire at a time (a lock)."""

    emulator: S7Emulator | None = None

    # -- public API ---------------------------------------------------------------------------------------------
    def read_v(self, first: int, count: int) -> bytes:
        with self._lock:
            return self._read_v(first, count)

    def write_v(self, first: int, data: bytes | Sequence[int]) -> None:
        data = bytes(data)
        with self._lock:
            self._write_v(first, data)

    def read(self, name: str | S7Address) -> int:
        """One operand: a bit (0/1), VB, VW (unsigned, big-endian) or VD; Q/I bits."""
        a = parse_s7(name)
        with self._lock:
            if a.area in ("Q", "I") and a.is_bit:
                return self._read_bits(a.area, a.byte * 8 + a.bit_in_byte, 1)[0]
            if a.area != "V":
                raise InvalidValue(f"{a}: only V memory and Q/I bits are reachable")
            raw = self._read_v(a.byte, a.size)
            return raw[0] >> a.bit_in_byte & 1 if a.is_bit else int.from_bytes(raw, "big")

    def write(self, name: str | S7Address, value: int) -> None:
        a = parse_s7(name)
        value = int(value)
        top = 1 if a.is_bit else (1 << 8 * a.size) - 1
        if not 0 <= value <= top:
            raise InvalidValue(f"value {value} for {a} is outside 0–{top}")
        with self._lock:
            if a.area == "Q" and a.is_bit:
                self._write_bits("Q", a.byte * 8 + a.bit_in_byte, [value])
            elif a.area != "V":
                raise InvalidValue(f"{a}: only V memory and Q bits are writable")
            elif a.is_bit:  # read-modify-write of the byte: S7 memory has no single-bit write over these wires
                old = self._read_v(a.byte, 1)[0]
                mask = 1 << a.bit_in_byte
                self._write_v(a.byte, bytes([old | mask if value else old & ~mask]))
            else:
                self._write_v(a.byte, value.to_bytes(a.size, "big"))

    def read_bits(self, name: str | S7Address, count: int = 1) -> list[int]:
        a = parse_s7(name)
        if not a.is_bit or a.area not in ("Q", "I"):
            raise InvalidValue(f"{a}: read_bits reads Q or I bits")
        with self._lock:
            return self._read_bits(a.area, a.byte * 8 + a.bit_in_byte, count)

    def status(self) -> PlcStatus:
        with self._lock:
            return self._status()

    def unreachable_reason(self, name: str | S7Address) -> str | None:
        parse_s7(name)
        return None

    def budget(self, write: bool = False) -> float | None:
        """The longest one request may take, retries included (seconds), or None when unbounded."""
        return None

    # -- primitives ---------------------------------------------------------------------------------------------
    @abstractmethod
    def _read_v(self, first: int, count: int) -> bytes: ...

    @abstractmethod
    def _write_v(self, first: int, data: bytes) -> None: ...

    @abstractmethod
    def _read_bits(self, area: str, first: int, count: int) -> list[int]: ...

    @abstractmethod
    def _write_bits(self, area: str, first: int, values: list[int]) -> None: ...

    @abstractmethod
    def _status(self) -> PlcStatus: ...


@runtime_checkable
class ClockedS7Io(Protocol):
    """A link with the S7 protocol's clock functions (:class:`~hil.families.s7smart.transport.s7wire.SnapS7Io`)."""

    description: str

    def cpu_clock(self) -> dt.datetime: ...

    def set_cpu_clock(self, when: dt.datetime) -> None: ...


# -- in process -----------------------------------------------------------------------------------------------------
class LocalS7Io(S7Io):
    """Direct calls into an in-process S7 emulator, each serviced at a scan boundary."""

    emulator: S7Emulator  # (always one, in process)

    def __init__(self, emulator: S7Emulator) -> None:
        super().__init__("s7-200smart emulator (in-process)")
        self.emulator = emulator

    def _service(self, request: Callable[[S7Memory], T]) -> T:
        self.requests += 1
        return self.emulator.service(request)

    def _read_v(self, first: int, count: int) -> bytes:
        return self._service(lambda mem: mem.read_bytes("V", first, count))

    def _write_v(self, first: int, data: bytes) -> None:
        self._service(lambda mem: mem.write_bytes("V", first, data))

    def _read_bits(self, area: str, first: int, count: int) -> list[int]:
        return self._service(lambda mem: [mem.areas[area][n // 8] >> n % 8 & 1 for n in range(first, first + count)])

    def _write_bits(self, area: str, first: int, values: list[int]) -> None:
        def apply(mem: S7Memory) -> None:
            for n, v in enumerate(values, first):
                mem.set(S7Address(area, n // 8, n % 8), v)
        self._service(apply)

    def _status(self) -> PlcStatus:
        emu = self.emulator
        running = self._service(lambda mem: emu.running)
        return PlcStatus(running=running, flags=["RUN"] if running else [], via="in-process",
                         identity={"unit": "emulator", "version": emu.version, "cpu": emu.cpu})


# -- over Modbus ----------------------------------------------------------------------------------------------------
class ModbusS7Io(OverModbusWire, S7Io):
    """An S7-200 SMART running the MBUS_SLAVE library, over Modbus/TCP or RTU.

    The requests, with their retry, outcome-unknown and resynchronisation rules, are the shared
    :class:`~hil.io.modbus_client.ModbusWire`'s (the same as an FBs's); this class maps S7 operands to its runs.
    """

    def __init__(self, wire: ModbusWire, modbus_map: S7ModbusMap) -> None:
        self._use_wire(wire)
        super().__init__(wire.description)
        self.map = modbus_map

    @classmethod
    def tcp(cls, host: str, port: int = 502, *, unit: int = 1, timeout: float = 1.0, retries: int = 2,
            modbus_map: S7ModbusMap = DEFAULT_MAP) -> ModbusS7Io:
        hint = (f"is the CPU reachable at {host}:{port}, and does its program call MBUS_SLAVE (Modbus TCP server "
                f"instruction) with this unit id and HoldStart/MaxHold matching the profile's [s7]?")
        description = f"modbus+tcp://{host}:{port}?unit={unit} (S7-200 SMART map, HoldStart VB{modbus_map.hold_start})"
        return cls(ModbusWire.tcp(host, port, unit=unit, timeout=timeout, retries=retries, hint=hint,
                                  probe=_probe(modbus_map), description=description, describe=_names(modbus_map)),
                   modbus_map)

    @classmethod
    def rtu(cls, device: str, *, baudrate: int = 9600, parity: str = "E", bytesize: int = 8, stopbits: int = 1,
            unit: int = 1, timeout: float = 1.0, retries: int = 2, fence: str = "trouble",
            modbus_map: S7ModbusMap = DEFAULT_MAP) -> ModbusS7Io:
        hint = "Is the CPU's RS485 port running MBUS_SLAVE (MBUS_INIT) at these settings?"
        return cls(ModbusWire.rtu(device, baudrate=baudrate, parity=parity, bytesize=bytesize, stopbits=stopbits,
                                  unit=unit, timeout=timeout, retries=retries, hint=hint, probe=_probe(modbus_map),
                                  label="S7-200 SMART map", describe=_names(modbus_map), fence=fence),
                   modbus_map)

    def unreachable_reason(self, name: str | S7Address) -> str | None:
        a = parse_s7(name)
        try:
            if a.area == "V":
                self.map.registers_for(a.byte, a.size)
            elif a.area in ("Q", "I") and a.is_bit:
                self.map.bit_number(a)
            else:
                return f"{a} is not in the S7-200 SMART Modbus map"
        except (ValueError, TransportError) as exc:
            return str(exc)
        return None

    def _read_v(self, first: int, count: int) -> bytes:
        lo, n = self.map.registers_for(first, count)  # raises UnreachableAddress before any I/O
        words: list[int] = []
        for start in range(lo, lo + n, MAX_READ_REGISTERS):
            words += self.wire.read(HOLDING, start, min(MAX_READ_REGISTERS, lo + n - start))
        data = from_words(words)
        skip = first - self.map.v_byte(lo)
        return data[skip:skip + count]

    def _write_v(self, first: int, data: bytes) -> None:
        if not data:
            return
        lo, n = self.map.registers_for(first, len(data))
        start_byte = self.map.v_byte(lo)
        whole = bytearray(2 * n)
        if start_byte != first or (first + len(data)) != start_byte + 2 * n:  # partial words: keep the other byte
            whole[:] = self._read_v(start_byte, 2 * n)
        whole[first - start_byte:first - start_byte + len(data)] = data
        words = to_words(bytes(whole))
        for i in range(0, n, MAX_WRITE_REGISTERS):
            self.wire.write(HOLDING, lo + i, words[i:i + MAX_WRITE_REGISTERS])

    def _read_bits(self, area: str, first: int, count: int) -> list[int]:
        self.map.bit_number(S7Address(area, (first + count - 1) // 8, (first + count - 1) % 8))
        if count > MAX_READ_BITS:
            raise InvalidValue(f"at most {MAX_READ_BITS} bits per read")
        return self.wire.read(COILS if area == "Q" else DISCRETE_INPUTS, first, count)

    def _write_bits(self, area: str, first: int, values: list[int]) -> None:
        if area != "Q":
            raise InvalidValue("only Q bits (coils) are writable over Modbus")
        self.map.bit_number(S7Address("Q", (first + len(values) - 1) // 8, (first + len(values) - 1) % 8))
        self.wire.write(COILS, first, values)

    def _status(self) -> PlcStatus:
        """Modbus has no status request: a one-register read proves the CPU answers; RUN/STOP stays unknown."""
        (word,) = to_words(self._read_v(self.map.hold_start, 2))
        return PlcStatus(running=None, via="modbus", identity={
            "transport": self.description, "unit": str(self.unit), "probe": f"VW{self.map.hold_start} = {word}"})



def _probe(modbus_map: S7ModbusMap) -> Probe:
    """VW(HoldStart) onwards: a resynchronising read picks its quantity in 1–8 (fewer if MaxHold is smaller)."""
    return Probe(0, max(1, min(8, modbus_map.max_hold)))


def _names(modbus_map: S7ModbusMap):  # noqa: ANN202 - a hil.io.modbus_client.Describe
    def describe(table: str, address: int, count: int) -> str:
        if table == HOLDING:
            first, last = modbus_map.v_byte(address), modbus_map.v_byte(address + count - 1) + 1
            return f"VB{first}–VB{last}"
        area = "Q" if table == COILS else "I"
        end = address + count - 1
        return f"{area}{address // 8}.{address % 8}" + (f"–{area}{end // 8}.{end % 8}" if count > 1 else "")
    return describe


# -- the guard ------------------------------------------------------------------------------------------------------
class GuardedS7Io(GuardedLink):
    """The guard (:mod:`hil.bench.guard`) over S7 operands: every write checked against the profile's ``[safety]
    writable`` (S7 ranges) before a byte is sent, originals journaled (on disk first on a real bench) and
    restored, read back, after each test; the CPU clock kept as the family declares it
    (:meth:`hil.families.s7smart.device.plc.S7Plc.clock`)."""

    #: what a suite may hold of it (hil.bench.view.guarded_io)
    FACE = S7IO

    inner: S7Io

    def __init__(self, inner: S7Io, writable: Iterable[str]) -> None:
        super().__init__(inner, expand_s7(writable))

    # -- the guard's address model: bytes, and Q/I bits ---------------------------------------------------------
    def split(self, name: str | S7Address) -> list[S7Address]:
        return units(parse_s7(name))

    def keys(self, elements: list[S7Address]) -> list[S7Address]:
        """A V bit is written as its whole byte (read, change, write back): journal the byte."""
        return [S7Address("V", e.byte) if e.area == "V" else e for e in elements]

    def read_originals(self, elements: list[S7Address]) -> list[int]:
        v: dict[int, int] = {}
        for first, count in _runs(sorted({e.byte for e in elements if e.area == "V"})):
            v.update(enumerate(self.inner.read_v(first, count), first))
        return [(v[e.byte] >> e.bit_in_byte & 1 if e.is_bit else v[e.byte]) if e.area == "V"
                else self.inner.read(e) for e in elements]

    def write_back(self, items: list[tuple[S7Address, int]]) -> None:
        v = {e.byte: value for e, value in items if e.area == "V" and not e.is_bit}
        for first, count in _runs(sorted(v)):
            self.inner.write_v(first, bytes(v[b] for b in range(first, first + count)))
        for e, value in items:
            if e.area != "V" or e.is_bit:
                self.inner.write(e, value)

    def value_problem(self, element: S7Address, value: int) -> str | None:
        top = 1 if element.is_bit else 0xFF  # the guard's elements: bits and bytes
        return None if 0 <= value <= top else f"value {value} for {element} is outside 0–{top}"

    # -- writes: check, journal, then pass on --------------------------------------------------------------------
    def write_v(self, first: int, data: bytes | Sequence[int]) -> None:
        data = bytes(data)
        names = [S7Address("V", b) for b in range(first, first + len(data))]
        self.guarded(names, lambda: self.inner.write_v(first, data), dict(zip(names, data)))

    def write(self, name: str | S7Address, value: int) -> None:
        a = parse_s7(name)
        # what each journaled element will hold (big-endian bytes; a Q bit itself); a V bit changes its byte by a
        # read-modify-write, so that byte's new value is not known here
        wrote = ({a: int(value) & 1} if a.is_bit and a.area != "V" else {} if a.is_bit else
                 dict(zip(units(a), int(value).to_bytes(a.size, "big"))) if 0 <= int(value) < 1 << 8 * a.size else {})
        self.guarded([a], lambda: self.inner.write(a, value), wrote)

    # -- the CPU's own clock (a wire that has clock functions: the S7 protocol) ------------------------------
    @property
    def has_cpu_clock(self) -> bool:
        return isinstance(self.inner, ClockedS7Io)

    def cpu_clock(self) -> dt.datetime:
        return self._clocked().cpu_clock()

    def set_cpu_clock(self, when: dt.datetime) -> None:
        """Set the clock with the protocol's function, its time journaled first (the restore keeps its offset)."""
        clocked = self._clocked()
        self.setting_clock(lambda: clocked.set_cpu_clock(when))

    def _clocked(self) -> ClockedS7Io:
        if not isinstance(self.inner, ClockedS7Io):
            raise TransportError(f"{self.inner.description} has no clock functions (the S7 protocol has them)")
        return self.inner

    # -- reads: straight through (writes above are the only way in) -------------------------------------------
    def read_v(self, first: int, count: int) -> bytes:
        return self.inner.read_v(first, count)

    def read(self, name: str | S7Address) -> int:
        return self.inner.read(name)

    def read_bits(self, name: str | S7Address, count: int = 1) -> list[int]:
        return self.inner.read_bits(name, count)


def _runs(numbers: list[int]) -> list[tuple[int, int]]:
    """Sorted byte numbers as (first, count) runs of consecutive ones: one request each."""
    runs: list[tuple[int, int]] = []
    for n in numbers:
        if runs and runs[-1][0] + runs[-1][1] == n:
            runs[-1] = (runs[-1][0], runs[-1][1] + 1)
        else:
            runs.append((n, 1))
    return runs
