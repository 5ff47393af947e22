"""The one typed stash key of the session's bench state: ``config.stash[BENCH_SESSION]`` is the hil plugin's
:class:`~hil.plugin.pytest_plugin.BenchSession` (``profile``, ``target``, ``bench`` once open, ``error``,
``recovery``), for the plugins beside it (safety, preflight, reporting, wire statistics) and anyone else's.  It lives
here, below all of them, so that none imports another plugin to reach it."""

from __future__ import annotations

from typing import TYPE_CHECKING

import pytest

if TYPE_CHECKING:
    from hil.plugin.pytest_plugin import BenchSession

BENCH_SESSION: pytest.StashKey[BenchSession] = pytest.StashKey()

__all__ = ["BENCH_SESSION"]
