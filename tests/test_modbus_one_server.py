"""One engine-over-Modbus server (hil.sim.modbus_engine) for every address map: what the FBs server does on the
wire (requests of a segment answered in order, strict quantities and functions, the unit gate, wire faults) holds
for the S7-200 SMART map and the fault rig too.  Raw MBAP frames, so nothing of hil's client decides."""

from __future__ import annotations

import datetime as dt

import pytest

from hil.bench.profile import load_profile
from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.sim.models.temperature import TemperatureModel
from hil.families.fbs.sim.rig import start_rig_modbus_tcp
from hil.families.s7smart.protocol.modbus_map import S7ModbusMap
from hil.families.s7smart.sim.emulator import S7Emulator
from hil.families.s7smart.sim.serve_modbus import start_s7_modbus_tcp
from hil.sim.modbus_engine import Tables
from hil.sim.wire_faults import WireFaults
from tests.conftest import REPO
from tests.test_wire_fidelity import adu, exchange, pdu_of

EMULATOR_BENCH = REPO / "fixtures" / "benches" / "emulator.toml"


@pytest.fixture
def s7():
    emulator = S7Emulator()
    emulator.memory.write_bytes("V", 0, bytes([0x12, 0x34, 0x56, 0x78]))
    emulator.memory.set("Q0.1", 1)
    faults = WireFaults()
    handle = start_s7_modbus_tcp(emulator, S7ModbusMap(0, 100), faults=faults)
    host, port = handle.address.rsplit(":", 1)
    yield emulator, (host, int(port)), faults
    handle.stop()


@pytest.fixture
def rig():
    emulator = build_emulator(load_profile(EMULATOR_BENCH), dt.datetime(2024, 2, 28, 12))
    faults = WireFaults()
    handle = start_rig_modbus_tcp(emulator, first_coil=16, faults=faults)
    host, port = handle.address.rsplit(":", 1)
    yield emulator, (host, int(port)), faults
    handle.stop()


# -- the S7-200 SMART map -------------------------------------------------------------------------------------------
def test_s7_requests_in_one_segment_are_all_answered_in_order(s7) -> None:
    _, address, _ = s7
    batch = (adu(1, 1, bytes([3, 0, 1, 0, 1])) + adu(2, 1, bytes([3, 0, 0, 0, 1]))
             + adu(3, 1, bytes([3, 0, 100, 0, 1])) + adu(4, 0xFF, bytes([1, 0, 0, 0, 8])))
    replies = exchange(address, batch, replies=4)
    assert [pdu_of(r) for r in replies] == [(1, 1, bytes([3, 2, 0x56, 0x78])), (2, 1, bytes([3, 2, 0x12, 0x34])),
                                            (3, 1, bytes([0x83, 2])),  # VW200: past MaxHold 100
                                            (4, 0xFF, bytes([1, 1, 0b10]))]  # Q0.1, unit FFH echoed


@pytest.mark.parametrize("pdu, reply", [
    (bytes([1, 0, 0, 0, 0]), bytes([0x81, 3])),  # quantity 0
    (bytes([2, 0, 0, 0x07, 0xD1]), bytes([0x82, 3])),  # 2001 discrete inputs
    (bytes([3, 0, 0, 0, 126]), bytes([0x83, 3])),  # 126 registers
    (bytes([4, 0, 0, 0, 0]), bytes([0x84, 3])),
    (bytes([15, 0, 0, 0, 0, 0]), bytes([0x8F, 3])),
    (bytes([16, 0, 0, 0, 0, 0]), bytes([0x90, 3])),
    (bytes([5, 0, 0, 0x12, 0x34]), bytes([0x85, 3])),  # FC05 takes FF00H or 0000H only
    (bytes([1, 1, 0, 0, 1]), bytes([0x81, 2])),  # Q32.0: past Q31.7
    (bytes([4, 0, 56, 0, 1]), bytes([0x84, 2])),  # past AIW110
    (bytes([8, 0, 0, 0, 0]), bytes([0x88, 1])),  # diagnostics: MBUS_SLAVE has none
    (bytes([0x41, 0, 0]), bytes([0xC1, 1])),
])
def test_s7_bad_quantities_and_functions_are_refused_as_the_fbs_does(s7, pdu: bytes, reply: bytes) -> None:
    emulator, address, _ = s7
    (answer,) = exchange(address, adu(1, 1, pdu))
    assert pdu_of(answer)[2] == reply
    assert emulator.memory.get("Q0.0") == 0  # nothing refused was written


def test_s7_another_unit_id_is_gateway_exception(s7) -> None:
    _, address, _ = s7
    (reply,) = exchange(address, adu(1, 7, bytes([3, 0, 0, 0, 1])))
    assert pdu_of(reply)[2] == bytes([0x83, 0x0B])


def test_s7_replies_go_through_the_wire_fault_plan(s7) -> None:
    emulator, address, faults = s7
    faults.push("drop", "corrupt", None)
    batch = b"".join(adu(tid, 1, bytes([3, 0, 0, 0, 1])) for tid in (1, 2, 3))
    first, second = exchange(address, batch, replies=2)
    assert pdu_of(first)[0] == 2 and first[2:4] != b"\0\0"  # 1 dropped; 2's MBAP protocol id made wrong
    assert pdu_of(second) == (3, 1, bytes([3, 2, 0x12, 0x34]))
    assert faults.injected == {"drop": 1, "corrupt": 1} and emulator.stats["modbus_requests"] == 3


# -- the fault rig ----------------------------------------------------------------------------------------------------
def test_rig_requests_in_one_segment_are_all_answered_in_order(rig) -> None:
    emulator, address, _ = rig
    model = emulator.model(TemperatureModel)
    batch = (adu(1, 1, bytes([5, 0, 16 + 3, 0xFF, 0])) + adu(2, 9, bytes([1, 0, 16, 0, 8]))
             + adu(3, 1, bytes([5, 0, 15, 0xFF, 0])) + adu(4, 1, bytes([5, 0, 16 + 3, 0, 0])))
    replies = exchange(address, batch, replies=4)
    assert [pdu_of(r) for r in replies] == [(1, 1, bytes([5, 0, 19, 0xFF, 0])),
                                            (2, 9, bytes([1, 1, 0b1000])),  # any unit: a module alone on its wire
                                            (3, 1, bytes([0x85, 2])),  # below first_coil
                                            (4, 1, bytes([5, 0, 19, 0, 0]))]
    assert model.broken == set()  # opened by 1, closed again by 4, in that order


@pytest.mark.parametrize("pdu, reply", [
    (bytes([1, 0, 16, 0, 0]), bytes([0x81, 3])),  # quantity 0
    (bytes([1, 0, 16, 0x07, 0xD1]), bytes([0x81, 3])),  # 2001 coils
    (bytes([15, 0, 16, 0, 0, 0]), bytes([0x8F, 3])),
    (bytes([5, 0, 16, 0x12, 0x34]), bytes([0x85, 3])),  # FC05 takes FF00H or 0000H only
    (bytes([1, 0, 16 + 96, 0, 1]), bytes([0x81, 2])),  # past the last bank
    (bytes([3, 0, 0, 0, 1]), bytes([0x83, 1])),  # a relay module has coils only
    (bytes([2, 0, 16, 0, 1]), bytes([0x82, 1])),
])
def test_rig_bad_quantities_and_functions_are_refused_as_the_fbs_does(rig, pdu: bytes, reply: bytes) -> None:
    emulator, address, _ = rig
    (answer,) = exchange(address, adu(1, 1, pdu))
    assert pdu_of(answer)[2] == reply
    assert emulator.model(TemperatureModel).broken == set()


def test_rig_replies_go_through_the_wire_fault_plan(rig) -> None:
    emulator, address, faults = rig
    faults.push("drop", "corrupt", None)
    batch = b"".join(adu(tid, 1, bytes([5, 0, 16 + tid, 0xFF, 0])) for tid in (1, 2, 3))
    first, second = exchange(address, batch, replies=2)
    assert pdu_of(first)[0] == 2 and first[2:4] != b"\0\0"
    assert pdu_of(second) == (3, 1, bytes([5, 0, 19, 0xFF, 0]))
    assert emulator.model(TemperatureModel).broken == {1, 2, 3}  # a lost reply is no lost write
    assert faults.injected == {"drop": 1, "corrupt": 1} and emulator.stats["rig_modbus_requests"] == 3


# -- the tables ----------------------------------------------------------------------------------------------------
def test_tables_find_the_first_unmapped_unit() -> None:
    tables = Tables(coils=((0, 10), (10, 20), (30, 40)))
    assert tables.unmapped_in(0, 0, 20) is None and tables.unmapped_in(0, 5, 16) == 20
    assert tables.unmapped_in(0, 25, 1) == 25 and tables.unmapped_in(0, 30, 10) is None
    assert tables.unmapped_in(0, 39, 2) == 40 and tables.unmapped_in(2, 0, 1) == 0  # no holding table at all
    with pytest.raises(ValueError, match="sorted and disjoint"):
        Tables(holding=((0, 10), (5, 20)))
