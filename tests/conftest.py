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
