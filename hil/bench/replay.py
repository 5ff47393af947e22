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
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, Protocol

from hil.bench.putback import Item, PutBack
from hil.bench.recovery import Outcome, Recovery
from hil.core.journal import ELEMENTS, Journal, run_left

MAX_AGE = 7 * 86400.0  # s: an older entry is not replayed by a run (the PLC has surely been used since)


class Replayable(Protocol):
    """What a replay needs of the guarded link (:class:`hil.bench.guard.Guard`): its allow-list, its family's
    address model and range check, what the PLC rewrites itself, and the verified put-back."""

    @property
    def writable(self) -> frozenset[Any]: ...

    @property
    def volatile(self) -> frozenset[Any]: ...

    side_effects: Callable[[list[Any]], Iterable[Any]] | None

    def split(self, name: Any) -> list[Any]: ...

    def keys(self, elements: list[Any]) -> list[Any]: ...

    def value_problem(self, element: Any, value: int) -> str | None: ...

    def causes_side_effects(self, element: Any) -> bool: ...

    def read_originals(self, elements: list[Any]) -> list[int]: ...

    def put_back(self, items: list[Item]) -> PutBack: ...


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
    """What the next replay does with one element entry, from the journal and the profile alone (also for ``hil
    restore --show``)."""

    name: str
    action: str  # "restore", "drop" (volatile), "refuse", or "check" (restore if it still holds what was written)
    why: str = ""
    element: Any = None
    entry: dict[str, Any] = field(default_factory=dict)

    @property
    def original(self) -> Any:
        return self.entry["original"]

    @property
    def left(self) -> list[Any] | None:
        """What the run left in it (None: the PLC rewrote it itself, there is no written value)."""
        return run_left(self.entry) if self.entry["wrote"] is not None else None


def element_verdicts(guard: Replayable, journal: Journal, by_hand: bool) -> list[Verdict]:
    """Each element entry's verdict from the journal and the profile alone (no PLC read yet)."""
    rewritten = _Rewritten(guard)
    out = []
    for name, entry in journal.data["elements"].items():
        element, why = _element(guard, name, entry)
        if element is None:
            out.append(Verdict(name, "refuse", why))
        elif element in guard.volatile:
            out.append(Verdict(name, "drop", "volatile in the profile: the PLC rewrites it itself"))
        else:
            why = _value_problem(guard, element, entry) or _not_allowed(guard, element, entry, rewritten) \
                or age_problem(entry, by_hand) or ""
            out.append(Verdict(name, "refuse", why) if why else Verdict(name, "check", "", element, entry))
    return out


def _element(guard: Replayable, name: str, entry: Any) -> tuple[Any, str]:
    """The one base element a well-formed entry names, or (None, why not)."""
    problem = ELEMENTS.check(entry)
    if problem:
        return None, f"malformed: {problem}"
    try:
        elements = guard.split(name)
    except Exception as exc:  # noqa: BLE001 - any bad name is refused by name
        return None, f"not an element of this PLC: {exc}"
    if len(elements) != 1 or str(elements[0]) != name:
        return None, "not one base element (a journal names bits and words)"
    return elements[0], ""


def _value_problem(guard: Replayable, element: Any, entry: dict[str, Any]) -> str | None:
    bad = next(filter(None, (guard.value_problem(element, v) for v in [entry["original"], *run_left(entry)])), None)
    return f"malformed: {bad}" if bad else None


class _Rewritten:
    """What the PLC itself rewrites because of a write the profile allows (its side effects), read once."""

    def __init__(self, guard: Replayable) -> None:
        self.guard = guard
        self._elements: frozenset[Any] | None = None

    def __contains__(self, element: Any) -> bool:
        if self._elements is None:
            guard = self.guard
            self._elements = frozenset(guard.keys(list(guard.side_effects(sorted(guard.writable, key=str))))) \
                if guard.side_effects is not None else frozenset()
        return element in self._elements


def _not_allowed(guard: Replayable, element: Any, entry: dict[str, Any], rewritten: _Rewritten) -> str | None:
    """Why the profile does not let recovery put ``element`` back (None: it does)."""
    if element in guard.writable:
        return None
    if entry["wrote"] is not None:
        return "not in the profile's [safety] writable"
    if element not in rewritten:
        return "neither in [safety] writable nor rewritten by the PLC after a write it allows"
    return None


def element_outcome(verdict: Verdict, now: Any = None, done: PutBack | None = None) -> tuple[Outcome, str]:
    """The one decision of what became of an element entry, and its line in the report — for a run's recovery,
    ``hil restore`` and ``hil restore --show`` alike: refused or dropped by its :class:`Verdict`; else, from what
    it holds ``now``, back already, changed since (left), or to restore — which ``done`` (the put-back, None for
    ``--show``) says was restored or failed."""
    name = verdict.name
    if verdict.action == "refuse":
        return Outcome.REFUSED, f"{name}: {verdict.why}"
    if verdict.action == "drop":
        return Outcome.DROPPED, f"{name}: {verdict.why}"
    original = verdict.original
    decision = still_the_runs(now, original, verdict.left)
    if decision == CHANGED:
        return Outcome.CHANGED, changed_line(name, now, verdict.left or [], original)
    if decision == RESTORE and done is None:
        whose = ", the PLC's own)" if verdict.left is None else ", as the run left it)"
        return Outcome.PLANNED, f"{name} to {original} (reads {now}{whose}"
    if decision == BACK:
        return Outcome.BACK, f"{name} = {original}"
    why = done.why(verdict.element) if done is not None else None
    if why is not None:
        return Outcome.FAILED, f"{name} (original {original}): {why}"
    return Outcome.RESTORED, f"{name} = {original}"


def replay_elements(guard: Replayable, journal: Journal, report: Recovery, by_hand: bool) -> None:
    """Put back each element that still holds what the run wrote, read back; list the rest.

    In two passes: first the causes of the PLC's own rewrites (an EN, FUN86's Sn/Zn registers: what
    :attr:`Guard.side_effects` answers for), then everything else.  What the PLC rewrites (a box's WR while its EN
    is on) may change between a read and the write that stops it; read before its cause is undone, a WR that
    happened to hold its original would be taken as back, and the PLC's next rewrite would stay."""
    checks, causes = [], []
    for verdict in element_verdicts(guard, journal, by_hand):
        if verdict.action != "check":
            report.add(*element_outcome(verdict))
            if verdict.action == "drop" and not report.show:
                journal.drop_elements([verdict.name])
        elif guard.causes_side_effects(verdict.element):
            causes.append(verdict)
        else:
            checks.append(verdict)
    for stage in (causes, checks):
        if stage:
            _replay(guard, journal, report, stage)


def _replay(guard: Replayable, journal: Journal, report: Recovery, checks: list[Verdict]) -> None:
    """One pass of :func:`replay_elements`: read ``checks``, put back those that still hold what the run wrote
    (:func:`still_the_runs`); with ``report.show`` only say so."""
    try:
        now = guard.read_originals([v.element for v in checks])
    except Exception as exc:  # noqa: BLE001 - nothing is written without knowing what is there
        report.failures += [f"{v.name} (original {v.original}): reading it failed: {exc}" for v in checks]
        return
    done = None
    if not report.show:
        restore = [(v.element, v.original) for v, value in zip(checks, now)
                   if still_the_runs(value, v.original, v.left) == RESTORE]
        done = guard.put_back(restore)
    back = []
    for verdict, value in zip(checks, now):
        outcome, line = element_outcome(verdict, value, done)
        report.add(outcome, line)
        if outcome in (Outcome.RESTORED, Outcome.BACK):
            back.append(verdict.name)
    if not report.show:
        journal.drop_elements(back)


__all__ = ["BACK", "CHANGED", "MAX_AGE", "RESTORE", "Recovery", "Replayable", "Verdict", "age_problem",
           "changed_line", "element_outcome", "element_verdicts", "identity_problem",
           "replay_elements", "still_the_runs"]
