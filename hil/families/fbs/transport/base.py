"""The one transport abstraction: read/write words and bits, mixed reads/writes, status — whatever the wire.

Subclasses implement small primitives that move at most one protocol request's worth; this base class parses
and validates names, checks values before anything is sent, splits large requests at the protocol's limits and
serialises requests with a lock (one request on the wire at a time, as a serial line demands).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypeVar

from hil.core.errors import HilError, InvalidValue
from hil.core.link import Link
from hil.families.fbs.address import Address, parse, span
from hil.io.status import PlcStatus

if TYPE_CHECKING:
    from hil.families.fbs.sim.plc import Emulator
    from hil.sim.runtime import ServerHandle

NameLike = str | Address
_R = TypeVar("_R")


@dataclass(frozen=True)
class Limits:
    """Largest single request, in the units the protocol counts."""

    words: int = 64  # 16-bit registers per read/write request
    bits: int = 256
    mixed_read_words: int = 64  # bit = 1, 16-bit = 1, 32-bit = 2
    mixed_write_words: int = 32


def check_value(address: Address, value: int) -> int:
    """Reject a value that does not fit the element before any byte is sent."""
    value = int(value)
    top = 1 if address.is_bit else (1 << address.bits) - 1
    if not 0 <= value <= top:
        kind = "0 or 1" if address.is_bit else f"0–{top} (unsigned {address.bits}-bit)"
        raise InvalidValue(f"value {value} for {address} is outside {kind}")
    return value


def value_problem(address: Address, value: int) -> str | None:
    """Why ``value`` cannot be ``address``'s (None when it can): :func:`check_value` as a verdict."""
    try:
        check_value(address, value)
    except InvalidValue as exc:
        return str(exc)
    return None


def _chunks(count: int, size: int) -> Iterable[tuple[int, int]]:
    for start in range(0, count, size):
        yield start, min(size, count - start)


class Transport(Link, ABC):
    """Base of every transport.  Use it as a context manager, or call :meth:`close`."""

    limits = Limits()
    #: The in-process emulator behind an ``emulator…`` target, else None.
    emulator: Emulator | None = None
    #: The emulator's server this transport talks to (an ``emulator+<wire>`` target), else None.
    server: ServerHandle | None = None
    #: Reads answered since this link's last request that may have changed the PLC (a write, or any request not
    #: known to be a read): on a port that answers at a scan's end each spans a scan, so a settle counts them
    #: (:meth:`hil.families.fbs.device.core.PlcCore.settle`).  Only what is counted as a read adds to it: a
    #: request counted otherwise starts it again, so a wire that counts nothing leaves it at 0.
    reads_since_write = 0

    @property
    def requests_per_read(self) -> int:
        """Requests one read takes: 2 where every read is fenced by a second one (a line without transaction ids
        that may repeat a reply, docs/safety.md).  Port 0 services each at the end of a scan: suites that bracket
        scans count with it."""
        return 1

    # -- public API -------------------------------------------------------------------------------------------
    def read_words(self, address: NameLike, count: int = 1) -> list[int]:
        """``count`` consecutive 16-bit (or 32-bit for DR/DD/…) values from ``address``."""
        first = self._word_address(address)
        span(first, count)
        per = max(1, self.limits.words // first.words)
        out: list[int] = []
        with self._lock:
            for start, n in _chunks(count, per):
                out += self._count_read(self._read_words(first.offset(start) if start else first, n))
        return out

    def write_words(self, address: NameLike, values: Sequence[int]) -> None:
        first = self._word_address(address)
        values = list(values)
        span(first, len(values))
        for i, v in enumerate(values):
            values[i] = check_value(first, v)
        per = max(1, self.limits.words // first.words)
        with self._lock:
            for start, n in _chunks(len(values), per):
                self._count(self._write_words(first.offset(start) if start else first, values[start:start + n]))

    def read_bits(self, address: NameLike, count: int = 1) -> list[int]:
        first = self._bit_address(address)
        span(first, count)
        out: list[int] = []
        with self._lock:
            for start, n in _chunks(count, self.limits.bits):
                out += [int(b) for b in self._count_read(self._read_bits(first.offset(start) if start else first, n))]
        return out

    def write_bits(self, address: NameLike, values: Sequence[int | bool]) -> None:
        first = self._bit_address(address)
        values = [check_value(first, int(v)) for v in values]
        span(first, len(values))
        with self._lock:
            for start, n in _chunks(len(values), self.limits.bits):
                self._count(self._write_bits(first.offset(start) if start else first, values[start:start + n]))

    def read_many(self, names: Iterable[NameLike], *, one_scan: bool = True) -> list[int]:
        """Read named elements of any kinds, in order (bits as 0/1).  ``one_scan`` False: the caller does not need
        them from one scan (the guard's originals and read-backs), so a transport may use more, cheaper frames."""
        addresses = [parse(n) for n in names]
        out: list[int] = []
        with self._lock:
            for group in word_groups(addresses, self.limits.mixed_read_words):
                out += self._count_read(self._read_many(group))
        return out

    def write_many(self, items: Mapping[NameLike, int] | Iterable[tuple[NameLike, int]], *,
                   one_scan: bool = True) -> None:
        """Write named elements of any kinds, in the order given (``one_scan``: as for :meth:`read_many`)."""
        pairs = list(items.items()) if isinstance(items, Mapping) else list(items)
        checked = [(address, check_value(address, v)) for address, v in ((parse(a), v) for a, v in pairs)]
        with self._lock:
            for group in word_groups(checked, self.limits.mixed_write_words, key=lambda item: item[0]):
                self._count(self._write_many(group))

    def read(self, name: NameLike) -> int:
        """One element of any kind."""
        address = parse(name)
        return self.read_bits(address)[0] if address.is_bit else self.read_words(address)[0]

    def write(self, name: NameLike, value: int) -> None:
        address = parse(name)
        if address.is_bit:
            self.write_bits(address, [value])
        else:
            self.write_words(address, [value])

    def status(self) -> PlcStatus:
        with self._lock:
            return self._count_read(self._status())

    def unreachable_reason(self, address: NameLike) -> str | None:
        """Why this transport cannot reach ``address`` (e.g. D4054 over the default Modbus map), or None."""
        parse(address)
        return None

    def require(self, names: Iterable[NameLike], action: str, error: type[Exception] | None = None) -> None:
        """Refuse ``action`` before anything is sent when this wire cannot reach one of ``names`` — so that a
        procedure never stops half-way (M1952 stranded at 1) on an address the wire could never reach."""
        for name in names:
            reason = self.unreachable_reason(name)
            if reason:
                raise (error or HilError)(f"cannot {action}: {reason} (nothing was written)")

    def budget(self, write: bool = False) -> float | None:
        """The longest one protocol request may take (retries, backoff, resynchronising included), or None."""
        return None

    # -- what a subclass provides ---------------------------------------------------------------------------
    @abstractmethod
    def _read_words(self, first: Address, count: int) -> list[int]: ...

    @abstractmethod
    def _write_words(self, first: Address, values: list[int]) -> None: ...

    @abstractmethod
    def _read_bits(self, first: Address, count: int) -> list[int]: ...

    @abstractmethod
    def _write_bits(self, first: Address, values: list[int]) -> None: ...

    @abstractmethod
    def _read_many(self, addresses: list[Address]) -> list[int]: ...

    @abstractmethod
    def _write_many(self, items: list[tuple[Address, int]]) -> None: ...

    @abstractmethod
    def _status(self) -> PlcStatus: ...

    # -- helpers ------------------------------------------------------------------------------------------------
    def _count(self, result: _R) -> _R:
        """Count one request sent that may have changed the PLC, passing its primitive's result through."""
        self.requests += 1
        self.reads_since_write = 0
        return result

    def _count_read(self, result: _R) -> _R:
        """Count one read sent (it changes nothing on the PLC), passing its primitive's result through."""
        self.requests += 1
        self.reads_since_write += 1
        return result

    @staticmethod
    def _word_address(name: NameLike) -> Address:
        address = parse(name)
        if address.is_bit:
            raise InvalidValue(f"{address} is a bit; use read_bits/write_bits (or a W… name such as WM800)")
        return address

    @staticmethod
    def _bit_address(name: NameLike) -> Address:
        address = parse(name)
        if not address.is_bit:
            raise InvalidValue(f"{address} is a register; use read_words/write_words")
        return address


def word_groups(items: list, budget: int, key: Callable = lambda a: a) -> Iterable[list]:
    """Split items into runs whose word cost (bit = 1, 16-bit = 1, 32-bit = 2) fits ``budget``."""
    group: list = []
    cost = 0
    for item in items:
        words = key(item).words
        if group and cost + words > budget:
            yield group
            group, cost = [], 0
        group.append(item)
        cost += words
    if group:
        yield group
