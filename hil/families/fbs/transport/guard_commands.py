"""FATEK commands 41 (RUN/STOP) and 42 (bit actions: disable, enable, set, reset) behind the FBs guard.

Each has an original the guard keeps as it keeps an element's: RUN/STOP before a test's first command 41 and a
bit's enable state (command 43) before its first enable or disable — journaled, durable first, before the command
goes out; put back when the test ends (before the values are restored) and read back; replayed by recovery only
while the PLC is still as the run left it (:func:`hil.bench.replay.still_the_runs`).  RUN/STOP only with
destructive actions allowed.  The element model and the reads and writes are
:class:`~hil.families.fbs.transport.guard.GuardedTransport`'s.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from hil.bench.guard import GuardedLink, PublicLink
from hil.bench.replay import BACK, CHANGED, RESTORE, Recovery, age_problem, still_the_runs
from hil.core.errors import HilError, WriteRefused
from hil.core.journal import DISABLED, ELEMENTS, ENABLE, RUN, Journal, earlier_of, run_left
from hil.families.fbs.address import Address, parse
from hil.families.fbs.transport.base import NameLike


class FatekCommandsGuard(GuardedLink):
    """Commands 41 and 42 of the link it wraps, guarded: its originals journaled first, put back, read back."""

    def __init__(self, inner: PublicLink, writable: Iterable[Address], volatile: Iterable[Address] = ()) -> None:
        super().__init__(inner, writable, volatile)
        self.allow_destructive = False  # FATEK command 41 (RUN/STOP) only with the explicit opt-in
        self.run_original: bool | None = None  # RUN/STOP before a test's first command 41
        # bit → disabled (forced) before a test's first command 42 enable/disable of it, read with command 43:
        # put back exactly (an operator's forced bit stays forced), read back with 43
        self.enable_original: dict[Address, bool] = {}

    def set_running(self, run: bool) -> None:
        """RUN (True) / STOP (False), command 41: only with destructive actions allowed; restored afterwards."""
        if not self.allow_destructive:
            raise WriteRefused("RUN/STOP (FATEK command 41) refused: it is destructive — pass "
                               "--hil-allow-destructive (or [safety] allow_destructive) on a bench where it may")
        inner_call = getattr(self.inner, "set_running", None)
        if inner_call is None:
            raise WriteRefused(f"RUN/STOP is not offered by {self.inner.description}")
        with self._lock:
            original = self.run_original
            if original is None:
                original = bool(self.inner.status().running)
            if self.durable is not None:  # the original and what is about to be set, on disk first (with what the
                # command before left: a run killed before this one goes out leaves that)
                before = self.durable.extra("run", {})
                self.durable.set_extra("run", {"original": original, "wrote": bool(run), **earlier_of(before)})
            self.run_original = original
            inner_call(bool(run))

    def bit_action(self, name: NameLike, action: int) -> None:
        """Command 42 (1 disable, 2 enable, 3 set, 4 reset) on a writable bit.  Before a bit is first enabled or
        disabled its enable state is read (command 43) and journaled, durable first, with the state the command
        sets; it is put back when the test ends, the bit's value with the other originals.  What is journaled as
        written is what the command leaves: the value set (3, 4), or the value the bit holds (1, 2 leave it), so
        that recovery can tell a bit someone changed since."""
        inner_call = getattr(self.inner, "bit_action", None)
        read_state = getattr(self.inner, "read_disabled", None)
        if inner_call is None or read_state is None:
            raise WriteRefused(f"bit actions (FATEK command 42) are not offered by {self.inner.description}")
        base = self.split(name)

        def act() -> None:
            if action in (1, 2):
                fresh = [a for a in base if a not in self.enable_original]
                states = {a: bool(read_state(a, 1)[0]) for a in fresh}
                if self.durable is not None:  # on disk before it is kept (and before the command goes out)
                    self.durable.add_enable_states({str(a): v for a, v in states.items()},
                                                   {str(a): action == 1 for a in base})
                self.enable_original.update(states)
            inner_call(base[0], action)
        with self._lock:
            self.check([name])  # refused before anything is read
            wrote = {base[0]: 1 if action == 3 else 0} if action in (3, 4) else \
                {base[0]: self.read_originals(base[:1])[0]}
            self.guarded([name], act, wrote)

    def _restore_actions(self) -> None:
        """The bits' enable states back and RUN/STOP back (before the values are restored), each read back
        (command 43, command 40) before it leaves the journal."""
        try:
            if self.enable_original:
                self._restore_enable_states()
        finally:  # RUN/STOP back even when an enable state could not be
            if self.run_original is not None:
                self._put_running(self.run_original)
                self.run_original = None
                if self.durable is not None:
                    self.durable.set_extra("run", None)

    def _restore_enable_states(self) -> None:
        wrong = []
        for address, disabled in sorted(self.enable_original.items(), key=lambda item: str(item[0])):
            try:
                self._put_enable_state(address, disabled)
            except HilError as exc:
                wrong.append(f"{address} (original {'disabled' if disabled else 'enabled'}): {exc}")
                continue
            del self.enable_original[address]
            if self.durable is not None:
                self.durable.drop_enable_states([str(address)])
        if wrong:
            raise HilError(f"enable states not put back: {'; '.join(wrong)}")

    def _put_enable_state(self, bit: Address, disabled: bool) -> None:
        """``bit`` disabled (forced) or enabled as ``disabled`` says — command 42 only if it is not — read back
        with command 43; WriteRefused when it does not read back so."""
        act, read = getattr(self.inner, "bit_action", None), getattr(self.inner, "read_disabled", None)
        if act is None or read is None:
            raise WriteRefused(f"{self.inner.description} has no commands 42/43")
        state = "disabled" if disabled else "enabled"
        if bool(read(bit, 1)[0]) != disabled:
            act(bit, 1 if disabled else 2)
            if bool(read(bit, 1)[0]) != disabled:
                raise WriteRefused(f"command 43 does not read back {state}")

    def _reenable(self, bits: list[Address]) -> None:
        """Command 42 "enable" for each bit, then read back with command 43; HilError naming what stays disabled."""
        act = getattr(self.inner, "bit_action", None)
        if act is None:
            raise WriteRefused(f"{self.inner.description} cannot re-enable bits (FATEK command 42)")
        for address in bits:
            act(address, 2)
        read = getattr(self.inner, "read_disabled", None)
        if read is None:
            raise WriteRefused(f"{self.inner.description} cannot read back the enable state (FATEK command 43)")
        still = [str(a) for a in bits if read(a, 1)[0]]
        if still:
            raise WriteRefused(f"{', '.join(still)} still read as disabled (command 43) after command 42 enable")

    def _put_running(self, run: bool) -> None:
        """RUN/STOP back to ``run`` and read back (command 40)."""
        if bool(self.inner.status().running) != run:
            set_running = getattr(self.inner, "set_running", None)
            if set_running is None:
                raise WriteRefused(f"RUN/STOP is not offered by {self.inner.description}")
            set_running(run)
        if bool(self.inner.status().running) != run:
            raise WriteRefused(f"the PLC does not read back {'RUN' if run else 'STOP'} after command 41")

    def _recover_actions(self, journal: Journal, report: Recovery, by_hand: bool) -> None:
        """A dead run's RUN/STOP (only with allow_destructive, and only while the PLC is still as the run set it)
        and its disabled bits (only writable ones), each read back; with ``report.show`` only said."""
        self._recover_running(journal, report, by_hand)
        names = journal.extra("disabled", [])
        if names:
            why = DISABLED.check(names)
            bits = []
            if why is None:
                try:
                    bits = [parse(n) for n in names]
                except Exception as exc:  # noqa: BLE001 - a bad name refuses the entry by name
                    why = f"not bits of this PLC: {exc}"
            refused = [str(b) for b in bits if b not in self.writable]
            if why is None and refused:
                why = f"{', '.join(refused)} not in the profile's [safety] writable"
            if why:
                report.refused.append(f"disabled bits {names}: {why}")
            elif report.show:
                report.planned.append(f"{', '.join(names)} enabled (command 42)")
            else:
                try:
                    self._reenable(bits)
                except HilError as exc:
                    report.failures.append(f"disabled bits {', '.join(names)}: {exc}")
                else:
                    report.verified.append(f"{', '.join(names)} enabled (read back, command 43)")
                    journal.set_extra("disabled", [])
        self._recover_enable_states(journal, report, by_hand)

    def _recover_running(self, journal: Journal, report: Recovery, by_hand: bool) -> None:
        """RUN/STOP back, while the PLC is still in the state the run set (:func:`still_the_runs`)."""
        run = journal.extra("run")
        if run is None:
            return
        why = RUN.check(run) or age_problem(run, by_hand)
        if why is None and not self.allow_destructive:
            why = "RUN/STOP is destructive and the profile's [safety] allow_destructive is off"
        if why is None and not hasattr(self.inner, "set_running"):
            why = f"RUN/STOP is not offered by {self.inner.description}"
        if why:
            report.refused.append(f"RUN/STOP: {why}")
            return
        state = {True: "RUN", False: "STOP"}
        now = bool(self.inner.status().running)  # read: what the PLC is in now
        decision = still_the_runs(now, run["original"], run_left(run))
        if decision == CHANGED:  # the run left it as it was; someone changed it
            report.changed.append(f"RUN/STOP is {state[now]}, the run set {state[run['wrote']]} (original "
                                  f"{state[run['original']]})")
        elif decision == BACK:
            report.back.append(f"RUN/STOP = {state[run['original']]}")
            if not report.show:
                journal.set_extra("run", None)
        elif report.show:
            report.planned.append(f"RUN/STOP = {state[run['original']]}")
        else:
            try:
                self._put_running(run["original"])
            except HilError as exc:
                report.failures.append(f"RUN/STOP (original {state[run['original']]}): {exc}")
            else:
                report.verified.append(f"RUN/STOP = {state[run['original']]}")
                journal.set_extra("run", None)

    def _recover_enable_states(self, journal: Journal, report: Recovery, by_hand: bool) -> None:
        """Each bit's journaled enable state (command 43 before the run's command 42) put back — writable bits only,
        and only while the bit is still as the run left it: its enable state the one the run set and its value
        not changed since (:meth:`_bit_verdict`) — and read back with command 43; with ``report.show`` only said."""
        act, read = getattr(self.inner, "bit_action", None), getattr(self.inner, "read_disabled", None)
        for name, entry in journal.data["enable"].items():
            why = ENABLE.check(entry) or age_problem(entry, by_hand)
            try:
                bit = parse(name) if why is None else None
            except Exception as exc:  # noqa: BLE001 - a bad name refuses the entry by name
                why = f"not a bit of this PLC: {exc}"
            if why is None and bit not in self.writable:
                why = "not in the profile's [safety] writable"
            if why is None and (act is None or read is None):
                why = f"{self.inner.description} has no commands 42/43"
            if why or bit is None or read is None:
                report.refused.append(f"enable state of {name}: {why}")
                continue
            try:
                decision = self._bit_verdict(name, bit, entry, journal.data["elements"].get(name), report, read)
            except HilError as exc:
                report.failures.append(f"enable state of {name}: reading it failed: {exc}")
                continue
            state = "disabled" if entry["disabled"] else "enabled"
            if decision == CHANGED:
                continue
            if decision == BACK:
                report.back.append(f"{name} {state} (read, command 43)")
                if not report.show:
                    journal.drop_enable_states([name])
                continue
            if report.show:
                report.planned.append(f"{name} {state} (command 42)")
                continue
            try:
                self._put_enable_state(bit, entry["disabled"])
            except HilError as exc:
                report.failures.append(f"enable state of {name} (original {state}): {exc}")
                continue
            report.verified.append(f"{name} {state} (read back, command 43)")
            journal.drop_enable_states([name])

    def _bit_verdict(self, name: str, bit: Address, entry: dict, element: dict | None, report: Recovery,
                     read: Callable[[Address, int], list[int]]) -> str:
        """What recovery does with a bit's enable state (:func:`still_the_runs`): the state the run set is the
        run's only while the bit's value is not changed since either (an operator who forced the bit at another
        value forced it: both are left) — a CHANGED one is reported here."""
        disabled, value = bool(read(bit, 1)[0]), self.read_originals([bit])[0]
        decision = still_the_runs(disabled, entry["disabled"], run_left(entry))
        touched = element is not None and ELEMENTS.check(element) is None and still_the_runs(
            value, element["original"], run_left(element) if element["wrote"] is not None else None) == CHANGED
        if decision == RESTORE and touched:
            decision = CHANGED
        if decision == CHANGED:
            shown = {True: "disabled", False: "enabled"}
            ran = f", value {' or '.join(map(str, run_left(element)))}" if element is not None and touched else ""
            report.changed.append(f"{name} is {shown[disabled]} with value {value}, the run left it "
                                  f"{' or '.join(shown[s] for s in run_left(entry))}{ran} (original "
                                  f"{shown[entry['disabled']]})")
        return decision


__all__ = ["FatekCommandsGuard"]
