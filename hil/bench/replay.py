"""Recovery: what a dead run's journal may put back, entry by entry, and only as far as it can be proven.

A journal (:mod:`hil.core.journal`) is replayed only when

* the file can be trusted (this user's, not writable by others, version 2, this bench's key) — else nothing;
* it was written on this PLC: the identity the wire reads now (FATEK command 53, the S7 identity) is the one the
  journal recorded; a wire that can read none relies on the key, which a profile's ``[bench] plc_id`` vouches for;

and then each entry only when it is well formed, within the profile's ``[safety] writable`` (RUN/STOP only with
``allow_destructive``; rig coils only on the profile's own rig), not ``volatile`` (the PLC rewrites it: dropped,
said), not older than :data:`MAX_AGE` (``hil restore`` by hand takes older ones), and *still holds the value the run
wrote* — an element someone changed since is left as it is and listed.  Everything not replayed is named and kept
in the journal; the report's "verified" list is exactly what was read back equal.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from hil.core.journal import ELEMENTS, Journal, run_left

if TYPE_CHECKING:  # the guard imports this module
    from hil.bench.guard import Guard

MAX_AGE = 7 * 86400.0  # s: an older entry is not replayed by a run (the PLC has surely been used since)


@dataclass
class Recovery:
    """What :meth:`hil.bench.guard.Guard.recover` found in a dead run's journal, and what became of each entry —
    or, with ``show`` (``hil restore --show``), what it would become: the same decisions, nothing written."""

    bench: str
    path: str
    pending: list[str] = field(default_factory=list)  # what the journal held, one line each
    verified: list[str] = field(default_factory=list)  # put back (or found back) and read back equal
    refused: list[str] = field(default_factory=list)  # not replayed, each with why (kept in the journal)
    changed: list[str] = field(default_factory=list)  # someone changed it since the run: left as it is (kept)
    failures: list[str] = field(default_factory=list)  # a restore that failed (kept)
    notes: list[str] = field(default_factory=list)  # dropped without a write, and why (volatile)
    by: str = ""  # whose run left the journal (another user's, on a shared bench: :meth:`Journal.left_by`)
    planned: list[str] = field(default_factory=list)  # ``show``: what a restore would put back (nothing written)
    show: bool = False  # decide and list only: nothing is written, to the PLC or to the journal
    parts: list[Recovery] = field(default_factory=list)  # one per journal (the run's, each lane's), once merged

    @property
    def needed(self) -> bool:
        return bool(self.pending or self.refused)

    def merge(self, other: Recovery) -> None:
        """Add what another journal of the same PLC (a lane's, :meth:`hil.core.journal.Journal.lane_names`) held."""
        if other.needed:
            self.path = f"{self.path}, {other.path}" if self.needed else other.path
            self.by = "; ".join(dict.fromkeys(b for b in (self.by if self.needed else "", other.by) if b))
        for name in ("pending", "verified", "refused", "changed", "failures", "notes", "planned"):
            getattr(self, name).extend(getattr(other, name))
        self.parts.append(other)

    @property
    def ok(self) -> bool:
        return not (self.failures or self.refused or self.changed)

    def sections(self) -> list[tuple[str, list[str]]]:
        """What became (``show``: would become) of the entries: (what, the entries' lines), by kind of outcome."""
        show = self.show
        return [("would restore", self.planned),
                ("already back (read)" if show else "restored and verified (read back)", self.verified),
                ("would drop" if show else "dropped", self.notes),
                ("changed since — left", self.changed),
                ("refused", self.refused),
                ("cannot tell (reading it failed)" if show else "restore failed", self.failures)]

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


#: what recovery does with an entry, from what it holds now (:func:`still_the_runs`)
BACK, RESTORE, CHANGED = "back", "restore", "changed"


def still_the_runs(now: Any, original: Any, left: list | None) -> str:
    """The one rule for every entry recovery may put back (an element, a bit's enable state, RUN/STOP): BACK when
    it holds its original (nothing to write), RESTORE when it still holds what the run left (``left``:
    :func:`hil.core.journal.run_left`; None for what the PLC rewrote itself, which has no written value), else
    CHANGED — someone changed it since the run: left as it is, and said."""
    if now == original:
        return BACK
    if left is None or now in left:
        return RESTORE
    return CHANGED


def changed_line(name: str, now: Any, left: list, original: Any) -> str:
    """How an entry someone changed since the run is reported."""
    return f"{name} reads {now}, the run wrote {' or '.join(map(str, left))} (original {original})"


def _describe_plc(identity: dict[str, str]) -> str:
    return ", ".join(f"{k} {v}" for k, v in sorted(identity.items()))


def identity_problem(journal: Journal, vouched: bool) -> str | None:
    """Why this journal may not be replayed on the PLC the wire reaches now (None: it may).  ``vouched``: the key
    is the profile's ``[bench] plc_id``, so a wire that reads no identity may still replay it."""
    then, now = journal.data.get("plc"), journal.plc
    if then is None:
        return None
    if now is None:
        if vouched:
            return None
        return (f"the journal was written on the PLC {_describe_plc(then)}, and this wire cannot read the PLC's "
                f"identity to check it is that one — nothing replayed (name the PLC with [bench] plc_id, or use "
                f"the wire the run used, {journal.data.get('endpoint')})")
    if then != now:
        return (f"the journal was written on the PLC {_describe_plc(then)}; the PLC reached now is "
                f"{_describe_plc(now)} — nothing replayed")
    return None


def age_problem(entry: Any, by_hand: bool) -> str | None:
    """Why an entry is too old for a run to replay (``hil restore`` by hand takes it)."""
    if by_hand or not isinstance(entry, dict):
        return None
    try:
        at = dt.datetime.fromisoformat(entry["at"])
    except (KeyError, TypeError, ValueError):
        return "it has no time stamp"
    age = (dt.datetime.now(dt.UTC) - at).total_seconds()
    if age > MAX_AGE:
        return f"it is {age / 86400:.0f} days old (over {MAX_AGE / 86400:.0f}); `hil restore` replays it by hand"
    return None


@dataclass
class Verdict:
    """What the next replay does with one element entry (also for ``hil restore --show``)."""

    name: str
    action: str  # "restore", "drop" (volatile), "refuse", or "check" (restore if it still holds what was written)
    why: str = ""
    element: Any = None
    entry: dict = field(default_factory=dict)


def element_verdicts(guard: Guard, journal: Journal, by_hand: bool) -> list[Verdict]:
    """Each element entry's verdict from the journal and the profile alone (no PLC read yet)."""
    out = []
    allowed_side: frozenset | None = None
    for name, entry in journal.data["elements"].items():
        problem = ELEMENTS.check(entry)
        if problem:
            out.append(Verdict(name, "refuse", f"malformed: {problem}"))
            continue
        try:
            elements = guard.split(name)
        except Exception as exc:  # noqa: BLE001 - any bad name is refused by name
            out.append(Verdict(name, "refuse", f"not an element of this PLC: {exc}"))
            continue
        if len(elements) != 1 or str(elements[0]) != name:
            out.append(Verdict(name, "refuse", "not one base element (a journal names bits and words)"))
            continue
        element = elements[0]
        if element in guard.volatile:
            out.append(Verdict(name, "drop", "volatile in the profile: the PLC rewrites it itself"))
            continue
        bad = next(filter(None, (guard.value_problem(element, v) for v in [entry["original"], *run_left(entry)])),
                   None)
        if bad:
            out.append(Verdict(name, "refuse", f"malformed: {bad}"))
            continue
        if element not in guard.writable:
            if entry["wrote"] is not None:
                out.append(Verdict(name, "refuse", "not in the profile's [safety] writable"))
                continue
            if allowed_side is None:  # what the PLC itself rewrites because of a write the profile allows
                allowed_side = frozenset(guard.keys(list(guard.side_effects(sorted(guard.writable, key=str))))) \
                    if guard.side_effects is not None else frozenset()
            if element not in allowed_side:
                out.append(Verdict(name, "refuse", "neither in [safety] writable nor rewritten by the PLC after a "
                                                   "write it allows"))
                continue
        old = age_problem(entry, by_hand)
        if old:
            out.append(Verdict(name, "refuse", old))
            continue
        out.append(Verdict(name, "check", "", element, entry))
    return out


def replay_elements(guard: Guard, journal: Journal, report: Recovery, by_hand: bool) -> None:
    """Put back each element that still holds what the run wrote, read back; list the rest.

    In two passes: first the causes of the PLC's own rewrites (an EN, FUN86's Sn/Zn registers: what
    :attr:`Guard.side_effects` answers for), then everything else.  What the PLC rewrites (a box's WR while its EN
    is on) may change between a read and the write that stops it; read before its cause is undone, a WR that
    happened to hold its original would be taken as back, and the PLC's next rewrite would stay."""
    checks, causes = [], []
    for verdict in element_verdicts(guard, journal, by_hand):
        label = f"{verdict.name}"
        if verdict.action == "refuse":
            report.refused.append(f"{label}: {verdict.why}")
        elif verdict.action == "drop":
            report.notes.append(f"{label}: {verdict.why}")
            if not report.show:
                journal.drop_elements([verdict.name])
        elif guard.causes_side_effects(verdict.element):
            causes.append(verdict)
        else:
            checks.append(verdict)
    for stage in (causes, checks):
        if stage:
            _replay(guard, journal, report, stage)


def _replay(guard: Guard, journal: Journal, report: Recovery, checks: list[Verdict]) -> None:
    """One pass of :func:`replay_elements`: read ``checks``, put back those that still hold what the run wrote
    (:func:`still_the_runs`); with ``report.show`` only say so."""
    try:
        now = guard.read_originals([v.element for v in checks])
    except Exception as exc:  # noqa: BLE001 - nothing is written without knowing what is there
        report.failures += [f"{v.name} (original {v.entry['original']}): reading it failed: {exc}" for v in checks]
        return
    back, restore = [], []
    for verdict, value in zip(checks, now):
        original = verdict.entry["original"]
        left = run_left(verdict.entry) if verdict.entry["wrote"] is not None else None
        decision = still_the_runs(value, original, left)
        if decision == BACK:
            back.append(verdict)
        elif decision == RESTORE:
            restore.append(verdict)
            if report.show:
                report.planned.append(f"{verdict.name} to {original} (reads {value}"
                                      + (", the PLC's own)" if left is None else ", as the run left it)"))
        else:
            report.changed.append(changed_line(verdict.name, value, left or [], original))
    if report.show:
        report.verified += [f"{v.name} = {v.entry['original']}" for v in back]
        return
    bad = {str(name): why for name, _, why in guard._put_back([(v.element, v.entry["original"]) for v in restore])} \
        if restore else {}
    for verdict in restore:
        if verdict.name in bad:
            report.failures.append(f"{verdict.name} (original {verdict.entry['original']}): {bad[verdict.name]}")
        else:
            back.append(verdict)
    report.verified += [f"{v.name} = {v.entry['original']}" for v in back]
    journal.drop_elements(v.name for v in back)


__all__ = ["BACK", "CHANGED", "MAX_AGE", "RESTORE", "Recovery", "Verdict", "age_problem", "changed_line",
           "element_verdicts", "identity_problem", "replay_elements", "still_the_runs"]
