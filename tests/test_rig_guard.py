"""A fault rig's coils go through the guard (hil.families.fbs.rig) over the one Modbus client: each coil's original
on disk before its first switch, put back and read back by the injector's undo, and a dead run's switched coils
put back by recovery only while they still hold what the run switched them to."""

from __future__ import annotations

import datetime as dt

import pytest

from hil.bench.profile import load_profile
from hil.bench.replay import Recovery
from hil.core.journal import Journal
from hil.families.fbs.injectors.modbus_coil import ModbusCoilSensorBreak
from hil.families.fbs.recovery import restore_rig_coils, rig_key
from hil.families.fbs.rig_identity import rig_refusal
from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.sim.rig import start_rig_modbus_tcp
from hil.families.fbs.transport.factory import open_transport
from hil.io.modbus_client import ModbusWire
from hil.io.request_policy import RequestPolicy
from tests.conftest import EMULATOR_BENCH


@pytest.fixture
def plc():
    """The PLC under test, in process (its clock running from 2026-01-01)."""
    emulator = build_emulator(load_profile(EMULATOR_BENCH), dt.datetime(2026, 1, 1))
    with open_transport("emulator", emulator_factory=lambda: emulator) as transport:
        yield transport


@pytest.fixture
def rig(plc):
    server = start_rig_modbus_tcp(plc.emulator)
    yield f"modbus+tcp://{server.address}?unit=1"
    server.stop()


@pytest.fixture
def not_the_plc(plc):
    """The identity decision recovery takes on every path, for this PLC."""
    return lambda target: rig_refusal(target, "emulator", plc, 2.0)


def _rigs(url: str) -> dict:
    """A profile's rig at ``url`` with the coils of its first bank allowed."""
    return {rig_key(url): frozenset(range(32))}


def _coil(url: str, coil: int) -> int:
    other = ModbusCoilSensorBreak(url, 0)
    try:
        return other.guard().read(coil)
    finally:
        other.close()


def test_a_coil_is_journaled_before_it_is_switched_and_put_back_by_undo(rig):
    journal = Journal("bench")
    injector = ModbusCoilSensorBreak(rig, 0, journal=journal)
    try:
        wire = injector.guard().inner.wire
        assert isinstance(wire, ModbusWire) and wire.policy == RequestPolicy(retries=2)  # the one Modbus client
        injector.open(3)
        entry = Journal("bench").load()["coils"][injector.coil_key(3)]  # on disk
        assert (entry["coil"], entry["original"], entry["wrote"]) == (3, False, True)
        assert _coil(rig, 3) == 1 and injector.opened == {3} and injector.originals == {3: False}
        injector.undo()
        assert _coil(rig, 3) == 0 and injector.opened == set() and injector.originals == {}
        assert Journal("bench").load()["coils"] == {}
    finally:
        injector.close()


def test_recovery_puts_back_only_coils_still_as_the_run_left_them(rig, not_the_plc):
    dead = ModbusCoilSensorBreak(rig, 0, journal=Journal("bench"))
    dead.open(4)
    dead.open(5)
    dead.close()  # the run dies: both coils on, both journaled
    operator = ModbusCoilSensorBreak(rig, 0)
    operator.guard().inner.write_coils([(5, 0), (5, 1), (5, 0)])  # someone switched coil 5 off since
    operator.close()
    journal = Journal("bench")
    journal.data = journal.load()
    report = Recovery("bench", str(journal.path))
    restore_rig_coils(journal, report, False, _rigs(rig), not_the_plc)
    assert report.verified == [f"rig coil {dead.coil_key(4)} = 0"]  # written and read back
    assert report.back == [f"rig coil {dead.coil_key(5)} = 0"]  # found off: read, nothing written
    assert not report.failures and not report.changed
    assert _coil(rig, 4) == 0 and Journal("bench").load()["coils"] == {}


def test_recovery_keeps_an_operators_change_and_refuses_a_rig_the_profile_does_not_name(rig, not_the_plc):
    dead = ModbusCoilSensorBreak(rig, 0, journal=Journal("bench"))
    dead.open(6)
    dead.close()
    journal = Journal("bench")
    journal.data = journal.load()
    report = Recovery("bench", str(journal.path))
    restore_rig_coils(journal, report, False, {}, not_the_plc)  # no rigs in the profile
    assert report.refused and "is not a fault rig of this profile" in report.refused[0] and _coil(rig, 6) == 1
    journal.data["coils"][dead.coil_key(6)]["wrote"] = False  # as if the run had switched it off: now it reads on
    report = Recovery("bench", str(journal.path))
    restore_rig_coils(journal, report, False, _rigs(rig), not_the_plc)
    assert report.changed == [f"rig coil {dead.coil_key(6)} reads 1, the run wrote 0 (original 0)"]
    assert _coil(rig, 6) == 1 and dead.coil_key(6) in Journal("bench").load()["coils"]
