"""Recovery first: what a dead run left in a PLC's journal — and in each journal its lanes left beside it —
replayed before anything else, as far as it can be proven: the family's own steps (e.g. a fault rig's coils), its
actions (RUN/STOP, disabled bits), the clock (exactly, from its journaled origin), then the elements
(:mod:`hil.bench.replay`).  With ``show`` (``hil restore --show``) the same decisions, nothing written.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass
from typing import Any, Protocol

from hil.bench.clock_keeper import ClockKeeper
from hil.bench.recovery import Recovery
from hil.bench.replay import Replayable, identity_problem, replay_elements
from hil.bench.write_journal import WriteJournal
from hil.core.errors import HilError
from hil.core.journal import COILS, Journal, JournalError, journal_path

#: a family's own recovery step (e.g. a fault rig's coils): called with the journal, the report to add to and
#: whether an operator asked for it by hand (``hil restore``: older entries too)
RecoveryStep = Callable[[Journal, Recovery, bool], None]


class Recoverable(Replayable, Protocol):
    """What recovery needs of the guard (:class:`hil.bench.guard.Guard`) besides what a replay does."""

    durable: Journal | None  # the journal whose entries a replay drops once verified
    identity_vouched: bool  # the journal's key is the profile's [bench] plc_id
    clocks: ClockKeeper
    written: WriteJournal


@dataclass(frozen=True)
class Replay:
    """How a recovery goes: the family's ``steps`` first; ``by_hand`` (``hil restore``: older entries too);
    ``show`` (decide and list only); ``accept_host_clock`` (a clock origin from another boot of the host)."""

    steps: tuple[RecoveryStep, ...] = ()
    by_hand: bool = False
    show: bool = False
    accept_host_clock: bool = False


def recover(guard: Recoverable, how: Replay, actions: RecoveryStep, lock: AbstractContextManager[Any]) -> Recovery:
    """Replay the guard's durable journal and each of its lanes' journals, each as if it were this run's own
    (``actions``: the family's own entries; ``lock``: the wire's, held while the PLC is put back); a journal that
    cannot be read is named (refused) and the others still replayed."""
    journal = guard.durable
    assert journal is not None  # (the guard recovers only with a journal on disk)
    report = Recovery(journal.key, str(journal.path), show=how.show)
    report.merge(_recover_part(guard, journal, how, actions, lock))
    for name in journal.lane_names():
        try:
            lane = journal.lane_journal(name)
        except JournalError as exc:  # damaged or untrusted: named, kept, and the others still replayed
            report.merge(Recovery(journal.key, str(journal_path(journal.key, journal.path.parent, name)),
                                  refused=[str(exc)], show=how.show))
            continue
        report.merge(_recover_part(guard, lane, how, actions, lock))
    return report


def _recover_part(guard: Recoverable, part: Journal, how: Replay, actions: RecoveryStep,
                  lock: AbstractContextManager[Any]) -> Recovery:
    """One of the journals, replayed as if it were the run's own."""
    journal = guard.durable
    guard.durable = part  # what the replay drops, it drops from that journal's file
    try:
        return _recover_journal(guard, part, how, actions, lock)
    finally:
        guard.durable = journal


def _recover_journal(guard: Recoverable, journal: Journal, how: Replay, actions: RecoveryStep,
                     lock: AbstractContextManager[Any]) -> Recovery:
    try:
        journal.data = journal.load()
    except JournalError as exc:
        return Recovery(journal.key, str(journal.path), refused=[str(exc)], show=how.show)
    report = Recovery(journal.key, str(journal.path), journal.describe(), by=journal.left_by(), show=how.show)
    if not journal.pending:
        return report
    mismatch = identity_problem(journal, guard.identity_vouched)
    if mismatch:
        report.refused.append(mismatch)
        return report
    if how.show:  # a family's step reads (and writes) another device: listed as the journal holds it
        report.planned += [f"{line} (not read by --show)" for line in journal.describe(COILS)]
    else:
        for step in how.steps:
            step(journal, report, how.by_hand)
    with lock:
        try:
            actions(journal, report, how.by_hand)
        except HilError as exc:
            report.failures.append(f"RUN/STOP and disabled bits: {exc}")
        _recover_clock(guard, journal, report, how)
        replay_elements(guard, journal, report, how.by_hand)
    return report


def _recover_clock(guard: Recoverable, journal: Journal, report: Recovery, how: Replay) -> None:
    """The clock a dead run may have set, back at its offset from the host's clock (exactly), read back."""
    origin = guard.clocks.journaled_origin(journal, report, how.by_hand, how.accept_host_clock, guard.writable)
    if origin is not None:
        with guard.written.replay():  # the clock's set procedure writes through the guard: not journaled
            guard.clocks.recover(origin, guard.durable, report)


__all__ = ["Recoverable", "RecoveryStep", "Replay", "recover"]
