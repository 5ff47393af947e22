"""``hil restore``: replay (or ``--show``) what a run that died left in a bench's journal (:mod:`hil.core.journal`)."""

from __future__ import annotations

import ipaddress
import json
import os
import socket

from rich.console import Console
from rich.markup import escape

from hil.core.errors import HilError


def restore(url: str | None, bench: str | None, console: Console, *, show: bool = False) -> int:
    from hil.core.lock import lock_key
    from hil.core.journal import Journal, state_dir
    if show:
        if url is None and bench is None:
            paths = sorted(state_dir().glob("journal-*.json"))
            keys = []
            for path in paths:
                try:
                    keys.append(json.loads(path.read_text()).get("bench", "?"))
                except (OSError, ValueError):
                    keys.append(f"? (unreadable {path})")
        else:
            keys = [lock_key(_target(url, bench))]
        shown = 0
        for key in keys:
            journal = Journal(key)
            if not journal.pending:
                continue
            shown += 1
            console.print(f"[bold]{escape(key)}[/] ({journal.path}): pending restore", highlight=False)
            for line in journal.describe():
                console.print(f"  {escape(line)}", highlight=False)
            for note in _gone(key, journal.data):
                console.print(f"  [yellow]{escape(note)}[/]", highlight=False)
        if not shown:
            console.print("nothing pending: no run left a PLC changed", highlight=False)
        return 0
    from hil.bench.family import open_bench
    from hil.bench.profile import load_profile
    from hil.core.lock import BenchLock
    from hil.core.paths import default_bench
    profile = load_profile(bench or default_bench())  # whichever family it is: its bench replays the journal
    target = url or profile.target
    with BenchLock(target).acquire():
        opened = open_bench(profile, target=target)
        try:
            report = opened.recover()
        finally:
            opened.close()
    if report is None:
        console.print(f"nothing pending: {target} is an in-process emulator (no run outlives itself)", highlight=False)
        return 0
    console.print(escape(report.summary()), highlight=False)
    return 0 if report.ok else 1


def _pids(data: object) -> set[int]:
    """Every run's pid a journal names (its entries carry the writer's)."""
    if isinstance(data, dict):
        found = {data["pid"]} if isinstance(data.get("pid"), int) else set()
        return found.union(*(_pids(v) for v in data.values()))
    if isinstance(data, list):
        return set().union(*(_pids(v) for v in data))
    return set()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: it exists
        return True
    return True


def _gone(key: str, data: object) -> list[str]:
    """What no longer exists behind a journal: the runs that wrote it, an emulator's loopback port or pty (a
    journal of an emulator that has stopped cannot be replayed, and needs none)."""
    notes = []
    dead = sorted(p for p in _pids(data) if not _alive(p))
    if dead:
        notes.append(f"the run(s) that wrote this (pid {', '.join(map(str, dead))}) are no longer running: "
                     f"the next run on this PLC replays it, or hil restore does now")
    scheme, _, rest = key.partition("://")
    if scheme == "serial" and not os.path.exists(rest):
        notes.append(f"{rest} no longer exists (an emulator's pseudo-terminal that has closed?): nothing to restore "
                     f"there; delete the journal if that PLC is gone for good")
    elif scheme == "tcp":
        host, _, port = rest.rpartition(":")
        host = host.strip("[]")
        if port.isdigit() and _loopback(host) and not _listening(host, int(port)):
            notes.append(f"nothing listens on {rest} now (an emulator that has stopped?): nothing to restore there; "
                         f"delete the journal if that PLC is gone for good")
    return notes


def _loopback(host: str) -> bool:
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _listening(host: str, port: int) -> bool:
    try:
        with socket.create_connection((host, port), timeout=0.5):
            return True
    except OSError:
        return False


def _target(url: str | None, bench: str | None) -> str:
    if url:
        return url
    if bench is None:
        raise HilError("name a target URL or a bench profile (--bench FILE)")
    from hil.bench.profile import load_profile
    return load_profile(bench).target


__all__ = ["restore"]
