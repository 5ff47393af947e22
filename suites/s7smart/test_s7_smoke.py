"""Smoke: the S7-200 SMART answers, and V memory round-trips through the bench's wire."""

import pytest

from hil.core.errors import WriteRefused

pytestmark = pytest.mark.family("s7-200smart")


@pytest.mark.spec("S7-WIRE-3")
def test_plc_answers_status(bench):
    status = bench.plc.status()
    assert status.running in (True, None), f"PLC reports {status.summary()}"


@pytest.mark.spec("S7-WIRE-1")
def test_v_bytes_round_trip(bench):
    bench.plc.io.write_v(200, bytes([0x12, 0x34, 0xFF, 0x00, 0x5A]))  # odd length: the last word is partial
    assert bench.plc.io.read_v(200, 5) == bytes([0x12, 0x34, 0xFF, 0x00, 0x5A])
    assert bench.plc.io.read("VW200") == 0x1234


@pytest.mark.spec("S7-WIRE-1")
def test_v_bit_round_trip(bench):
    bench.plc.io.write("V210.3", 1)
    assert bench.plc.io.read("VB210") & 0x08 and bench.plc.io.read("V210.3") == 1


@pytest.mark.spec("HIL-GUARD-1")
def test_write_outside_allow_list_is_refused(bench):
    with pytest.raises(WriteRefused, match="VB300"):
        bench.plc.io.write_v(300, b"\x01")
