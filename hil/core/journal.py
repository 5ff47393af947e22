"""The durable write-ahead journal of one bench: what must be put back if this run dies.

Before the first write to an element in a test, its original value is on disk (written to a temporary file,
fsync'd, moved over the journal with :func:`os.replace`, and the directory fsync'd), together with the bench's
identity (its canonical endpoint, :func:`hil.core.lock.lock_key`), the test's id and the run's pid.  The same
goes for what a fault rig's coils held before an injection, and for the clock before a test sets it (recorded as
the PLC's time against the host's wall clock, so the restore is the same whatever the host's time zone).  An
entry leaves the journal only after its restore was written *and read back equal*.

A run that dies (SIGKILL, power cut, a lost terminal) leaves the file behind; the next run on the same bench
replays it before anything else (:meth:`hil.bench.guard.Guard.recover`) and says so, and ``hil restore`` does it by hand.

File: ``<state dir>/journal-<sha256(key)[:16]>.json`` where the state dir is ``$HIL_STATE_DIR``, else
``$XDG_STATE_HOME/hil``, else ``~/.local/state/hil`` (created with mode 0700).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import os
from pathlib import Path
from typing import Any, Iterable

from hil.core.errors import HilError

VERSION = 1


class JournalError(HilError):
    """The journal cannot be written or read (a run must not write to a PLC it cannot journal)."""


def state_dir() -> Path:
    given = os.environ.get("HIL_STATE_DIR")
    if given:
        base = Path(given)
    else:
        xdg = os.environ.get("XDG_STATE_HOME")
        base = (Path(xdg) if xdg else Path.home() / ".local" / "state") / "hil"
    base.mkdir(parents=True, exist_ok=True, mode=0o700)
    return base


def journal_path(key: str, directory: Path | None = None) -> Path:
    digest = hashlib.sha256(key.encode()).hexdigest()[:16]
    return (Path(directory) if directory else state_dir()) / f"journal-{digest}.json"


def _empty(key: str) -> dict[str, Any]:
    return {"version": VERSION, "bench": key, "elements": {}, "clock": None, "coils": {}, "enable": {}}


class Journal:
    """One bench's journal file.  Every mutation is on disk (fsync'd) when the method returns."""

    def __init__(self, key: str, directory: Path | None = None) -> None:
        self.key = key
        self.path = journal_path(key, directory)
        self.test = ""  # the test now running (its node id), written with each entry
        self.data = self.load()

    # -- reading ----------------------------------------------------------------------------------------------------
    def load(self) -> dict[str, Any]:
        try:
            raw = self.path.read_text()
        except FileNotFoundError:
            return _empty(self.key)
        except OSError as exc:
            raise JournalError(f"cannot read the bench journal {self.path}: {exc}") from None
        try:
            data = json.loads(raw)
        except ValueError as exc:
            raise JournalError(f"the bench journal {self.path} is damaged ({exc}); it lists values a crashed run "
                               f"left changed on {self.key} — check them by hand, then delete the file") from None
        for name, default in _empty(self.key).items():
            data.setdefault(name, default)
        return data

    @property
    def pending(self) -> bool:
        d = self.data
        return bool(d["elements"] or d["clock"] or d["coils"] or d.get("run") is not None or d.get("disabled")
                    or d.get("enable"))

    def extra(self, name: str, default: Any = None) -> Any:
        """``run`` (RUN/STOP before a command 41) or ``disabled`` (bits a command 42 disabled)."""
        value = self.data.get(name)
        return default if value is None else value

    def set_extra(self, name: str, value: Any) -> None:
        if self.data.get(name) != value:
            self.data[name] = value
            self._save()

    def elements(self) -> dict[str, int]:
        return {name: entry["value"] for name, entry in self.data["elements"].items()}

    def enable_states(self) -> dict[str, bool]:
        """Bit → whether it was disabled (forced, FATEK command 42) before a test first enabled or disabled it."""
        return {name: bool(entry["disabled"]) for name, entry in self.data["enable"].items()}

    def coils(self) -> dict[str, dict[str, Any]]:
        return dict(self.data["coils"])

    def clock(self) -> dict[str, Any] | None:
        return self.data["clock"]

    def describe(self) -> list[str]:
        """What is pending, for people: one line per entry."""
        d = self.data
        lines = []
        for name, entry in d["elements"].items():
            lines.append(f"{name} = {entry['value']} (0x{entry['value']:04X}) — written by {entry.get('test') or '?'}"
                         f" (pid {entry.get('pid')})")
        if d["clock"]:
            c = d["clock"]
            lines.append(f"clock: was {c['plc']} at host time {c['host']:.3f} (scale {c['scale']}) — set by "
                         f"{c.get('test') or '?'} (pid {c.get('pid')})")
        if d.get("run") is not None:
            lines.append(f"RUN/STOP: was {'RUN' if d['run'] else 'STOP'}")
        for name in d.get("disabled") or []:
            lines.append(f"{name} disabled by command 42 (to be re-enabled)")
        for name, entry in d["enable"].items():
            lines.append(f"{name} {'disabled' if entry['disabled'] else 'enabled'} (command 43) before "
                         f"{entry.get('test') or '?'} (pid {entry.get('pid')}) enabled or disabled it")
        for key, entry in d["coils"].items():
            lines.append(f"rig coil {key} = {int(entry['value'])} — injected by {entry.get('test') or '?'} "
                         f"(pid {entry.get('pid')})")
        return lines

    # -- writing (each one durable before it returns) ----------------------------------------------------------
    def _stamp(self) -> dict[str, Any]:
        return {"test": self.test, "pid": os.getpid(), "at": dt.datetime.now(dt.timezone.utc).isoformat()}

    def add_elements(self, originals: dict[str, int]) -> None:
        """Record originals; an element already journaled keeps its first (older) original."""
        fresh = {n: v for n, v in originals.items() if n not in self.data["elements"]}
        if not fresh:
            return
        stamp = self._stamp()
        for name, value in fresh.items():
            self.data["elements"][name] = {"value": int(value), **stamp}
        self._save()

    def drop_elements(self, names: Iterable[str]) -> None:
        names = [n for n in names if n in self.data["elements"]]
        if names:
            for name in names:
                del self.data["elements"][name]
            self._save()

    def set_clock(self, plc_time: dt.datetime, host: float, scale: float, **more: Any) -> None:
        """The clock before a test set it: ``plc_time`` when the host's wall clock said ``host`` (``more``: the
        host's ``boot`` id and ``since_boot`` time then, to tell a host clock stepped before recovery)."""
        if self.data["clock"] is None:
            self.data["clock"] = {"plc": plc_time.isoformat(), "host": host, "scale": scale, **more,
                                  **self._stamp()}
            self._save()

    def drop_clock(self) -> None:
        if self.data["clock"] is not None:
            self.data["clock"] = None
            self._save()

    def add_enable_states(self, states: dict[str, bool]) -> None:
        """Record bits' enable states (True: disabled) before a first command 42 enable/disable; a bit already
        journaled keeps its first (older) state.  Nothing is kept in memory unless it is on disk."""
        fresh = {n: bool(v) for n, v in states.items() if n not in self.data["enable"]}
        if fresh:
            stamp = self._stamp()
            self._commit("enable", {**self.data["enable"], **{n: {"disabled": v, **stamp} for n, v in fresh.items()}})

    def drop_enable_states(self, names: Iterable[str]) -> None:
        kept = {n: e for n, e in self.data["enable"].items() if n not in set(names)}
        if len(kept) != len(self.data["enable"]):
            self._commit("enable", kept)

    def _commit(self, name: str, value: Any) -> None:
        """``data[name] = value`` on disk; in memory only once it is (a failed save leaves both as they were)."""
        old = self.data[name]
        self.data[name] = value
        try:
            self._save()
        except JournalError:
            self.data[name] = old
            raise

    def add_coil(self, key: str, target: str, coil: int, unit: int, value: bool) -> None:
        if key not in self.data["coils"]:
            self.data["coils"][key] = {"target": target, "coil": coil, "unit": unit, "value": bool(value),
                                       **self._stamp()}
            self._save()

    def drop_coil(self, key: str) -> None:
        if self.data["coils"].pop(key, None) is not None:
            self._save()

    def _save(self) -> None:
        directory = self.path.parent
        try:
            if not self.pending:
                try:
                    os.unlink(self.path)
                except FileNotFoundError:
                    return
            else:
                self.data["bench"] = self.key
                tmp = directory / f".{self.path.name}.{os.getpid()}.tmp"
                fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW, 0o600)
                try:
                    os.write(fd, json.dumps(self.data, indent=1, sort_keys=True).encode())
                    os.fsync(fd)
                finally:
                    os.close(fd)
                os.replace(tmp, self.path)
            dfd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY)
            try:
                os.fsync(dfd)
            finally:
                os.close(dfd)
        except OSError as exc:
            raise JournalError(f"cannot write the bench journal {self.path}: {exc} — refusing to write to the PLC "
                               f"without its originals on disk") from None


__all__ = ["Journal", "JournalError", "journal_path", "state_dir"]
