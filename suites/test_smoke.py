"""Smoke: the PLC answers, and a user register and relay round-trip through the bench's wire."""

import pytest


def test_plc_answers_status(bench):
    status = bench.plc.status()
    # The suites need a PLC in RUN; None means the wire has no status command (Modbus) but the PLC answered.
    assert status.running in (True, None), f"PLC reports {status.summary()}"


def test_user_register_round_trip(bench):
    bench.plc.io.write_words("R1000", [0x1234, 0xFFFF, 0])
    assert bench.plc.io.read_words("R1000", 3) == [0x1234, 0xFFFF, 0]


def test_user_relay_round_trip(bench):
    bench.plc.io.write_bits("M1000", [1, 0, 1, 1])
    assert bench.plc.io.read_bits("M1000", 4) == [1, 0, 1, 1]


def test_mixed_read_and_write(bench):
    bench.plc.io.write_many({"R1010": 4321, "M1008": 1})
    assert bench.plc.io.read_many(["R1010", "M1008"]) == [4321, 1]


def test_write_outside_allow_list_is_refused(bench):
    from hil.core.errors import WriteRefused
    with pytest.raises(WriteRefused, match="R2000"):
        bench.plc.io.write_words("R2000", [1])
