"""The journal writer: what a test wrote — each element's original before its first write, and the value written
— kept in memory and, on a real bench, on disk first (:class:`hil.core.journal.Journal`, fsync'd) before the write
goes out; an original leaves both only once it is put back and read back (:meth:`WriteJournal.verified`)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterable, Iterator
from typing import Any

from hil.core.journal import Journal


class WriteJournal:
    """The originals a session still has to put back, and what the current test touched."""

    def __init__(self, volatile: frozenset[Any]) -> None:
        self.volatile = volatile  # rewritten by the PLC itself: never journaled
        self.originals: dict[Any, int] = {}  # element → its value before the first write (until verified restored)
        self.touched: set[Any] = set()  # every element written since the test started
        self.effects: set[Any] = set()  # every element journaled as a side effect of those writes
        self.last_wrote: dict[Any, int] = {}  # element → what the test last wrote to it, where the family knows
        # On disk before each write goes out (None for an in-process emulator: nothing outlives the run).
        self.durable: Journal | None = None
        self.replaying = False  # recovery is writing a dead run's originals back (not a test writing)

    @contextlib.contextmanager
    def replay(self) -> Iterator[None]:
        """Recovery's own writes (the clock's set procedure) put back: they journal nothing."""
        self.replaying = True
        try:
            yield
        finally:
            self.replaying = False

    def fresh(self, elements: Iterable[Any]) -> list[Any]:
        """Those of ``elements`` whose original is still to be read: not journaled yet, not volatile."""
        return [e for e in dict.fromkeys(elements) if e not in self.originals and e not in self.volatile]

    def record(self, originals: dict[Any, int], wrote: dict[Any, int], *, on_disk: bool = True) -> None:
        """Journal ``originals`` with what is about to be written (``wrote``, where the family knows it) — on disk
        first (``on_disk``: unless the guard's own clock restore writes after the journal failed)."""
        if self.durable is not None and on_disk:
            self.durable.add_elements({str(e): v for e, v in originals.items()},
                                      {str(e): v for e, v in wrote.items() if e not in self.volatile})
        self.originals.update(originals)

    def touch(self, covered: Iterable[Any], wrote: dict[Any, int]) -> None:
        """The test wrote ``covered``: remember it, and what it wrote where the family knows that."""
        for element in covered:
            self.touched.add(element)
            if element in wrote:
                self.last_wrote[element] = wrote[element]
            else:
                self.last_wrote.pop(element, None)

    def due(self, held: frozenset[Any]) -> list[tuple[Any, int]]:
        """The originals to put back now: every one outside ``held``."""
        return [(e, v) for e, v in self.originals.items() if e not in held]

    def verified(self, items: list[tuple[Any, int]]) -> None:
        """``items`` are back and read back: only now do their originals leave memory and disk."""
        for element, _ in items:
            del self.originals[element]
        if self.durable is not None and items:
            self.durable.drop_elements(str(e) for e, _ in items)

    def effects_of_this_test(self) -> set[Any]:
        """Journaled elements the PLC rewrites only because of this test's writes, never written by it."""
        return self.effects - self.touched if self.touched else set()

    def forget_test(self) -> None:
        """The next test starts: forget what was touched (unrestored originals stay until a restore succeeds)."""
        self.touched.clear()
        self.effects.clear()
        self.last_wrote.clear()


__all__ = ["WriteJournal"]
