"""The FBs family's guarded transport: the guard (:mod:`hil.bench.guard`) over FBs element names, and FATEK
commands 41 (RUN/STOP) and 42 (bit actions) behind it.

The guard's rules (allow-list before a byte is sent, originals journaled, durable first, the clock kept at its
offset, verified restore retried until it succeeds, recovery) are :class:`hil.bench.guard.Guard`'s; this module
gives them the FBs address model: an element is a base :class:`~hil.families.fbs.address.Address` (a bit or a
16-bit word; WM16 covers M16–M31), and its reads are the transport's, where no late or repeated reply is taken for
an answer (FATEK and Modbus RTU fence every read: README, Safety).

Elements the PLC itself rewrites every scan (``volatile``, e.g. the RTC read-out R4128–R4135) are allowed but
not journaled: the clock's own declaration (:meth:`hil.families.fbs.device.rtc.Rtc.clock`) puts it right.
"""

from __future__ import annotations

from typing import Iterable, Sequence

from hil.bench.guard import Guard
from hil.core.errors import HilError, TransportError, WriteRefused
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
        # bit → disabled (forced) before a test's first command 42 enable/disable of it, read with command 43:
        # put back exactly (an operator's forced bit stays forced), read back with 43
        self.enable_original: dict[Address, bool] = {}

    # -- the guard's address model -------------------------------------------------------------------------------
    def split(self, name: NameLike) -> list[Address]:
        return list(parse(name).elements())

    def read_originals(self, elements: list[Address]) -> list[int]:
        return self.inner.read_many(elements)  # never a late reply: the transport fences its reads (README, Safety)

    def write_back(self, items: list[tuple[Address, int]]) -> None:
        self.inner.write_many(items)

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
        """Command 42 (1 disable, 2 enable, 3 set, 4 reset) on a writable bit.  Before a bit is first enabled or
        disabled its enable state is read (command 43) and journaled, durable first; it is put back when the test
        ends, the bit's value with the other originals."""
        inner_call = getattr(self.inner, "bit_action", None)
        read_state = getattr(self.inner, "read_disabled", None)
        if inner_call is None or read_state is None:
            raise WriteRefused(f"bit actions (FATEK command 42) are not offered by {self.inner.description}")

        def act() -> None:
            base = self.split(name)
            fresh = [a for a in base if a not in self.enable_original] if action in (1, 2) else []
            if fresh:
                states = {a: bool(read_state(a, 1)[0]) for a in fresh}
                if self.durable is not None:
                    self.durable.add_enable_states({str(a): v for a, v in states.items()})
                self.enable_original.update(states)
            inner_call(base[0], action)
        self.guarded([name], act)

    def _restore_actions(self) -> None:
        """The bits' enable states back, each read back (command 43), and RUN/STOP back (before the values)."""
        try:
            if self.enable_original:
                self._restore_enable_states()
        finally:  # RUN/STOP back even when an enable state could not be
            if self.run_original is not None:
                if bool(self.inner.status().running) != self.run_original:
                    self.inner.set_running(self.run_original)
                self.run_original = None
                if self.durable is not None:
                    self.durable.set_extra("run", None)

    def _restore_enable_states(self) -> None:
        if getattr(self.inner, "read_disabled", None) is None or getattr(self.inner, "bit_action", None) is None:
            names = ", ".join(sorted(str(a) for a in self.enable_original))
            raise HilError(f"the enable states of {names} (FATEK commands 42/43) cannot be put back over "
                           f"{self.inner.description}: restore them over the PLC's FATEK port")
        wrong = []
        for address, disabled in sorted(self.enable_original.items(), key=lambda item: str(item[0])):
            if bool(self.inner.read_disabled(address, 1)[0]) != disabled:
                self.inner.bit_action(address, 1 if disabled else 2)
                if bool(self.inner.read_disabled(address, 1)[0]) != disabled:
                    wrong.append(f"{address} (original {'disabled' if disabled else 'enabled'})")
                    continue
            del self.enable_original[address]
            if self.durable is not None:
                self.durable.drop_enable_states([str(address)])
        if self.durable is not None and not self.enable_original:
            self.durable.set_extra("disabled", None)  # an older journal's list of bits to re-enable: done
        if wrong:
            raise HilError(f"command 43 reads the enable state of {', '.join(wrong)} wrong after restoring it")

    def _adopt(self, journal: Journal) -> None:
        run = journal.extra("run")
        if run is not None and self.run_original is None:
            self.run_original = bool(run)
        for name, disabled in journal.enable_states().items():
            self.enable_original.setdefault(parse(name), disabled)
        for name in journal.extra("disabled", []):  # an older journal: bits a run disabled, to be re-enabled
            self.enable_original.setdefault(parse(name), False)

    # -- writes: check, journal, then pass on --------------------------------------------------------------
    def write_words(self, address: NameLike, values: Sequence[int]) -> None:
        first = parse(address)
        names = [first.offset(i) for i in range(len(values))] if values else []
        self.guarded(names, lambda: super(GuardedTransport, self).write_words(first, values))

    def write_bits(self, address: NameLike, values: Sequence[int | bool]) -> None:
        first = parse(address)
        names = [first.offset(i) for i in range(len(values))] if values else []
        self.guarded(names, lambda: super(GuardedTransport, self).write_bits(first, values))

    def write_many(self, items) -> None:  # noqa: ANN001 - same forms as Transport.write_many
        pairs = list(items.items()) if hasattr(items, "items") else list(items)
        self.guarded([a for a, _ in pairs], lambda: super(GuardedTransport, self).write_many(pairs))

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
