"""Recovery first: replay what a dead run left in a bench's journal (:mod:`hil.core.journal`), verify it, say so.

Every run on a real bench (the pytest plugin, ``hil run``, each writing CLI command) calls :func:`recover` after
taking the bench lock and before anything else; ``hil restore --bench FILE`` calls it by hand.  What is
restored, in this order:

1. the fault rig's coils, each to the state it held before the injection (read back to verify);
2. the clock, to its original offset from the host's wall clock (the PLC's time then, carried forward by the
   time that has passed since, times the profile's time scale), with the manual's M1952 procedure;
3. every journaled element (written, then all read back equal).

Each entry leaves the journal only once verified; what fails stays for the next attempt.
"""

from __future__ import annotations

import datetime as dt
import time
from dataclasses import dataclass, field
from typing import Any

from hil.core.errors import HilError, TransportError
from hil.core.journal import Journal


@dataclass
class Recovery:
    bench: str
    path: str
    pending: list[str] = field(default_factory=list)  # what the journal held, one line each
    failures: list[str] = field(default_factory=list)  # what could not be restored (still in the journal)

    @property
    def needed(self) -> bool:
        return bool(self.pending)

    @property
    def ok(self) -> bool:
        return not self.failures

    def summary(self) -> str:
        if not self.needed:
            return f"hil bench recovery: nothing pending for {self.bench}"
        if self.ok:
            return (f"hil bench recovery: a previous run on {self.bench} died leaving {len(self.pending)} value(s) "
                    f"changed — restored and verified: " + "; ".join(self.pending))
        return (f"hil bench recovery FAILED on {self.bench}: still unrestored (kept in {self.path}): "
                + "; ".join(self.failures))


def recover(journal: Journal, transport: Any, timebase: Any) -> Recovery:
    """Replay ``journal`` onto the PLC behind ``transport`` (a direct, unguarded transport)."""
    journal.data = journal.load()
    report = Recovery(journal.key, str(journal.path), journal.describe())
    if not journal.pending:
        return report
    _coils(journal, report)
    _actions(journal, transport, report)
    _clock(journal, transport, timebase, report)
    _elements(journal, transport, report)
    return report


def _actions(journal: Journal, transport: Any, report: Recovery) -> None:
    """Bits disabled with command 42 re-enabled; RUN/STOP as it was before a command 41."""
    disabled = journal.extra("disabled", [])
    if disabled:
        try:
            for name in disabled:
                transport.bit_action(name, 2)
        except Exception as exc:  # noqa: BLE001
            report.failures.append(f"re-enabling {', '.join(disabled)}: {exc}")
        else:
            journal.set_extra("disabled", [])
    run = journal.extra("run")
    if run is not None:
        try:
            if bool(transport.status().running) != bool(run):
                transport.set_running(bool(run))
        except Exception as exc:  # noqa: BLE001
            report.failures.append(f"RUN/STOP (was {'RUN' if run else 'STOP'}): {exc}")
        else:
            journal.set_extra("run", None)


def _coils(journal: Journal, report: Recovery) -> None:
    from hil.families.fbs.faults import ModbusCoilSensorBreak
    for key, entry in journal.coils().items():
        rig = ModbusCoilSensorBreak(entry["target"], entry["coil"])
        try:
            rig._write(0, bool(entry["value"]))
            if rig._read(entry["coil"]) != bool(entry["value"]):
                raise HilError("does not read back")
        except Exception as exc:  # noqa: BLE001 - every entry is tried; failures are listed
            report.failures.append(f"rig coil {key} (original {int(entry['value'])}): {exc}")
            continue
        finally:
            rig.close()
        journal.drop_coil(key)


def _clock(journal: Journal, transport: Any, timebase: Any, report: Recovery) -> None:
    entry = journal.clock()
    if not entry:
        return
    from hil.families.fbs.device.plc import FbsPlc
    plc0 = dt.datetime.fromisoformat(entry["plc"])
    host0, scale = float(entry["host"]), float(entry["scale"])

    def original() -> dt.datetime:
        return plc0 + dt.timedelta(seconds=(time.time() - host0) * scale)

    try:
        result = FbsPlc(transport, timebase).rtc.sync_to(original)
        if not result.accepted:
            raise HilError(f"the PLC refused {result.sent} (M1955 = 1)")
    except Exception as exc:  # noqa: BLE001
        report.failures.append(f"RTC (original {plc0}, offset kept from host time): {exc}")
        return
    journal.drop_clock()


def _elements(journal: Journal, transport: Any, report: Recovery) -> None:
    items = list(journal.elements().items())
    if not items:
        return
    for attempt in (1, 2):
        try:
            transport.write_many(items)
            now = transport.read_many([name for name, _ in items])
        except TransportError as exc:
            if attempt == 1:
                try:
                    transport.reopen()
                    continue
                except HilError:
                    pass
            report.failures += [f"{name} (original {value}): {exc}" for name, value in items]
            return
        break
    good = [name for (name, value), got in zip(items, now) if got == value]
    report.failures += [f"{name} (original {value}): reads {got} after restore"
                        for (name, value), got in zip(items, now) if got != value]
    journal.drop_elements(good)


__all__ = ["Recovery", "recover"]
