"""Which FATEK frames carry many elements (hil.families.fbs.transport.plan), seen on the wire of a real transport."""

from __future__ import annotations

import pytest

from hil.families.fbs.address import parse
from hil.families.fbs.protocol.fatek import decode_request, split_frame
from hil.families.fbs.transport.factory import open_transport
from hil.families.fbs.transport.plan import ROUND_TRIP, plan


@pytest.fixture
def plc():
    with open_transport("emulator+fatek-tcp") as transport:
        transport.frames = []
        transport.observers.append(lambda direction, frame: direction == "tx" and transport.frames.append(
            decode_request(split_frame(bytes(frame)))))
        yield transport


def _codes(plc) -> list[str]:
    return [command.code for command in plc.frames]


def test_what_fits_one_mixed_frame_stays_one_frame(plc):
    """One frame is one scan: the RTC's time and its flags, however adjacent most of them are."""
    names = [f"R{4128 + i}" for i in range(8)] + ["WM1952"]
    plc.read_many(names)
    assert _codes(plc) == ["48"]
    plc.frames.clear()
    plc.write_many([("M1952", 1)] + [(f"R{4128 + i}", 0) for i in range(7)])
    assert _codes(plc) == ["49"]


def test_one_run_goes_in_one_range_frame(plc):
    plc.read_many([f"R{100 + i}" for i in range(10)])
    plc.read_many([f"M{10 + i}" for i in range(10)])
    plc.write_many([(f"R{100 + i}", i) for i in range(10)])
    assert _codes(plc) == ["46", "44", "47"]
    assert plc.read_words("R100", 10) == list(range(10))


def test_long_requests_put_adjacent_runs_in_range_frames_and_the_scattered_rest_in_mixed_ones(plc):
    runs = [f"R{680 + i}" for i in range(40)] + [f"Y{64 + i}" for i in range(32)]
    scattered = [f"R{2000 + 7 * i}" for i in range(20)]
    names = scattered[:10] + runs + scattered[10:]
    values = {n: (i * 37) % (2 if n.startswith("Y") else 65536) for i, n in enumerate(names)}
    plc.write_many(values.items())
    writes = _codes(plc)
    assert "47" in writes and "45" in writes and "49" in writes
    # writes keep the caller's order: the first ten scattered ones go before the runs, the rest after them
    assert writes.index("49") < writes.index("47") and writes[-1] == "49"
    plc.frames.clear()
    assert plc.read_many(names) == [values[n] for n in names]
    assert sorted(_codes(plc)) == ["44", "46", "48"]  # R680–R719 in one 46 frame, Y64–Y95 in one 44, the rest 48


def test_a_short_run_stays_in_the_mixed_frames_when_naming_it_is_cheaper():
    # two adjacent registers: a range frame of its own costs more characters (and a round trip) than two names
    names = [parse(f"R{2000 + 3 * i}") for i in range(70)] + [parse("R5000"), parse("R5001")]
    pieces = plan(names, open_transport("emulator").limits)
    assert not any(piece.run for piece in pieces)
    assert ROUND_TRIP > 0


def test_duplicates_and_values_come_back_in_the_callers_order(plc):
    plc.write_words("R100", list(range(70)))
    names = [f"R{100 + i}" for i in range(70)] + ["R105", "R100"]
    assert plc.read_many(names) == list(range(70)) + [5, 0]


def test_a_read_that_need_not_be_one_scan_finds_its_runs_in_address_order_and_answers_in_the_callers(plc):
    """The guard's restores name a test's blocks, then FUN86's: read in address order, they share range frames;
    each value still comes back at its caller's position."""
    plc.write_words("R3000", list(range(100, 107)))
    names = ["R3001", "R3004", "R3005", "R3006", "R3000", "R3002", "R3003"]
    assert plc.read_many(names, one_scan=False) == [100 + int(n[1:]) - 3000 for n in names]
    assert _codes(plc) == ["47", "46"]
    plc.frames.clear()
    names = ["M5", "R3004", "M4", "R3003", "Y3", "R3002"]
    assert plc.read_many(names, one_scan=False)[1::2] == [104, 103, 102]
    assert len(plc.frames) <= 2
