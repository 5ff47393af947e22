"""The guard every suite write goes through: an allow-list checked before a byte is sent, and a write journal.

A real PLC is somebody's machine.  The guard

* refuses any write touching an element outside the profile's ``[safety] writable`` ranges (WriteRefused,
  raised before the inner transport sees the request);
* journals the original value of each element on its first write (read from the PLC just before writing);
* :meth:`restore` writes every original back and reads them all again to prove it, pass or fail.

Elements the PLC itself rewrites every scan (``volatile``, e.g. the RTC read-out R4128–R4135) are allowed but
not journaled: restoring their old values is meaningless, so a procedure (syncing the RTC to host time) puts
them right instead; :attr:`touched` tells the bench which procedures are due.
"""

from __future__ import annotations

from typing import Callable, Iterable, Sequence

from hil.families.fbs.address import Address, parse, parse_range
from hil.core.errors import HilError, RestoreError, TransportError, WriteRefused
from hil.families.fbs.transport.base import NameLike, PlcStatus, Transport


def expand(ranges: Iterable[str]) -> frozenset[Address]:
    """Base elements (bits and 16-bit words) named by ``["R4128-R4135", "M1952", "WM800"]``."""
    out: set[Address] = set()
    for text in ranges:
        for element in parse_range(text):
            out.update(element.elements())
    return frozenset(out)


class GuardedTransport(Transport):
    def __init__(self, inner: Transport, writable: Iterable[str], volatile: Iterable[str] = ()) -> None:
        super().__init__(f"guarded {inner.description}")
        self.inner = inner
        self.limits = inner.limits
        self.requests_per_read = inner.requests_per_read
        self.emulator = inner.emulator
        self.writable = expand(writable)
        self.volatile = expand(volatile)
        self.journal: dict[Address, int] = {}  # base element → value before the test's first write
        self.touched: set[Address] = set()  # every base element written since the journal was started
        self.reopened = 0  # reconnections made to restore
        # The durable journal (hil.core.journal.Journal): each original is on disk before its first write.  None for
        # an in-process emulator (each run builds its own: nothing outlives the run).
        self.durable = None
        # Elements the PLC itself rewrites because of a write (the device layer declares them, e.g. an EN rising
        # edge → PR/IR/DR of that FUN86 box): journaled as originals along with the written ones, never written.
        self.side_effects: Callable[[list[Address]], Iterable[Address]] | None = None
        # Called with the base elements of every write before it is journaled (the bench records the clock).
        self.before_write: Callable[[list[Address]], None] | None = None
        self.allow_destructive = False  # FATEK command 41 (RUN/STOP) only with the explicit opt-in
        self.run_original: bool | None = None  # RUN/STOP before a test's first command 41
        self.disabled: set[Address] = set()  # bits a test disabled with command 42: re-enabled on restore

    # -- the allow-list and the journal --------------------------------------------------------------------
    def check(self, names: Iterable[NameLike]) -> list[Address]:
        """Raise WriteRefused unless every element is writable; return the base elements covered."""
        base: list[Address] = []
        for name in names:
            address = parse(name)
            parts = list(address.elements())
            refused = [str(p) for p in parts if p not in self.writable]
            if refused:
                shown = ", ".join(refused[:4]) + ("…" if len(refused) > 4 else "")
                raise WriteRefused(
                    f"write to {address} refused: {shown} not in the bench's [safety] writable list — add the "
                    f"range to the profile if this test may change it on this bench")
            base += parts
        return base

    def _remember(self, base: Sequence[Address]) -> None:
        if self.before_write is not None:
            self.before_write(list(base))
        wanted = list(base)
        if self.side_effects is not None:
            wanted += list(self.side_effects(list(base)))
        fresh = [a for a in dict.fromkeys(wanted) if a not in self.journal and a not in self.volatile]
        if fresh:
            originals = dict(zip(fresh, self.inner.read_many(fresh)))  # a read is never a late reply (README, Safety)
            if self.durable is not None:  # on disk (fsync'd) before the write goes out
                self.durable.add_elements({str(a): v for a, v in originals.items()})
            self.journal.update(originals)
        self.touched.update(base)

    def start_journal(self) -> None:
        """The next test starts: forget which elements were touched.  Originals whose restore failed stay in the
        journal (and on disk) until a restore succeeds — :meth:`restore` retries them."""
        self.touched.clear()

    @property
    def unrestored(self) -> list[tuple[Address, int]]:
        return list(self.journal.items())

    def restore(self) -> list[tuple[Address, int]]:
        """Write every journaled original back, then read them all to verify.  Returns what was restored.

        If the wire failed (the transport raised a TransportError), reconnect once (:meth:`Transport.reopen`;
        an emulator's server keeps running, only the client reconnects) and try again.  Raises RestoreError
        listing each element that could not be written or read back equal, with its original value.
        """
        self.restore_actions()
        items = list(self.journal.items())
        if not items:
            return []
        failures, wire_failed = self._restore_once(items)
        if failures and wire_failed:
            try:
                self.inner.reopen()
            except HilError as exc:
                failures = [(a, v, f"{why}; reconnecting failed: {exc}") for a, v, why in failures]
            else:
                self.reopened += 1
                failures, _ = self._restore_once(items)
        if failures:
            raise RestoreError(failures)
        self.journal.clear()
        if self.durable is not None:  # verified: only now may the originals leave the disk
            self.durable.drop_elements(str(a) for a, _ in items)
        return items

    def _restore_once(self, items: list[tuple[Address, int]]) -> tuple[list[tuple[str, int, str]], bool]:
        failures: list[tuple[str, int, str]] = []
        try:
            self.inner.write_many(items)
        except Exception as exc:  # noqa: BLE001 - any failure must end up in the list, not hide the rest
            return [(str(a), v, f"write failed: {exc}") for a, v in items], isinstance(exc, TransportError)
        try:
            now = self.inner.read_many([a for a, _ in items])
        except Exception as exc:  # noqa: BLE001
            return [(str(a), v, f"read-back failed: {exc}") for a, v in items], isinstance(exc, TransportError)
        failures += [(str(a), v, f"reads {got} after restore") for (a, v), got in zip(items, now) if got != v]
        return failures, False

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
        with self._lock:
            base = self.check([name])
            self._remember(base)
            if action == 1:
                self.disabled.update(base)
                if self.durable is not None:
                    self.durable.set_extra("disabled", sorted({*self.durable.extra("disabled", []),
                                                               *(str(a) for a in base)}))
            inner_call(base[0], action)

    def restore_actions(self) -> None:
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

    # -- writes: check, journal, then pass on --------------------------------------------------------------
    def write_words(self, address: NameLike, values: Sequence[int]) -> None:
        first = parse(address)
        names = [first.offset(i) for i in range(len(values))] if values else []
        self._guarded(names, lambda: super(GuardedTransport, self).write_words(first, values))

    def write_bits(self, address: NameLike, values: Sequence[int | bool]) -> None:
        first = parse(address)
        names = [first.offset(i) for i in range(len(values))] if values else []
        self._guarded(names, lambda: super(GuardedTransport, self).write_bits(first, values))

    def write_many(self, items) -> None:  # noqa: ANN001 - same forms as Transport.write_many
        pairs = list(items.items()) if hasattr(items, "items") else list(items)
        self._guarded([a for a, _ in pairs], lambda: super(GuardedTransport, self).write_many(pairs))

    def _guarded(self, names: list[Address], write) -> None:  # noqa: ANN001
        with self._lock:
            base = self.check(names)
            self._remember(base)
            write()

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
