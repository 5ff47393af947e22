"""Hooks the hil pytest plugin offers to other plugins (conftest files, test helpers)."""

from __future__ import annotations

import datetime as dt

import pytest

from hil.bench.profile import Profile
from hil.sim.engine import Engine


@pytest.hookspec(firstresult=True)
def pytest_hil_make_emulator(profile: Profile, epoch: dt.datetime) -> Engine | None:
    """Return the Emulator to use for an ``emulator…`` target, or None for the default build.

    The harness's own tests use this to run the suites against deliberately broken emulators.
    """
