"""What recovery found in a dead run's journal, and what became of each entry (:class:`Recovery`).

Every entry ends in one :class:`Outcome`, and each outcome has one label, for a replay and for ``hil restore
--show`` alike: the run's console line and JUnit property, ``hil restore`` and ``hil restore --show`` all print the
same report (:meth:`Recovery.sections`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum


class Outcome(Enum):
    """What became of one journal entry (with ``show``: what would), in the order a report lists them."""

    #: (the :class:`Recovery` list that holds it, its label after a replay, its label for ``show``)
    PLANNED = ("planned", "would restore", "would restore")
    RESTORED = ("verified", "restored and verified (read back)", "restored and verified (read back)")
    #: found holding its original: read, nothing written
    BACK = ("back", "already back (read)", "already back (read)")
    DROPPED = ("notes", "dropped", "would drop")
    CHANGED = ("changed", "changed since — left", "changed since — left")
    REFUSED = ("refused", "refused", "refused")
    FAILED = ("failures", "restore failed", "cannot tell (reading it failed)")

    def __init__(self, kept_in: str, done: str, shown: str) -> None:
        self.kept_in, self.done, self.shown = kept_in, done, shown

    def label(self, show: bool) -> str:
        return self.shown if show else self.done

    @classmethod
    def labelled(cls, label: str) -> Outcome:
        """The outcome a report's label names (either form)."""
        return next(o for o in cls if label in (o.done, o.shown))


@dataclass
class Recovery:
    """What :meth:`hil.bench.guard.Guard.recover` found in a dead run's journal, and what became of each entry —
    or, with ``show`` (``hil restore --show``), what it would become: the same decisions, nothing written."""

    bench: str
    path: str
    pending: list[str] = field(default_factory=list)  # what the journal held, one line each
    verified: list[str] = field(default_factory=list)  # put back and read back equal
    back: list[str] = field(default_factory=list)  # found holding its original: nothing written
    refused: list[str] = field(default_factory=list)  # not replayed, each with why (kept in the journal)
    changed: list[str] = field(default_factory=list)  # someone changed it since the run: left as it is (kept)
    failures: list[str] = field(default_factory=list)  # a restore that failed (kept)
    notes: list[str] = field(default_factory=list)  # dropped without a write, and why (volatile)
    by: str = ""  # whose run left the journal (another user's, on a shared bench: :meth:`Journal.left_by`)
    planned: list[str] = field(default_factory=list)  # ``show``: what a restore would put back (nothing written)
    show: bool = False  # decide and list only: nothing is written, to the PLC or to the journal
    parts: list[Recovery] = field(default_factory=list)  # one per journal (the run's, each lane's), once merged

    def add(self, outcome: Outcome, line: str) -> None:
        """One entry's outcome, as its line."""
        self.lines(outcome).append(line)

    def lines(self, outcome: Outcome) -> list[str]:
        """The entries that ended in ``outcome``."""
        lines: list[str] = getattr(self, outcome.kept_in)
        return lines

    @property
    def needed(self) -> bool:
        return bool(self.pending or self.refused)

    def merge(self, other: Recovery) -> None:
        """Add what another journal of the same PLC (a lane's, :meth:`hil.core.journal.Journal.lane_names`) held."""
        if other.needed:
            self.path = f"{self.path}, {other.path}" if self.needed else other.path
            self.by = "; ".join(dict.fromkeys(b for b in (self.by if self.needed else "", other.by) if b))
        self.pending.extend(other.pending)
        for outcome in Outcome:
            self.lines(outcome).extend(other.lines(outcome))
        self.parts.append(other)

    @property
    def ok(self) -> bool:
        return not (self.failures or self.refused or self.changed)

    def sections(self) -> list[tuple[str, list[str]]]:
        """What became (``show``: would become) of the entries: (what, the entries' lines), by kind of outcome."""
        return [(outcome.label(self.show), self.lines(outcome)) for outcome in Outcome]

    def summary(self) -> str:
        if not self.needed:
            return f"hil bench recovery: nothing pending for {self.bench}"
        parts = [f"{what}: " + "; ".join(lines) for what, lines in self.sections() if lines]
        if self.ok:
            return (f"hil bench recovery: a previous run on {self.bench}{self._whose()} died leaving "
                    f"{len(self.pending)} entry(s) — " + " — ".join(parts))
        return (f"hil bench recovery FAILED on {self.bench}{self._whose()} (what is left is kept in {self.path}; "
                f"`hil restore --show` lists it): " + " — ".join(parts))

    def _whose(self) -> str:
        return f" ({self.by}; its journal {self.path})" if self.by else ""


__all__ = ["Outcome", "Recovery"]
