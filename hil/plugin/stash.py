"""The one typed stash key of the session's bench state: ``config.stash[BENCH_SESSION]`` is the hil plugin's
session (:class:`~hil.plugin.pytest_plugin.BenchSession`: ``profile``, ``target``, ``bench`` once open, ``error``,
``recovery``), for the plugins beside it (safety, preflight, reporting, wire statistics) and anyone else's.  The key
and the state's surface (:class:`BenchState`) live here, below all of them, so that none imports another plugin —
not even for a type — to reach it."""

from __future__ import annotations

from typing import Protocol

import pytest

from hil.bench.base import BenchBase
from hil.bench.lab.session import LabSession
from hil.bench.profile import Profile
from hil.bench.replay import Recovery
from hil.core.lock import BenchLock


class BenchState(Protocol):
    """The session's bench state, as the plugins use it."""

    bench: BenchBase | None  # once opened
    error: str | None  # why the bench could not be opened
    dead: str | None  # the PLC stopped answering: later tests error with this reason
    recovery: Recovery | None  # what a dead run left, replayed when the bench opened
    lab: LabSession | None  # the labgrid place held for this session
    lock: BenchLock | None  # on a real bench, held until unconfigure
    place_lock: BenchLock | None  # keyed on the labgrid place
    plc_lock: BenchLock | None  # keyed on the profile's [bench] plc_id
    plc_line: str  # the header's "hil PLC: …" line, once written ("" before)
    header_panel: bool  # the console output's panel shows that line instead

    @property
    def profile(self) -> Profile: ...

    @property
    def target(self) -> str: ...

    @property
    def leased(self) -> bool: ...

    def open(self) -> BenchBase: ...

    def finish(self, request: pytest.FixtureRequest, bench: BenchBase) -> None: ...

    def close_wire(self) -> None: ...

    def release(self) -> None: ...


BENCH_SESSION: pytest.StashKey[BenchState] = pytest.StashKey()

__all__ = ["BENCH_SESSION", "BenchState"]
