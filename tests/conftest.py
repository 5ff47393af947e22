"""Shared fixtures for the harness's own tests."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
EMULATOR_BENCH = REPO / "fixtures" / "benches" / "emulator.toml"
EMULATOR_TARGETS = ["emulator", "emulator+fatek-tcp", "emulator+fatek-serial", "emulator+modbus-tcp",
                    "emulator+modbus-rtu"]

pytest_plugins = ["pytester"]


@pytest.fixture
def emulator():
    from hil.families.fbs.sim import Emulator
    return Emulator()


@pytest.fixture(autouse=True)
def _private_hil_state(tmp_path_factory, monkeypatch):
    """Each test's bench journals and locks in its own directories, never the user's (hil.core.journal, hil.core.lock)."""
    base = tmp_path_factory.mktemp("hil-state")
    monkeypatch.setenv("HIL_STATE_DIR", str(base / "state"))
    monkeypatch.setenv("HIL_HISTORY_URL", "off")  # the run history only where a test turns it on (test_history*)
    if "HIL_LOCK_DIR" not in __import__("os").environ:
        monkeypatch.setenv("HIL_LOCK_DIR", str(base / "locks"))


@pytest.fixture(autouse=True)
def _no_process_left_behind():
    """What a test started in a group of its own (tests/processes.py) and did not end — it failed or was
    interrupted first — is ended here: an interrupted run leaves no ``hil emulate`` or worker behind."""
    from tests import processes
    before = processes.running()  # a module's or the session's emulator: ended by its own fixture
    yield
    processes.end_all(but=before)

