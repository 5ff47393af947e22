"""Hooks the hil pytest plugin offers to other plugins (conftest files, test helpers)."""

from __future__ import annotations

import pytest


@pytest.hookspec(firstresult=True)
def pytest_hil_make_emulator(profile, epoch):  # noqa: ANN001, ANN201
    """Return the Emulator to use for an ``emulator…`` target, or None for the default build.

    The harness's own tests use this to run the suites against deliberately broken emulators.
    """
