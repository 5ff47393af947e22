"""A fault rig's coils (a Modbus relay module, ``[faults.*] kind = "modbus-coil"``): reached through the one Modbus
client, switched only through the guard.

:class:`GuardedRig` is the guard (:class:`hil.bench.guard.GuardedLink`) round the rig's
:class:`~hil.io.modbus_client.ModbusWire`, with plain coil numbers for elements: a coil's original is read and
journaled (on disk first, in the journal's ``coils`` section, :class:`CoilJournal`) before its first switch, and
:meth:`~hil.bench.guard.Guard.restore` writes every original back and reads it back — an entry leaves the journal
only once verified, a failed one stays for the next restore.  Recovery (:meth:`GuardedRig.replay`) puts back what a
dead run left switched, through the same restore, only while a coil still holds what the run switched it to.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from hil.bench.guard import GuardedLink
from hil.bench.lab.resolve import ranges
from hil.bench.replay import BACK, CHANGED, Recovery, changed_line, still_the_runs
from hil.core.errors import RestoreError
from hil.core.journal import Journal, run_left
from hil.core.lock import lock_key
from hil.io.modbus_client import COILS, HOLDING, ModbusWire, Probe
from hil.io.status import PlcStatus
from hil.io.url import Target

#: what proves a relay module answers and resynchronises its RTU line: holding register 0 ([our choice]: the
#: emulator's rig serves it; on TCP a new connection resynchronises and no probe is read)
RIG_PROBE = Probe(0, 1)
MAX_COILS = 2000  # coils one FC01 read may ask for


def rig_unit(target: Target) -> int:
    """The Modbus unit a rig's target names (``?unit=``, an int once hil.io.url has read it), else 1."""
    return int(str(target.params.get("unit", 1)))


def rig_wire(target: Target, timeout: float, retries: int = 2) -> ModbusWire:
    """The one Modbus client to a fault rig at ``target`` (``modbus+tcp://…``, ``modbus+rtu://…``, RFC 2217)."""
    unit = rig_unit(target)
    hint = "is the relay module powered and wired, and are its unit id and address right?"
    if target.scheme == "modbus+tcp":
        return ModbusWire.tcp(target.host, target.port, unit=unit, timeout=timeout, retries=retries, hint=hint,
                              probe=RIG_PROBE, description=f"{target} (fault rig)", describe=_coils)
    p = target.params
    return ModbusWire.rtu(target.serial_port, baudrate=int(str(p.get("baudrate", 9600))),
                          parity=str(p.get("parity", "E")), bytesize=int(str(p.get("bytesize", 8))),
                          stopbits=int(str(p.get("stopbits", 1))), unit=unit,
                          timeout=timeout, retries=retries, hint=hint, probe=RIG_PROBE, label="fault rig",
                          describe=_coils)


def coil_runs(coils: Iterable[int]) -> list[tuple[int, int]]:
    """The coils as runs of consecutive numbers (first, count), each at most one FC01 read long."""
    runs: list[tuple[int, int]] = []
    for coil in sorted(set(coils)):
        if runs and coil == sum(runs[-1]) and runs[-1][1] < MAX_COILS:
            runs[-1] = (runs[-1][0], runs[-1][1] + 1)
        else:
            runs.append((coil, 1))
    return runs


def _coils(table: str, address: int, count: int) -> str:
    return f"{table} {address}" + (f"–{address + count - 1}" if count > 1 else "")


@dataclass(frozen=True)
class RigCoil:
    """One coil of one rig: its number, and its name in the journal (``<endpoint>#unit<u>/coil<n>``)."""

    key: str
    coil: int

    def __str__(self) -> str:
        return self.key


class RigLink:
    """A relay module's coils over the one Modbus client, by coil number: the public link the guard wraps."""

    emulator = None

    def __init__(self, wire: ModbusWire) -> None:
        self.wire = wire
        self.description = wire.description

    @property
    def requests(self) -> int:
        return self.wire.requests

    def read_coils(self, coils: list[int]) -> list[int]:
        """Each coil's state (0/1): one request per run of consecutive coils, never across a gap (a rig's banks
        may have coils it does not serve between them)."""
        states: dict[int, int] = {}
        for first, count in coil_runs(coils):
            states.update(zip(range(first, first + count), self.wire.read(COILS, first, count)))
        return [states[c] for c in coils]

    def write_coils(self, items: list[tuple[int, int]]) -> None:
        """Switch coils, in order (each never repeated when its reply is lost: the request policy's rule)."""
        for coil, value in items:
            self.wire.write(COILS, coil, [int(value)])

    def read_registers(self, address: int, count: int) -> list[int]:
        return self.wire.read(HOLDING, address, count)

    def status(self) -> PlcStatus:
        return PlcStatus(running=None, via="modbus", identity={"transport": self.description})

    def unreachable_reason(self, name: Any) -> str | None:
        return None

    def budget(self, write: bool = False) -> float | None:
        return self.wire.budget(write)

    def reopen(self) -> None:
        self.wire.reopen()

    def close(self) -> None:
        self.wire.close()

    def exclusive(self) -> contextlib.AbstractContextManager[None]:
        """Nothing to hold: a rig's wire is this link's alone, and each request on it is whole by itself."""
        return contextlib.nullcontext()


class CoilJournal:
    """The journal's ``coils`` section for one rig, as the guard's durable journal (``add_elements`` /
    ``drop_elements`` with coil keys; coil originals and states as booleans)."""

    def __init__(self, journal: Journal, target: Target, unit: int, guard: GuardedRig) -> None:
        self.journal, self.target, self.unit, self.guard = journal, target, unit, guard

    @property
    def failed(self) -> str | None:
        return self.journal.failed

    def add_elements(self, originals: dict[str, int], wrote: dict[str, int | None] | None = None) -> None:
        wrote = wrote or {}
        for key in dict.fromkeys([*originals, *wrote]):
            coil = self.guard.coil(key)
            original = originals[key] if key in originals else self.guard.journal.get(coil)
            state = wrote.get(key)
            self.journal.add_coil(key, str(self.target), coil.coil, self.unit, bool(original),
                                  wrote=None if state is None else bool(state))

    def drop_elements(self, names: Iterable[str]) -> None:
        for key in names:
            self.journal.drop_coil(key)


class GuardedRig(GuardedLink):
    """The guard round a rig's coils: ``writable`` coil numbers only, originals journaled before the first switch,
    restored and read back."""

    inner: RigLink

    def __init__(self, target: Target, link: RigLink, writable: Iterable[int], journal: Journal | None = None) -> None:
        self.target = target
        self.unit = rig_unit(target)
        self._prefix = f"{lock_key(str(target))}#unit{self.unit}/coil"
        super().__init__(link, [self.coil(c) for c in writable])
        if journal is not None:
            # the guard's durable journal, for coils: the methods the guard calls, kept in the journal's coils section
            self.durable = CoilJournal(journal, target, self.unit, self)  # type: ignore[assignment]  # not a Journal

    def coil(self, name: int | str | RigCoil) -> RigCoil:
        """The element for a coil number, its journal key, or itself."""
        if isinstance(name, RigCoil):
            return name
        if isinstance(name, str):  # a journal key, kept as written (a dead run's may name its URL otherwise)
            return RigCoil(name, int(name.rpartition("/coil")[2]))
        return RigCoil(f"{self._prefix}{int(name)}", int(name))

    # -- the guard's address model --------------------------------------------------------------------------
    def split(self, name: Any) -> list[RigCoil]:
        return [self.coil(name)]

    def read_originals(self, elements: list[RigCoil]) -> list[int]:
        return self.inner.read_coils([e.coil for e in elements])

    def write_back(self, items: list[tuple[RigCoil, int]]) -> None:
        self.inner.write_coils([(e.coil, v) for e, v in items])

    # -- switching ----------------------------------------------------------------------------------------------
    def switch(self, coil: int, on: bool) -> None:
        """Coil ``coil`` on or off, its original journaled first."""
        element = self.coil(coil)
        self.guarded([element], lambda: self.inner.write_coils([(coil, int(on))]), {element: int(on)})

    def read(self, coil: int) -> int:
        return self.inner.read_coils([coil])[0]

    # -- recovery -----------------------------------------------------------------------------------------------
    def replay(self, entries: dict[str, dict[str, Any]], report: Recovery) -> None:
        """A dead run's coil ``entries`` (checked by the caller): each back to its original through the restore,
        only while it still holds what the run switched it to (or its original: then it is only dropped), and only
        a coil of this guard's allow-list.  Each run of consecutive coils is read and put back on its own, so a
        coil the rig fails leaves the others to be put back."""
        elements = self._replayable(entries, report)
        for first, count in coil_runs(e.coil for e in elements):
            self._replay_run([e for e in elements if first <= e.coil < first + count], entries, report)

    def _replayable(self, entries: dict[str, dict[str, Any]], report: Recovery) -> list[RigCoil]:
        """The entries' coils this guard may write back; the others refused by name (their entries stay)."""
        allowed = {e.coil for e in self.writable}
        out = []
        for key, entry in entries.items():
            coil = int(entry["coil"])
            if not key.endswith(f"/coil{coil}"):
                why = f"its key does not name coil {coil}, its entry's — check the journal (hil restore --show)"
            elif coil not in allowed:
                why = (f"coil {coil} is not one the profile lets its injectors switch on {self.target} "
                       f"({ranges(frozenset(allowed)) or 'none'}): put it back by hand, or name it in [faults.*] coils")
            else:
                out.append(RigCoil(key, coil))
                continue
            report.refused.append(f"rig coil {key}: {why}; left as it is, the entry kept")
        return out

    def _replay_run(self, elements: list[RigCoil], entries: dict[str, dict[str, Any]], report: Recovery) -> None:
        try:
            states = self.read_originals(elements)
        except Exception as exc:  # noqa: BLE001 - nothing is written without knowing what is there
            report.failures += [f"rig coil {e} (original {int(entries[e.key]['original'])}): {exc}" for e in elements]
            return
        back, again = [], []
        for element, value in zip(elements, states):
            entry = entries[element.key]
            # (coils as 0/1: the journal may hold them as booleans) — the one rule recovery uses for every entry
            original, now = int(bool(entry["original"])), int(bool(value))
            left = [int(bool(v)) for v in run_left(entry)] if entry["wrote"] is not None else None
            verdict = still_the_runs(now, original, left)
            if verdict == BACK:
                back.append(element)
            elif verdict == CHANGED:
                report.changed.append(changed_line(f"rig coil {element}", now, left or [], original))
            else:
                self.journal[element] = int(original)
                again.append(element)
        failed: set[str] = set()
        if again:
            try:
                self.restore()
            except RestoreError as exc:
                for name, value, why in exc.failures:
                    failed.add(str(name))
                    report.failures.append(f"rig coil {name} (original {int(value)}): {why}")
        for element in again:  # a failed one stays on disk for the next recovery, not retried with the next coils
            self.journal.pop(element, None)
        restored = [e for e in again if e.key not in failed]
        if self.durable is not None:  # what read back as its original (a restored one is dropped already)
            self.durable.drop_elements(e.key for e in back + restored)
        for found, lines in ((back, report.back), (restored, report.verified)):
            lines += [f"rig coil {e} = {int(entries[e.key]['original'])}" for e in elements if e in found]


__all__ = ["CoilJournal", "GuardedRig", "RIG_PROBE", "RigCoil", "RigLink", "coil_runs", "rig_unit", "rig_wire"]
