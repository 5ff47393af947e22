"""Replaying recorded FATEK frames (hil.families.fbs.transport.replay, ``replay+fatek://`` targets): the device
procedures send exactly the recorded frames and decode the recorded replies; anything else is a clear mismatch, never a
hang."""

from __future__ import annotations

import socket

import pytest

from hil.core.errors import HilError, TargetError
from hil.families.fbs.transport.factory import open_transport
from hil.families.fbs.transport.replay import RecordedPlc, ReplayError, ReplayMismatch, load_recording
from hil.io.url import parse_target
from tests.frames import FRAMES, SCENARIOS, plc_on


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_each_procedure_sends_its_recorded_frames_and_decodes_the_replies(name):
    run, expected = SCENARIOS[name]
    with open_transport(f"replay+fatek://{FRAMES / name}.txt?timeout=0.5") as transport:
        got = run(plc_on(transport))
        transport.replay.verify()
    assert got == expected


def test_the_recordings_are_the_cheapest_frames_for_the_rtc_read():
    exchanges = load_recording(FRAMES / "rtc-read-all.txt")
    assert len(exchanges) == 1, "R4128–R4135 with M1952–M1955: one mixed read (command 48)"
    assert exchanges[0].request[3:5] == b"48"


def test_a_procedure_that_sends_other_frames_is_named_with_both_frames():
    run, _ = SCENARIOS["rtc-set-leap-day"]
    with open_transport(f"replay+fatek://{FRAMES}/rtc-read-all.txt?timeout=0.3&retries=0") as transport:
        with pytest.raises(HilError):  # the recorded PLC hangs up on the first wrong request
            run(plc_on(transport))
        with pytest.raises(ReplayMismatch, match=r"request 1 differs from the recording: sent .*read 1 from M1955"
                                                 r".*recorded .*mixed read"):
            transport.replay.verify()


def test_requests_left_unsent_are_reported():
    with (
        open_transport(f"replay+fatek://{FRAMES}/rtc-set-leap-day.txt?timeout=0.3") as transport,
        pytest.raises(ReplayMismatch, match=r"8 recorded request\(s\) never sent, the first .*read 1 from M1955"),
    ):
        transport.replay.verify()


def test_a_request_after_the_recording_ended_loses_the_connection_and_is_named():
    run, _ = SCENARIOS["rtc-read-all"]
    with open_transport(f"replay+fatek://{FRAMES}/rtc-read-all.txt?timeout=0.3&retries=0") as transport:
        run(plc_on(transport))
        with pytest.raises(HilError, match="connection lost"):
            plc_on(transport).rtc.read_all()
        with pytest.raises(ReplayMismatch, match="comes after the recording ended"):
            transport.replay.verify()


def test_a_recorded_silence_is_replayed_as_a_timeout(tmp_path):
    text = (FRAMES / "rtc-read-all.txt").read_text()
    silent = tmp_path / "silent.txt"
    silent.write_text("\n".join(line for line in text.splitlines() if " <- " not in line) + "\n")
    exchanges = load_recording(silent)
    assert len(exchanges) == 1 and exchanges[0].reply is None
    with open_transport(f"replay+fatek://{silent}?timeout=0.3&retries=0") as transport:
        with pytest.raises(HilError, match=r"0\.3"):
            plc_on(transport).rtc.read_all()
        transport.replay.verify()  # the request itself was the recorded one


def test_a_trace_saved_for_a_failed_test_loads(tmp_path):
    """The reporting plugin saves traces/<test>.txt with a '# nodeid: outcome' line before the trace."""
    text = (FRAMES / "rtc-read-all.txt").read_text().split("\n", 1)[1]
    saved = tmp_path / "suites_test_rtc.py__test_x.txt"
    saved.write_text("# suites/test_rtc.py::test_x: failed\n" + text)
    assert load_recording(saved) == load_recording(FRAMES / "rtc-read-all.txt")


@pytest.mark.parametrize("content,message", [
    (None, "cannot read recording"),
    ("hello\n", "not one FATEK wire trace"),
    ("# wire trace (modbus-tcp): 2 entries\n12:00:00.000 -> 00 01  | x\n", "a modbus-tcp trace"),
    ("# wire trace (fatek): 0 entries\n", "holds no frames"),
    ("# wire trace (fatek): 1 entries\n12:00:00.000 <- 02 30 03 .0.  | reply\n", "a reply with no request"),
    ("# wire trace (fatek): 1 entries\n12:00:00.000 -> 02 3G 03 .0.  | x\n", "unreadable hex"),
], ids=["missing", "not-a-trace", "modbus", "empty", "reply-first", "bad-hex"])
def test_unusable_recordings_are_refused_with_the_reason(tmp_path, content, message):
    path = tmp_path / "rec.txt"
    if content is not None:
        path.write_text(content)
    with pytest.raises(ReplayError, match=message):
        load_recording(path)
    with pytest.raises(ReplayError, match=message):
        open_transport(f"replay+fatek://{path}")


def test_replay_urls():
    target = parse_target("replay+fatek:///tmp/x.txt?station=2&timeout=0.5")
    assert (target.device, target.params, target.protocol) == ("/tmp/x.txt", {"station": 2, "timeout": 0.5}, "fatek")
    with pytest.raises(TargetError, match="names no recording"):
        parse_target("replay+fatek://")
    with pytest.raises(TargetError, match="unknown parameter 'unit'"):
        parse_target("replay+fatek:///tmp/x.txt?unit=1")


def test_the_recorded_plc_stops_cleanly_with_a_client_connected():
    peer = RecordedPlc(load_recording(FRAMES / "rtc-read-all.txt"))
    host, port = peer.address.rsplit(":", 1)
    with socket.create_connection((host, int(port))):
        peer.close()
    assert not peer._thread.is_alive()
