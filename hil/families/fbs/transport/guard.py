"""The FBs family's guarded transport: the guard (:mod:`hil.bench.guard`) over FBs element names, and FATEK
commands 41 (RUN/STOP) and 42 (bit actions) behind it.

The guard's rules (allow-list before a byte is sent, originals journaled, durable first, the clock kept at its
offset, verified restore retried until it succeeds, recovery) are :class:`hil.bench.guard.Guard`'s; this module
gives them the FBs address model: an element is a base :class:`~hil.families.fbs.address.Address` (a bit or a
16-bit word; WM16 covers M16–M31), and its reads are the transport's, where no late or repeated reply is taken for
an answer (README, Safety: which reads are fenced).

Elements the PLC itself rewrites every scan (``volatile``, e.g. the RTC read-out R4128–R4135) are allowed but
not journaled: the clock's own declaration (:meth:`hil.families.fbs.device.rtc.Rtc.clock`) puts it right.
"""

from __future__ import annotations

from typing import Iterable, Sequence

from hil.bench.guard import Guard
from hil.core.errors import TransportError, WriteRefused
from hil.core.journal import Journal
from hil.families.fbs.address import Address, parse, parse_range
from hil.families.fbs.transport.base import NameLike, PlcStatus, Transport


def expand(ranges: Iterable[str]) -> frozenset[Address]:
    """Base elements (bits and 16-bit words) named by ``["R4128-R4135", "M1952", "WM800"]``."""
    out: set[Address] = set()
    for text in ranges:
        for element in parse_range(text):
            out.update(element.elements())
    return frozenset(out)


class GuardedTransport(Guard, Transport):
    #: what a suite may hold of it (hil.bench.view.guarded_io)
    PUBLIC = ("read", "read_words", "read_bits", "read_many", "write", "write_words", "write_bits", "write_many",
              "status", "unreachable_reason", "require", "budget", "set_running", "bit_action", "description",
              "limits", "requests_per_read")

    def __init__(self, inner: Transport, writable: Iterable[str], volatile: Iterable[str] = ()) -> None:
        super().__init__(f"guarded {inner.description}", expand(writable), expand(volatile))
        self.inner = inner
        self.limits = inner.limits
        self.requests_per_read = inner.requests_per_read
        self.emulator = inner.emulator
        self.allow_destructive = False  # FATEK command 41 (RUN/STOP) only with the explicit opt-in
        self.run_original: bool | None = None  # RUN/STOP before a test's first command 41
        self.disabled: set[Address] = set()  # bits a test disabled with command 42: re-enabled on restore

    # -- the guard's address model -------------------------------------------------------------------------------
    def split(self, name: NameLike) -> list[Address]:
        return list(parse(name).elements())

    def read_originals(self, elements: list[Address]) -> list[int]:
        # never a late reply (README, Safety: which reads are fenced); from one scan or not, as frames are cheapest
        return self.inner.read_many(elements, one_scan=False)

    def write_back(self, items: list[tuple[Address, int]]) -> None:
        self.inner.write_many(items, one_scan=False)  # in order; every restore is read back

    # -- FATEK commands 41 and 42, behind the same guard -----------------------------------------------------
    def set_running(self, run: bool) -> None:
        """RUN (True) / STOP (False), command 41: only with destructive actions allowed; restored afterwards."""
        if not self.allow_destructive:
            raise WriteRefused("RUN/STOP (FATEK command 41) refused: it is destructive — pass "
                               "--hil-allow-destructive (or [safety] allow_destructive) on a bench where it may")
        inner_call = getattr(self.inner, "set_running", None)
        if inner_call is None:
            raise WriteRefused(f"RUN/STOP is not offered by {self.inner.description}")
        with self._lock:
            if self.run_original is None:
                self.run_original = bool(self.inner.status().running)
                if self.durable is not None:
                    self.durable.set_extra("run", self.run_original)
            inner_call(bool(run))

    def bit_action(self, name: NameLike, action: int) -> None:
        """Command 42 (1 disable, 2 enable, 3 set, 4 reset) on a writable bit; a disabled bit is re-enabled and
        its value restored when the test ends."""
        inner_call = getattr(self.inner, "bit_action", None)
        if inner_call is None:
            raise WriteRefused(f"bit actions (FATEK command 42) are not offered by {self.inner.description}")

        def act() -> None:
            base = self.split(name)
            if action == 1:
                self.disabled.update(base)
                if self.durable is not None:
                    self.durable.set_extra("disabled", sorted({*self.durable.extra("disabled", []),
                                                               *(str(a) for a in base)}))
            inner_call(base[0], action)
        self.guarded([name], act)

    def _restore_actions(self) -> None:
        """Re-enable the bits a test disabled and put RUN/STOP back (before the values are restored)."""
        if self.disabled:
            for address in sorted(self.disabled, key=str):
                self.inner.bit_action(address, 2)
            self.disabled.clear()
            if self.durable is not None:
                self.durable.set_extra("disabled", [])
        if self.run_original is not None:
            if bool(self.inner.status().running) != self.run_original:
                self.inner.set_running(self.run_original)
            self.run_original = None
            if self.durable is not None:
                self.durable.set_extra("run", None)

    def _adopt(self, journal: Journal) -> None:
        run = journal.extra("run")
        if run is not None and self.run_original is None:
            self.run_original = bool(run)
        self.disabled.update(parse(name) for name in journal.extra("disabled", []))

    # -- writes: check, journal, then pass on --------------------------------------------------------------
    def write_words(self, address: NameLike, values: Sequence[int]) -> None:
        first = parse(address)
        names = [first.offset(i) for i in range(len(values))] if values else []
        self.guarded(names, lambda: super(GuardedTransport, self).write_words(first, values))

    def write_bits(self, address: NameLike, values: Sequence[int | bool]) -> None:
        first = parse(address)
        names = [first.offset(i) for i in range(len(values))] if values else []
        self.guarded(names, lambda: super(GuardedTransport, self).write_bits(first, values))

    def read_many(self, names: Iterable[NameLike], *, one_scan: bool = True) -> list[int]:
        return self.inner.read_many(names, one_scan=one_scan)  # the wire's own frames (FATEK: planned)

    def write_many(self, items, *, one_scan: bool = True) -> None:  # noqa: ANN001 - as Transport.write_many
        pairs = list(items.items()) if hasattr(items, "items") else list(items)
        self.guarded([a for a, _ in pairs], lambda: self.inner.write_many(pairs, one_scan=one_scan))

    # -- primitives: straight to the inner transport ------------------------------------------------------------
    def _count(self, result):  # noqa: ANN001, ANN202 - each request is counted once, where it is sent
        return self.inner._count(result)

    def _read_words(self, first: Address, count: int) -> list[int]:
        return self.inner._read_words(first, count)

    def _write_words(self, first: Address, values: list[int]) -> None:
        self.inner._write_words(first, values)

    def _read_bits(self, first: Address, count: int) -> list[int]:
        return self.inner._read_bits(first, count)

    def _write_bits(self, first: Address, values: list[int]) -> None:
        self.inner._write_bits(first, values)

    def _read_many(self, addresses: list[Address]) -> list[int]:
        return self.inner._read_many(addresses)

    def _write_many(self, items: list[tuple[Address, int]]) -> None:
        self.inner._write_many(items)

    def _status(self) -> PlcStatus:
        return self.inner._status()

    def unreachable_reason(self, address: NameLike) -> str | None:
        return self.inner.unreachable_reason(address)

    def reopen(self) -> None:
        self.inner.reopen()

    def budget(self, write: bool = False) -> float | None:
        return self.inner.budget(write)

    def _close(self) -> None:
        self.inner.close()
