"""The default Modbus map of an FBs main unit, both ways (pure: no I/O).

FBs elements map onto two Modbus tables (see the spec, "Modbus on an FBs PLC (default map)"):

* coils:    Y0–Y255 → 0–255, X0–X255 → 1000–1255, M0–M2001 → 2000–4001, S0–S999 → 6000–6999,
            T0–T255 contacts → 9000–9255, C0–C255 contacts → 9500–9755
* holding:  R0–R4167 → 0–4167, R5000–R5998 → 5000–5998, D0–D2998 → 6000–8998, RT0–RT255 → 9000–9255,
            RC0–RC199 → 9500–9699, DRC200–DRC255 → 9700–9811 (2 registers each, low word first)

Everything else (R4168–R4999, R5999+, D2999+ — so D4053/D4054) has no Modbus address unless the PLC is given a
user map (R3968 = A55AH); asking for it raises :class:`~hil.core.errors.UnreachableAddress` so that nothing ever reads
the wrong register silently.

A "unit" below is one coil or one holding register, written ``(table, pdu)``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from hil.core.errors import AddressError, InvalidValue, UnreachableAddress
from hil.families.fbs.address import LOW_WORD_FIRST, PACKED_16, PACKED_32, PAIRED_32, Address, parse

COIL, HOLDING = "coil", "holding"
TABLES = (COIL, HOLDING)
MAP_NAME = "the default FBs Modbus map"

#: What to do about an element the default map cannot reach.
REMEDY = ("to reach it, configure a Modbus user map on the PLC (R3968 = A55AH, table in R3969–R3980) and use a "
          "transport that knows that map, or use a FATEK target (fatek+tcp://HOST:500 or fatek+serial://DEVICE)")

Unit = tuple[str, int]  # (table, pdu address)


@dataclass(frozen=True)
class ModbusRef:
    """Where an FBs element lives on Modbus: ``count`` consecutive units of ``table`` from ``pdu`` (0-based)."""

    table: str  # "coil" | "holding"
    pdu: int
    count: int = 1

    @property
    def units(self) -> list[Unit]:
        return [(self.table, self.pdu + i) for i in range(self.count)]


@dataclass(frozen=True)
class Run:
    """One contiguous Modbus request's worth: ``count`` units of ``table`` from ``pdu``."""

    table: str
    pdu: int
    count: int

    @property
    def end(self) -> int:
        return self.pdu + self.count

    def __str__(self) -> str:
        return f"{self.table} {self.pdu}" + (f"–{self.end - 1}" if self.count > 1 else "")


@dataclass(frozen=True)
class _Segment:
    """A block of elements of one kind laid out contiguously in one table."""

    table: str
    kind: str
    first: int  # first element index
    last: int  # last element index (inclusive)
    pdu: int  # pdu address of element ``first``
    width: int = 1  # units per element (2 for the 32-bit counters)

    @property
    def pdu_end(self) -> int:
        return self.pdu + (self.last - self.first + 1) * self.width

    def describe(self) -> str:
        return f"{self.kind}{self.first}–{self.kind}{self.last} → {self.table} {self.pdu}–{self.pdu_end - 1}"


SEGMENTS: tuple[_Segment, ...] = (
    _Segment(COIL, "Y", 0, 255, 0),
    _Segment(COIL, "X", 0, 255, 1000),  # X are coils on an FBs, not discrete inputs
    _Segment(COIL, "M", 0, 2001, 2000),
    _Segment(COIL, "S", 0, 999, 6000),
    _Segment(COIL, "T", 0, 255, 9000),
    _Segment(COIL, "C", 0, 255, 9500),
    _Segment(HOLDING, "R", 0, 4167, 0),
    _Segment(HOLDING, "R", 5000, 5998, 5000),
    _Segment(HOLDING, "D", 0, 2998, 6000),
    _Segment(HOLDING, "RT", 0, 255, 9000),
    _Segment(HOLDING, "RC", 0, 199, 9500),
    _Segment(HOLDING, "DRC", 200, 255, 9700, width=2),
)

#: Protocol limits per request (Modbus application protocol, section 6).
MAX_READ = {COIL: 2000, HOLDING: 125}  # FC01, FC03
MAX_WRITE = {COIL: 1968, HOLDING: 123}  # FC15, FC16


def segments(table: str) -> tuple[_Segment, ...]:
    """The mapped blocks of ``table`` in pdu order (for servers that must cover exactly the map)."""
    return _SORTED[_table(table)]


#: the map is fixed: sorted once (a server's request gate walks it on every request)
_SORTED = {table: tuple(sorted((s for s in SEGMENTS if s.table == table), key=lambda s: s.pdu))
           for table in (COIL, HOLDING)}


# -- FBs element → Modbus ----------------------------------------------------------------------------------------
def to_modbus(address: str | Address) -> ModbusRef:
    """Where ``address`` lives in the default map; raises :class:`UnreachableAddress` if it has no Modbus twin."""
    a = parse(address)
    if a.kind in PACKED_16 or a.kind in PACKED_32:
        bank = PACKED_16.get(a.kind) or PACKED_32[a.kind]
        first, last = _element_ref(Address(bank, a.index), a), _element_ref(Address(bank, a.index + a.bits - 1), a)
        if last.pdu - first.pdu != a.bits - 1:  # never for the default map (banks map whole), but stay honest
            raise _unreachable(a, f"its bits {bank}{a.index}–{bank}{a.index + a.bits - 1} are not contiguous coils")
        return ModbusRef(COIL, first.pdu, a.bits)
    if a.kind in PAIRED_32:
        lo, hi = (_element_ref(word, a) for word in a.elements())
        if hi.pdu != lo.pdu + 1:
            raise _unreachable(a, f"its words are not consecutive holding registers; {REMEDY}")
        return ModbusRef(HOLDING, lo.pdu, 2)
    return _element_ref(a, a)


def _element_ref(element: Address, asked: Address) -> ModbusRef:
    for seg in SEGMENTS:
        if seg.kind == element.kind and seg.first <= element.index <= seg.last:
            return ModbusRef(seg.table, seg.pdu + (element.index - seg.first) * seg.width, seg.width)
    raise _unreachable(asked, _why_not(element))


def _why_not(element: Address) -> str:
    covered = [s.describe() for s in SEGMENTS if s.kind == element.kind]
    what = f"{element} has no Modbus address" if element.kind != "R" and element.kind != "D" else \
        f"{element} lies outside the mapped {element.kind} ranges"
    where = f" (the map covers {'; '.join(covered)})" if covered else ""
    return f"{what}{where}; {REMEDY}"


def _unreachable(asked: Address, detail: str) -> UnreachableAddress:
    return UnreachableAddress(str(asked), MAP_NAME, detail)


def unreachable_reason(address: str | Address) -> str | None:
    """Why ``address`` cannot be reached over the default map, or None if it can."""
    try:
        to_modbus(address)
    except UnreachableAddress as exc:
        return str(exc)
    return None


def units(address: str | Address) -> list[Unit]:
    """The coils or registers holding ``address``'s value, least significant first."""
    return to_modbus(address).units


# -- Modbus → FBs element ----------------------------------------------------------------------------------------
def locate(table: str, pdu: int) -> tuple[Address, int] | None:
    """The element at ``(table, pdu)`` and which 16-bit part of it (0 = low, 1 = high word of a DRC), or None."""
    table = _table(table)
    for seg in SEGMENTS:
        if seg.table == table and seg.pdu <= pdu < seg.pdu_end:
            n, part = divmod(pdu - seg.pdu, seg.width)
            return Address(seg.kind, seg.first + n), part
    return None


def from_modbus(table: str, pdu: int) -> Address:
    """The FBs element at ``(table, pdu)``; both registers of a 32-bit counter give its ``DRC`` name."""
    found = locate(table, pdu)
    if found is None:
        covered = "; ".join(s.describe() for s in segments(table))
        raise AddressError(f"{_table(table)} {pdu} is not in {MAP_NAME} (it maps {covered}); "
                           f"a PLC with that address configured needs a user map (R3968 = A55AH)")
    return found[0]


def is_mapped(table: str, pdu: int) -> bool:
    return locate(table, pdu) is not None


def unmapped_in(table: str, pdu: int, count: int) -> int | None:
    """The first address of ``count`` units from ``pdu`` that the map does not cover, or None if all are."""
    at = pdu
    for seg in segments(table):
        if at >= pdu + count:
            return None
        if at < seg.pdu:
            return at
        if at < seg.pdu_end:
            at = seg.pdu_end
    return at if at < pdu + count else None


# -- values ------------------------------------------------------------------------------------------------------
def encode(address: str | Address, value: int) -> list[tuple[Unit, int]]:
    """The unit values that write ``value`` to ``address`` (bits 0/1, registers 0–65535)."""
    ref = to_modbus(address)
    if ref.table == COIL:
        return [(unit, value >> i & 1) for i, unit in enumerate(ref.units)]
    words = [value >> (16 * i) & 0xFFFF for i in range(ref.count)]
    if ref.count == 2 and not LOW_WORD_FIRST:
        words.reverse()
    return list(zip(ref.units, words))


def decode(address: str | Address, values: Mapping[Unit, int]) -> int:
    """``address``'s value from unit values read off the wire (``values`` must hold all its units)."""
    ref = to_modbus(address)
    parts = [int(values[unit]) for unit in ref.units]
    if ref.table == COIL:
        return sum((1 if bit else 0) << i for i, bit in enumerate(parts))
    if ref.count == 2 and not LOW_WORD_FIRST:
        parts.reverse()
    return sum(word << (16 * i) for i, word in enumerate(parts))


# -- coalescing --------------------------------------------------------------------------------------------------
def coalesce(addresses: Iterable[str | Address], *, limits: Mapping[str, int] = MAX_READ) -> list[Run]:
    """Contiguous runs per table covering every unit of ``addresses`` (order not kept; for reads).

    Units shared by several addresses are read once; a run never exceeds ``limits[table]`` units. Raises
    :class:`UnreachableAddress` for the first unmapped address, before the caller sends anything.
    """
    wanted: dict[str, set[int]] = {COIL: set(), HOLDING: set()}
    for address in addresses:
        ref = to_modbus(address)
        wanted[ref.table].update(range(ref.pdu, ref.pdu + ref.count))
    runs: list[Run] = []
    for table in TABLES:
        runs += _runs_of(table, sorted(wanted[table]), limits[table])
    return runs


def _runs_of(table: str, pdus: list[int], limit: int) -> list[Run]:
    runs: list[Run] = []
    for pdu in pdus:
        if runs and pdu == runs[-1].end and runs[-1].count < limit:  # the next unit, and the request has room
            runs[-1] = Run(table, runs[-1].pdu, runs[-1].count + 1)
        else:
            runs.append(Run(table, pdu, 1))
    return runs


def coalesce_writes(items: Iterable[tuple[str | Address, int]], *,
                    limits: Mapping[str, int] = MAX_WRITE) -> list[tuple[Run, list[int]]]:
    """Runs with their unit values for writing ``items`` in the order given.

    Consecutive items whose units continue the current run (same table, next address up) share one request;
    anything else starts a new one, so the PLC sees the writes in the caller's order (a trigger bit written
    after its parameters still lands after them).
    """
    out: list[tuple[Run, list[int]]] = []
    for address, value in items:
        for (table, pdu), unit_value in encode(address, value):
            if out:
                run, values = out[-1]
                if run.table == table and run.end == pdu and run.count < limits[table]:
                    values.append(unit_value)
                    out[-1] = (Run(table, run.pdu, run.count + 1), values)
                    continue
            out.append((Run(table, pdu, 1), [unit_value]))
    return out


def _table(table: str) -> str:
    name = table.lower().rstrip("s")
    if name in ("coil", "holding", "holding register"):
        return COIL if name == "coil" else HOLDING
    raise InvalidValue(f"unknown Modbus table {table!r}: the FBs default map uses 'coil' and 'holding'")


__all__ = ["ModbusRef", "Run", "to_modbus", "from_modbus", "locate", "units", "encode", "decode", "coalesce",
           "coalesce_writes", "unreachable_reason", "unmapped_in", "is_mapped", "segments", "SEGMENTS",
           "MAX_READ", "MAX_WRITE", "COIL", "HOLDING", "MAP_NAME", "REMEDY"]
