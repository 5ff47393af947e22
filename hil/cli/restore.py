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
    from hil.cli.target import open_target
    from hil.families.fbs.recovery import recover
    with open_target(url, bench) as opened:  # not writing=True: that would replay it before we report it
        target = url or opened.profile.target  # type: ignore[union-attr]
        from hil.core.lock import BenchLock
        with BenchLock(target).acquire():
            report = recover(Journal(lock_key(target)), opened.transport, opened.timebase)
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
