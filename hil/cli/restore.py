"""``hil restore``: replay (or ``--show``) what a run that died left in a PLC's journal (:mod:`hil.core.journal`).

By hand, recovery follows the same rules as a run's (:mod:`hil.bench.replay`: this user's file, this PLC, the
profile's allow-list and switches, still the value the run wrote), except that it also takes entries older than a
run would, and — with ``--accept-host-clock`` — a clock origin from another boot of the host.  ``--show`` writes
nothing: it lists every journal it finds (whose, which bench) and, with the PLC's profile, what a restore would do
with each entry, decided by the very code a restore runs (:meth:`hil.bench.guard.Guard.recover`, ``show``) on
what the PLC holds now.
"""

from __future__ import annotations

import argparse
import contextlib
import ipaddress
import os
import socket
from collections.abc import Callable, Iterator
from pathlib import Path

from rich.console import Console
from rich.markup import escape

from hil.bench.family import open_bench
from hil.bench.profile import Profile, load_profile
from hil.bench.recovery import Recovery
from hil.cli.parser import Subparsers
from hil.core.errors import HilError
from hil.core.journal import Journal, inspect, journal_dir
from hil.core.lock import bench_locks, lock_key
from hil.core.paths import default_bench
from hil.io.url import parse_target


def restore(url: str | None, bench: str | None, console: Console, *, show: bool = False,
            accept_host_clock: bool = False) -> int:
    if show:
        return _show(url, bench, console)
    if url and bench is None and not parse_target(url).in_process:
        raise HilError(f"name the profile of the PLC at {url} (--bench FILE): recovery replays only what that "
                       f"profile's [safety] allows, and the default profile is the emulator's")
    profile = load_profile(bench or default_bench())  # whichever family it is: its bench replays the journal
    with _locked(profile, url or profile.target) as target:
        opened = open_bench(profile, target=target)
        try:
            report = opened.recover(by_hand=True, accept_host_clock=accept_host_clock)
        finally:
            opened.close()
    if report is None:
        console.print(f"nothing pending: {target} is an in-process emulator (no run outlives itself)",
                      highlight=False, soft_wrap=True)
        return 0
    console.print(escape(report.summary()), highlight=False, soft_wrap=True)
    return 0 if report.ok else 1


@contextlib.contextmanager
def _locked(profile: Profile, target: str) -> Iterator[str]:
    """The bench's locks (its endpoint's, and its PLC's when the profile names it), as a run takes them."""
    with contextlib.ExitStack() as stack:
        for lock in bench_locks(target, profile.plc_id):
            stack.enter_context(lock)
        yield target


Say = Callable[..., None]  # a line on the console: say(text, style="")


def _show(url: str | None, bench: str | None, console: Console) -> int:
    """Every journal found, whose and which bench's, and — for the profile's PLC — what a restore would do with
    each entry on what the PLC holds now (read, nothing written); a refused file in one line."""
    def say(text: str, style: str = "") -> None:
        console.print(f"[{style}]{escape(text)}[/]" if style else escape(text), highlight=False, soft_wrap=True)

    planned: dict[Path, Recovery] = {}
    if bench is not None or (url and parse_target(url).in_process):
        profile = load_profile(bench or default_bench())
        planned = _plan(profile, url or profile.target, say)
    shown = 0
    for path, key, journal, refused in _journals(url, bench):
        shown += 1
        if refused:
            say(f"refused {refused}", "bold red")
        elif journal is not None:
            _show_journal(say, path, key, journal, planned.get(path))
    if not shown:
        say("nothing pending: no run left a PLC changed")
    return 0


def _journals(url: str | None, bench: str | None) -> Iterator[tuple[Path, str, Journal | None, str | None]]:
    """Each journal file to list: (its path, its key, the journal or None, why it is refused or None) — one left
    pending or refused; with a URL and no profile, only the journals of the PLC at that URL."""
    for path in sorted(journal_dir().glob("journal-*.json")):
        key, journal, refused = inspect(path)
        if url and bench is None and journal is not None and lock_key(url) not in (key, journal.data.get("endpoint")):
            continue
        if refused or (journal is not None and journal.pending):
            yield path, str(key), journal, refused


def _show_journal(say: Say, path: Path, key: str, journal: Journal, part: Recovery | None) -> None:
    """One journal: whose, what a restore would do with each entry (``part``: decided by the restore's own code,
    :meth:`hil.bench.guard.Guard.recover` with ``show``) or, without the PLC's profile, what it holds."""
    say(_header(path, key, journal), "bold")
    if part is not None:
        for label, lines in part.sections():
            for line in lines:
                say(f"  {label}: {line}")
    else:
        for line in journal.describe():
            say(f"  {line}")
        say("  what a restore would do: needs the PLC's profile to read it — hil restore --show --bench FILE",
            "yellow")
    for note in _gone(str(journal.data.get("endpoint") or key), journal.data):
        say(f"  {note}", "yellow")


def _plan(profile: Profile, target: str, say: Say) -> dict[Path, Recovery]:
    """What a restore would do with each journal of the profile's PLC (by file): the restore's own decisions
    (:meth:`hil.bench.guard.Guard.recover` with ``show``), on the PLC read now under the bench's locks.  Empty,
    and said, when a run holds the bench (its PLC is not read behind that run's back)."""
    try:
        with _locked(profile, target):
            opened = open_bench(profile, target=target)
            try:
                report = opened.recover(by_hand=True, show=True)
            finally:
                opened.close()
    except HilError as exc:
        say(f"{target} not read ({exc}): its journals are listed as they are", "yellow")
        return {}
    return {} if report is None else {Path(part.path): part for part in report.parts}


def _header(path: Path, key: str, journal: Journal) -> str:
    """Whose journal it is (each run's user and pid, :meth:`Journal.left_by`) and which bench's (its key, the wire
    written over)."""
    where = f", written over {journal.data['endpoint']}" if journal.data.get("endpoint") else ""
    lane = f", lane {journal.lane}" if journal.lane else ""
    return f"{key}{lane} ({path}): pending restore — left by {journal.left_by()}{where}"


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


# -- the command line -----------------------------------------------------------------------------------------------
def add_parser(sub: Subparsers, summary: str) -> None:
    parser = sub.add_parser("restore", help=summary,
                            description="Every run journals each value before it first writes it (on disk, "
                                        "fsync'd); a run that dies leaves the journal behind and the next run on "
                                        "that PLC replays it first. This does it by hand, holding the bench lock.",
                            epilog="examples:\n  hil restore --bench my-bench.toml\n"
                                   "  hil restore --show                 (every bench's pending journal)\n"
                                   "  hil restore --show --bench my-bench.toml   (and what a restore would do, "
                                   "read from the PLC)\n"
                                   "  hil restore --show fatek+tcp://192.168.1.5\n")
    parser.add_argument("url", nargs="?", help="target URL (default: the --bench profile's target)")
    parser.add_argument("--bench", metavar="FILE", help="bench profile (its target, timeout and time scale)")
    parser.add_argument("--show", action="store_true",
                        help="list every journal (whose, which bench) and, with --bench, what a restore would do "
                             "with each entry on the PLC as it reads now; write nothing")
    parser.add_argument("--accept-host-clock", action="store_true",
                        help="set the PLC's clock from a journal written during another boot of this host, on the "
                             "host clock as it is now (whether it was stepped since cannot be checked)")
    parser.set_defaults(func=command)


def command(args: argparse.Namespace, console: Console) -> int:
    return restore(args.url, args.bench, console, show=args.show, accept_host_clock=args.accept_host_clock)
