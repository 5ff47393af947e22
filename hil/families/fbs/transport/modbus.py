"""ModbusTransport: an FBs reached over Modbus/TCP or Modbus RTU through the default map, with pymodbus's clients.

Every request is resolved through :mod:`hil.families.fbs.protocol.modbus_map` *before* anything is sent, so an
element the default map cannot reach (D4054, R4168…) raises :class:`~hil.core.errors.UnreachableAddress` instead
of silently reading some other register.  Requests of any shape become contiguous runs per table — coils via FC01/FC15,
holding registers via FC03/FC16 — split at the protocol limits (2000/1968 coils, 125/123 registers).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import TypeVar

from hil.families.fbs.address import Address, parse, span
from hil.families.fbs.protocol import modbus_map as mm
from hil.families.fbs.protocol.modbus_map import COIL, HOLDING, MAX_READ, MAX_WRITE, Run
from hil.families.fbs.transport.base import Limits, NameLike, PlcStatus, Transport, check_value
from hil.io.modbus_client import ModbusWire, OverModbusWire, Probe

#: A cheap read that proves the PLC answers: R4128 (RTC seconds), always mapped; R4128–R4135 are, so a
#: resynchronising read picks its quantity in 1–8.
PROBE = Probe(4128, 8)
_R = TypeVar("_R")


class ModbusTransport(OverModbusWire, Transport):
    """An FBs over Modbus (default map).  Build with :meth:`tcp` or :meth:`rtu`; use as a context manager.

    The requests themselves, with their retry, outcome-unknown and resynchronisation rules, are the shared
    :class:`~hil.io.modbus_client.ModbusWire`'s; this class maps FBs names to its runs.
    """

    # The base class splits read_* and write_* at one size; these are the read limits (FC01/FC03).  Runs are split
    # again at the (smaller) write limits, and Modbus requests are counted one by one by the wire.
    limits = Limits(words=MAX_READ[HOLDING], bits=MAX_READ[COIL], mixed_read_words=MAX_READ[HOLDING],
                    mixed_write_words=MAX_WRITE[HOLDING])

    def __init__(self, wire: ModbusWire) -> None:
        self._use_wire(wire)
        super().__init__(wire.description)

    # -- constructors -----------------------------------------------------------------------------------------
    @classmethod
    def tcp(cls, host: str, port: int = 502, *, unit: int = 1, timeout: float = 1.0,
            retries: int = 2) -> ModbusTransport:
        """Modbus/TCP to ``host:port`` (an FBs Ethernet module serves port 502, at most 8 clients)."""
        hint = (f"is the PLC powered and reachable at {host}:{port} (ping it), does its Ethernet module serve "
                f"Modbus/TCP on that port, and are fewer than 8 clients connected?")
        return cls(ModbusWire.tcp(host, port, unit=unit, timeout=timeout, retries=retries, hint=hint, probe=PROBE,
                                  description=f"modbus+tcp://{host}:{port}?unit={unit}", describe=_names))

    @classmethod
    def rtu(cls, device: str, *, baudrate: int = 9600, parity: str = "E", bytesize: int = 8, stopbits: int = 1,
            unit: int = 1, timeout: float = 1.0, retries: int = 2, fence: str = "trouble") -> ModbusTransport:
        """Modbus RTU on serial ``device`` (a path such as /dev/ttyUSB0 or a pty, or a pyserial URL such as an RFC
        2217 server's ``rfc2217://HOST:PORT``); ``fence="reads"``: the line may repeat replies (every read fenced)."""
        hint = ("The PLC port must be in Modbus RTU slave mode (R4047, e.g. 5502H for port 1; "
                "port 0 never speaks Modbus)")
        return cls(ModbusWire.rtu(device, baudrate=baudrate, parity=parity, bytesize=bytesize, stopbits=stopbits,
                                  unit=unit, timeout=timeout, retries=retries, hint=hint, probe=PROBE,
                                  describe=_names, fence=fence))

    # -- validation before anything is sent --------------------------------------------------------------------
    def unreachable_reason(self, address: NameLike) -> str | None:
        return mm.unreachable_reason(address)

    def read_words(self, address: NameLike, count: int = 1) -> list[int]:
        self._check_run(address, count)
        return super().read_words(address, count)

    def write_words(self, address: NameLike, values: Sequence[int]) -> None:
        # Not the base class's chunking: it splits writes at the read limit (125), and 123 + 2 + … would cost
        # an extra request per chunk; _write_items splits at the FC16/FC15 limits itself.
        self._write_run_of(self._word_address(address), values)

    def read_bits(self, address: NameLike, count: int = 1) -> list[int]:
        self._check_run(address, count)
        return super().read_bits(address, count)

    def write_bits(self, address: NameLike, values: Sequence[int | bool]) -> None:
        self._write_run_of(self._bit_address(address), values)

    def _write_run_of(self, first: Address, values: Sequence[int | bool]) -> None:
        items = [(a, check_value(a, int(v))) for a, v in zip(span(first, len(values)), values)]
        with self._lock:
            self._write_items(items)  # resolves every address before the first request

    def read_many(self, names: Iterable[NameLike], *, one_scan: bool = True) -> list[int]:
        names = list(names)
        for name in names:
            mm.to_modbus(name)
        return super().read_many(names)

    def write_many(self, items: Mapping[NameLike, int] | Iterable[tuple[NameLike, int]], *,
                   one_scan: bool = True) -> None:
        pairs = list(items.items()) if isinstance(items, Mapping) else list(items)
        for name, _ in pairs:
            mm.to_modbus(name)
        super().write_many(pairs)

    @staticmethod
    def _check_run(address: NameLike, count: int) -> None:
        """The base class sends large requests in pieces; refuse the whole request before the first piece."""
        if count >= 1:
            for a in span(parse(address), count):
                mm.to_modbus(a)

    # -- primitives ---------------------------------------------------------------------------------------------
    def _read_words(self, first: Address, count: int) -> list[int]:
        return self._read_addresses(span(first, count))

    def _write_words(self, first: Address, values: list[int]) -> None:
        self._write_items(list(zip(span(first, len(values)), values)))

    _read_bits = _read_words
    _write_bits = _write_words

    def _read_many(self, addresses: list[Address]) -> list[int]:
        return self._read_addresses(addresses)

    def _write_many(self, items: list[tuple[Address, int]]) -> None:
        self._write_items(items)

    def _status(self) -> PlcStatus:
        """Modbus has no status command: RUN/STOP is unknown here (a FATEK target can tell).

        A real read of R4128 (holding 4128, always mapped) proves that the PLC answers, so a status that
        returns means the wire and the unit work.
        """
        (seconds,) = self.wire.read(HOLDING, PROBE.address, 1)
        return PlcStatus(running=None, via="modbus",
                         identity={"transport": self.description, "unit": str(self.unit),
                                   "probe": f"R4128 = {seconds}"})

    def _count(self, result: _R) -> _R:
        return result  # requests are counted per Modbus frame, by the wire

    _count_read = _count  # (so no read is counted towards a settle either: reads_since_write stays 0)

    # -- runs -------------------------------------------------------------------------------------------------
    def _read_addresses(self, addresses: Sequence[Address]) -> list[int]:
        runs = mm.coalesce(addresses, limits=MAX_READ)  # raises UnreachableAddress before any I/O
        values: dict[mm.Unit, int] = {}
        for run in runs:
            for i, value in enumerate(self._read_run(run)):
                values[(run.table, run.pdu + i)] = value
        return [mm.decode(a, values) for a in addresses]

    def _write_items(self, items: Sequence[tuple[Address, int]]) -> None:
        checked = [(a, check_value(a, v)) for a, v in items]
        for run, values in mm.coalesce_writes(checked, limits=MAX_WRITE):  # all resolved before any I/O
            self._write_run(run, values)

    def _read_run(self, run: Run) -> list[int]:
        return self.wire.read(run.table, run.pdu, run.count)

    def _write_run(self, run: Run, values: list[int]) -> None:
        self.wire.write(run.table, run.pdu, values)



def _names(table: str, pdu: int, count: int) -> str:
    """The FBs elements at the ends of a run, for error messages."""
    first = mm.locate(table, pdu)
    last = mm.locate(table, pdu + count - 1)
    a = str(first[0]) if first else "unmapped"
    b = str(last[0]) if last else "unmapped"
    return a if count == 1 or a == b else f"{a}–{b}"


__all__ = ["ModbusTransport"]
