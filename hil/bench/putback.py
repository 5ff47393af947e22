"""Putting originals back, verified: write them, read them back, and say which are back and which are not.

The one put-back under both restores — the guard's after each test (:meth:`hil.bench.guard.Guard.restore`) and
recovery's of a dead run's journal (:mod:`hil.bench.replay`) — so "restored" means the same thing in both: written
and read back equal.  A wire that failed is reconnected once and the whole put-back tried again.
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from dataclasses import dataclass
from typing import Any, Protocol

from hil.core.errors import HilError, TransportError

Failure = tuple[str, Any, str]  # (element, original, why), as RestoreError lists them
Item = tuple[Any, int]  # (element, its original)


class Restorable(Protocol):
    """What a put-back needs of a guarded link: its family's raw writes and fenced reads of elements."""

    def write_back(self, items: list[Item]) -> None: ...

    def read_originals(self, elements: list[Any]) -> list[int]: ...


@dataclass(frozen=True)
class PutBack:
    """What became of each item put back: ``restored`` (written, or found, and read back equal) or ``failed``."""

    restored: list[Item]
    failed: list[Failure]

    @classmethod
    def of(cls, items: list[Item], failed: list[Failure]) -> PutBack:
        """The verdict of each of ``items``: restored unless a failure names it."""
        bad = {name for name, _, _ in failed}
        return cls([(e, v) for e, v in items if str(e) not in bad], failed)

    def why(self, element: Any) -> str | None:
        """Why ``element`` could not be put back (None: it is back)."""
        return next((why for name, _, why in self.failed if name == str(element)), None)


def put_back(link: Restorable, items: list[Item], reopen: Callable[[], None],
             read_first: Collection[Any] = ()) -> PutBack:
    """Write ``items`` and read them back — those in ``read_first`` only where a read shows they differ; when the
    wire failed, ``reopen()`` once and try again."""
    if not items:
        return PutBack([], [])
    failures, wire_failed = _put_back_once(link, items, read_first)
    if failures and wire_failed:
        try:
            reopen()
        except HilError as exc:
            return PutBack.of(items, [(a, v, f"{why}; reconnecting failed: {exc}") for a, v, why in failures])
        failures, _ = _put_back_once(link, items, read_first)
    return PutBack.of(items, failures)


class _Stopped(Exception):
    """A write or read of the put-back failed: what it leaves unrestored, and whether the wire failed."""

    def __init__(self, failures: list[Failure], wire: bool) -> None:
        super().__init__(failures)
        self.failures, self.wire = failures, wire


def _put_back_once(link: Restorable, items: list[Item], checked: Collection[Any]) -> tuple[list[Failure], bool]:
    # What the test wrote goes back first, in order (an EN back at 0 stops FUN86 rewriting its outputs).  Then one
    # read is both that write's read-back and the check of what is read first (``checked``: e.g. what the PLC
    # rewrote only because of the test's writes, stable now that its cause is undone): those are written back,
    # and read back again, only where they differ — on port 0 a read of a block costs what writing it does, so an
    # untouched block costs one read instead of a write and a read-back.
    first = [(a, v) for a, v in items if a not in checked]
    later = [(a, v) for a, v in items if a in checked]
    wrong: list[Failure] = []
    try:
        if first:
            _write(link, first, blame=items)
        now = _read(link, first + later, blame=items)
        wrong = _reads_wrong(first, now)
        differ = [(a, v) for (a, v), got in zip(later, now[len(first):]) if got != v]
        if differ:
            _write(link, differ, blame=differ)
            wrong += _reads_wrong(differ, _read(link, differ, blame=differ))
    except _Stopped as stop:
        return wrong + stop.failures, stop.wire
    return wrong, False


def _write(link: Restorable, items: list[Item], blame: list[Item]) -> None:
    try:
        link.write_back(items)
    except Exception as exc:  # any failure must end up in the list, not hide the rest
        raise _Stopped(_all(blame, "write failed", exc), isinstance(exc, TransportError)) from exc


def _read(link: Restorable, items: list[Item], blame: list[Item]) -> list[int]:
    try:
        return link.read_originals([a for a, _ in items])
    except Exception as exc:  # any failure must end up in the list, not hide the rest
        raise _Stopped(_all(blame, "read-back failed", exc), isinstance(exc, TransportError)) from exc


def _all(items: list[Item], what: str, exc: Exception) -> list[Failure]:
    return [(str(a), v, f"{what}: {exc}") for a, v in items]


def _reads_wrong(items: list[Item], got: list[int]) -> list[Failure]:
    return [(str(a), v, f"reads {now} after restore") for (a, v), now in zip(items, got) if now != v]


__all__ = ["Failure", "Item", "PutBack", "Restorable", "put_back"]
