"""The FBs family's guarded transport: the guard (:mod:`hil.bench.guard`) over FBs element names, and FATEK
commands 41 (RUN/STOP) and 42 (bit actions) behind it (:mod:`hil.families.fbs.transport.guard_commands`).

The guard's rules (allow-list before a byte is sent, originals journaled, durable first, the clock kept at its
offset, verified restore retried until it succeeds, recovery) are :class:`hil.bench.guard.Guard`'s; this module
gives them the FBs address model: an element is a base :class:`~hil.families.fbs.address.Address` (a bit or a
16-bit word; WM16 covers M16–M31), and its reads are the transport's, where no late or repeated reply is taken for
an answer (docs/safety.md: which reads are fenced).

Elements the PLC itself rewrites every scan (``volatile``, e.g. the RTC read-out R4128–R4135) are allowed but
not journaled: the clock's own declaration (:meth:`hil.families.fbs.device.rtc.Rtc.clock`) puts it right.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

from hil.core.errors import HilError
from hil.families.fbs.address import LOW_WORD_FIRST, PAIRED_32, Address, expand, parse
from hil.families.fbs.faces import FbsIO
from hil.families.fbs.transport.base import NameLike, Transport, check_value, value_problem
from hil.families.fbs.transport.guard_commands import FatekCommandsGuard


def element_values(pairs: Iterable[tuple[Address, int]]) -> dict[Address, int]:
    """What a write of (address, value) pairs leaves in each base element (WM16 → M16…M31, DR0 → R0, R1), for the
    journal's "wrote"; a value that does not fit is left out (the write itself refuses it)."""
    out: dict[Address, int] = {}
    for address, value in pairs:
        try:
            value = check_value(address, int(value))
        except (HilError, TypeError, ValueError):
            continue
        parts = list(address.elements())
        if len(parts) == 1:
            out[parts[0]] = value
        elif address.kind in PAIRED_32:
            lo, hi = value & 0xFFFF, value >> 16
            out[parts[0]], out[parts[1]] = (lo, hi) if LOW_WORD_FIRST else (hi, lo)
        else:  # packed bits, lowest first
            out.update({bit: value >> i & 1 for i, bit in enumerate(parts)})
    return out


class GuardedTransport(FatekCommandsGuard):
    """The guard round an FBs transport, through the transport's public API: reads pass straight through (its
    own frames, fenced where the wire needs it), writes are checked and journaled first; FATEK commands 41 and 42
    as :class:`~hil.families.fbs.transport.guard_commands.FatekCommandsGuard` guards them."""

    #: what a suite may hold of it (hil.bench.view.guarded_io)
    FACE = FbsIO

    read_effects_first = True  # a FATEK range read costs what the range write does: FUN86's outputs read first
    inner: Transport

    def __init__(self, inner: Transport, writable: Iterable[str], volatile: Iterable[str] = ()) -> None:
        super().__init__(inner, expand(writable), expand(volatile))

    # -- the guard's address model -------------------------------------------------------------------------------
    def split(self, name: NameLike) -> list[Address]:
        return list(parse(name).elements())

    def read_originals(self, elements: list[Address]) -> list[int]:
        # never a late reply (docs/safety.md: which reads are fenced); from one scan or not, as frames are cheapest
        return self.inner.read_many(elements, one_scan=False)

    def write_back(self, items: list[tuple[Address, int]]) -> None:
        self.inner.write_many(items, one_scan=False)  # in order; every restore is read back

    def _read_first(self, items: list[tuple[Address, int]]) -> set:
        """Besides FUN86's side effects, each run of adjacent elements the test last wrote back to their originals
        (a block of Ki = 0 over Ki = 0), causes of side effects apart: read, and written only where they differ —
        the PLC may have changed them since, the read says.  Whole runs only: one left out of the middle of a run
        would split its write frame."""
        checked = super()._read_first(items)
        # never a cause of side effects (an EN, FUN86's Sn/Zn registers): those go back first, always, so that
        # what they make the PLC rewrite is read only once they are undone (even after a write of unknown outcome)
        same = {a for a, v in items if a in self.last_wrote and self.last_wrote[a] == v
                and not self.causes_side_effects(a)}
        rest = sorted((a for a, _ in items if a not in checked), key=lambda a: (a.kind, a.index))
        run: list[Address] = []
        for address in [*rest, None]:
            if address is not None and run and run[-1].kind == address.kind and run[-1].index + 1 == address.index:
                run.append(address)
                continue
            if run and all(a in same for a in run):
                checked |= set(run)
            run = [address] if address is not None else []
        return checked

    def value_problem(self, element: Address, value: int) -> str | None:
        return value_problem(element, value)

    # -- reads: straight through ----------------------------------------------------------------------------
    limits = property(lambda self: self.inner.limits)
    requests_per_read = property(lambda self: self.inner.requests_per_read)
    reads_since_write = property(lambda self: self.inner.reads_since_write)

    def read(self, name: NameLike) -> int:
        return self.inner.read(name)

    def read_words(self, address: NameLike, count: int = 1) -> list[int]:
        return self.inner.read_words(address, count)

    def read_bits(self, address: NameLike, count: int = 1) -> list[int]:
        return self.inner.read_bits(address, count)

    def read_many(self, names: Iterable[NameLike], *, one_scan: bool = True) -> list[int]:
        return self.inner.read_many(names, one_scan=one_scan)  # the wire's own frames (FATEK: planned)

    def require(self, names: Iterable[NameLike], action: str, error: type[Exception] | None = None) -> None:
        self.inner.require(names, action, error)

    # -- writes: check, journal, then pass on --------------------------------------------------------------
    def write(self, name: NameLike, value: int) -> None:
        address = parse(name)
        (self.write_bits if address.is_bit else self.write_words)(address, [value])

    def write_words(self, address: NameLike, values: Sequence[int]) -> None:
        first = parse(address)
        names = [first.offset(i) for i in range(len(values))] if values else []
        self.guarded(names, lambda: self.inner.write_words(first, values), element_values(zip(names, values)))

    def write_bits(self, address: NameLike, values: Sequence[int | bool]) -> None:
        first = parse(address)
        names = [first.offset(i) for i in range(len(values))] if values else []
        self.guarded(names, lambda: self.inner.write_bits(first, values), element_values(zip(names, values)))

    def write_many(self, items: Mapping[NameLike, int] | Iterable[tuple[NameLike, int]], *,
                   one_scan: bool = True) -> None:
        pairs = list(items.items()) if isinstance(items, Mapping) else list(items)
        self.guarded([a for a, _ in pairs], lambda: self.inner.write_many(pairs, one_scan=one_scan),
                     element_values((parse(a), v) for a, v in pairs))
