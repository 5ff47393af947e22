"""``hil restore``: replay (or ``--show``) what a run that died left in a bench's journal (:mod:`hil.core.journal`)."""

from __future__ import annotations

import json

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


def _target(url: str | None, bench: str | None) -> str:
    if url:
        return url
    if bench is None:
        raise HilError("name a target URL or a bench profile (--bench FILE)")
    from hil.bench.profile import load_profile
    return load_profile(bench).target


__all__ = ["restore"]
