"""``hil restore``: replay (or ``--show``) what a run that died left in a PLC's journal (:mod:`hil.core.journal`).

By hand, recovery follows the same rules as a run's (:mod:`hil.bench.replay`: this user's file, this PLC, the
profile's allow-list and switches, still the value the run wrote), except that it also takes entries older than a
run would.  ``--show`` changes nothing: it says, for each journal and each entry, what the next run does with it.
"""

from __future__ import annotations

import ipaddress
import os
import socket
from typing import TYPE_CHECKING

from rich.console import Console
from rich.markup import escape

from hil.core.errors import HilError
from hil.bench.family import open_bench
from hil.bench.profile import Profile, load_profile
from hil.core.lock import BenchLock, plc_key
from hil.core.paths import default_bench
from hil.io.url import parse_target
from hil.core.journal import inspect, journal_dir, journal_path, run_left
from hil.bench.replay import age_problem

if TYPE_CHECKING:
    from hil.core.journal import Journal


def restore(url: str | None, bench: str | None, console: Console, *, show: bool = False) -> int:
    if show:
        return _show(url, bench, console)
    if url and bench is None and not parse_target(url).in_process:
        raise HilError(f"name the profile of the PLC at {url} (--bench FILE): recovery replays only what that "
                       f"profile's [safety] allows, and the default profile is the emulator's")
    profile = load_profile(bench or default_bench())  # whichever family it is: its bench replays the journal
    target = url or profile.target
    locks = [BenchLock(target)]
    if profile.plc_id:
        locks.append(BenchLock(target, key=plc_key(target, profile.plc_id)))
    try:
        for lock in locks:
            lock.acquire()
        opened = open_bench(profile, target=target)
        try:
            report = opened.recover(by_hand=True)
        finally:
            opened.close()
    finally:
        for lock in reversed(locks):
            lock.release()
    if report is None:
        console.print(f"nothing pending: {target} is an in-process emulator (no run outlives itself)", highlight=False, soft_wrap=True)
        return 0
    console.print(escape(report.summary()), highlight=False, soft_wrap=True)
    return 0 if report.ok else 1


def _show(url: str | None, bench: str | None, console: Console) -> int:
    """Each pending journal, entry by entry, with what the next run does with it; one line for a refused file."""
    profile = None
    if url is None and bench is None:
        paths = sorted(journal_dir().glob("journal-*.json"))
    else:
        profile = load_profile(bench) if bench else None
        target = url or profile.target  # type: ignore[union-attr]
        paths = [journal_path(plc_key(target, profile.plc_id if profile else None))]
    shown = listed = 0
    for path in paths:
        if not path.exists():
            continue
        key, journal, refused = inspect(path)
        if refused:
            shown += 1
            console.print(f"[bold red]refused[/] {escape(refused)}", highlight=False, soft_wrap=True)
            continue
        assert journal is not None
        if not journal.pending:
            continue
        shown += 1
        listed += 1
        console.print(f"[bold]{escape(str(key))}[/] ({path}): pending restore"
                      + (f", written over {journal.data['endpoint']}" if journal.data.get("endpoint") else ""),
                      highlight=False, soft_wrap=True)
        for line in _verdicts(journal, profile):
            console.print(f"  {escape(line)}", highlight=False, soft_wrap=True)
        for note in _gone(str(journal.data.get("endpoint") or key), journal.data):
            console.print(f"  [yellow]{escape(note)}[/]", highlight=False, soft_wrap=True)
    if not shown:
        console.print("nothing pending: no run left a PLC changed", highlight=False, soft_wrap=True)
    elif profile is None and listed:
        console.print("(each entry also needs the PLC's profile to allow it: --bench FILE shows what it allows)",
                      highlight=False, soft_wrap=True)
    return 0


def _verdicts(journal: Journal, profile: Profile | None) -> list[str]:
    """One line per entry: what it holds, then what the next run does with it (under ``profile`` when given)."""
    writable = volatile = plugin = None
    if profile is not None:
        plugin = profile.plugin
        writable = plugin.elements(profile.safety.writable)
        volatile = plugin.elements(profile.safety.volatile)
    out = []
    for kind, name, entry in journal.entries():
        problem = kind.check(entry)
        what = kind.describe(name or kind.section, entry) if problem is None else f"{kind.section} {name or ''}".strip()
        if problem is None:
            problem = age_problem(entry, by_hand=False)
            if problem:
                problem += " — not replayed by a run"
        dropped = False
        if problem is None and kind.section == "elements" and plugin is not None and writable is not None \
                and volatile is not None:
            try:
                element = next(iter(plugin.elements([str(name)])), None)
            except (HilError, ValueError):
                element = None
            dropped = element in volatile
            if element is None:
                problem = "not an element of this PLC"
            elif not dropped and element not in writable and entry.get("wrote") is not None:
                problem = "not in the profile's [safety] writable"
            check = getattr(plugin, "value_problem", None)
            if problem is None and not dropped and check is not None:
                bad = next(filter(None, (check(element, v) for v in [entry["original"], *run_left(entry)])), None)
                problem = f"malformed: {bad}" if bad else None
        if problem is None and kind.section == "run" and profile is not None \
                and not profile.safety.allow_destructive:
            problem = "RUN/STOP needs [safety] allow_destructive"
        if problem is not None:
            out.append(f"{what}: next run refuses it ({problem}); kept")
        elif dropped:
            out.append(f"{what}: next run drops it (volatile in the profile)")
        elif kind.section == "elements" and writable is not None and element not in writable:
            out.append(f"{what}: next run restores it only if the PLC rewrites it after a write the profile allows "
                       f"(a FUN86 box's gains after its EN), else refuses it")
        elif kind.keyed and entry.get("wrote") is not None:
            out.append(f"{what}: next run restores it if it still reads "
                       f"{' or '.join(str(int(v)) for v in run_left(entry))}, else leaves it and says so")
        else:
            out.append(f"{what}: next run restores it (read back)")
    return out


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



__all__ = ["restore"]
