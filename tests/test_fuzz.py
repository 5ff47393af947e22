"""Fuzzing with hypothesis: parsers and servers take any bytes without crashing or accepting a bad frame."""

from __future__ import annotations

import contextlib
import socket
import time

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hil.bench.profile import load_profile, profile_from_dict
from hil.core.errors import AddressError, HilError, ProfileError
from hil.families.fbs.address import parse, parse_range
from hil.families.fbs.protocol.fatek import (
    STX,
    FrameAssembler,
    FrameError,
    ReadRegisters,
    RequestError,
    WriteRegisters,
    build_frame,
    check_reply,
    checksum,
    decode_request,
    encode_request,
    split_frame,
)
from hil.families.fbs.sim import Emulator
from hil.families.fbs.sim.serve_fatek import FatekServerCore, start_fatek_pty, start_fatek_tcp

FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
VALID = [encode_request(1, ReadRegisters("R0", 3)), encode_request(1, WriteRegisters("R1000", [5, 6])),
         build_frame(1, "44", "08M0010"), build_frame(1, "40"), build_frame(1, "4E", "hello"),
         build_frame(1, "48", "02R00010M0001"), build_frame(1, "49", "01R0100000FF")]


def _checksum_ok(frame: bytes) -> bool:
    return len(frame) >= 8 and checksum(frame[:-3]) == frame[-3:-1].upper()


@st.composite
def mutated(draw) -> bytes:
    """A valid request with a few bytes flipped, inserted or deleted."""
    frame = bytearray(draw(st.sampled_from(VALID)))
    for _ in range(draw(st.integers(1, 3))):
        op, pos = draw(st.sampled_from("fid")), draw(st.integers(0, len(frame) - 1))
        if op == "f":
            frame[pos] = draw(st.integers(0, 255))
        elif op == "i":
            frame.insert(pos, draw(st.integers(0, 255)))
        elif len(frame) > 1:
            del frame[pos]
    return bytes(frame)


ANY_BYTES = st.one_of(st.binary(max_size=600), mutated(), st.lists(mutated(), max_size=4).map(b"".join))


@FUZZ
@given(ANY_BYTES)
def test_split_frame_never_accepts_a_bad_checksum(data):
    try:
        frame = split_frame(data)
    except FrameError:
        return
    assert _checksum_ok(data) and data[0] == STX
    with contextlib.suppress(RequestError):
        decode_request(frame)


@FUZZ
@given(ANY_BYTES, st.integers(1, 254), st.sampled_from(["44", "46", "4E", "40"]))
def test_check_reply_raises_only_harness_errors(data, station, command):
    try:
        check_reply(data, station, command)
    except HilError:
        return
    assert _checksum_ok(data)


@FUZZ
@given(st.lists(st.binary(max_size=80), max_size=8))
def test_assembler_frames_are_stx_to_etx_whatever_the_chunks(chunks):
    assembler = FrameAssembler()
    for frame in (f for chunk in chunks for f in assembler.feed(chunk)):
        assert frame[0] == STX and frame[-1] == 3 and 3 not in frame[1:-1] and STX not in frame[1:]


@FUZZ
@given(st.text(max_size=20))
def test_address_parser_raises_address_errors_only(text):
    for fn in (parse, parse_range):
        with contextlib.suppress(AddressError):
            fn(text)


_TOML_VALUES = st.recursive(st.one_of(st.none(), st.booleans(), st.integers(-5, 70000), st.floats(-1, 2000),
                                      st.text(max_size=12), st.sampled_from(["R1000-R1009", "emulator", "M1952"])),
                            lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner,
                                                                                        max_size=3), max_leaves=8)
_KEYS = st.sampled_from(["name", "target", "station", "timeout", "writable", "volatile", "seed", "drop", "delay",
                         "script", "chip", "start", "scan_time_ms", "time_scale", "bogus"])
_SECTIONS = st.sampled_from(["bench", "safety", "emulator", "rtc", "wire_faults", "faults", "other"])


@FUZZ
@given(st.dictionaries(_SECTIONS, st.dictionaries(_KEYS, _TOML_VALUES, max_size=4), max_size=4))
def test_profile_loader_raises_profile_errors_only(data):
    data = dict(data)
    data.setdefault("bench", {}).setdefault("name", "fuzz")
    with contextlib.suppress(ProfileError):
        profile_from_dict(data)


@FUZZ
@given(st.binary(max_size=300))
def test_profile_file_of_any_bytes(tmp_path, data):
    path = tmp_path / "bench.toml"
    path.write_bytes(data)
    with pytest.raises(ProfileError):
        load_profile(path)  # random bytes are never a profile with a [bench] name


@FUZZ
@given(st.lists(ANY_BYTES, max_size=6))
def test_server_core_answers_only_good_frames(chunks):
    emulator = Emulator()
    core = FatekServerCore(emulator)
    assembler = core.session()
    for chunk in chunks:
        for reply in core.feed(assembler, chunk):
            assert _checksum_ok(reply)
    assert emulator.stats["fatek_internal_error"] == 0
    # Every reply answers a frame with a good checksum: never more replies than good frames for us.
    assert emulator.stats["fatek_replies"] <= emulator.stats["fatek_requests"]


@pytest.fixture(scope="module", params=["tcp", "pty"])
def live(request):
    emulator = Emulator()
    server = start_fatek_tcp(emulator) if request.param == "tcp" else start_fatek_pty(emulator)
    yield request.param, server, emulator
    server.stop()


def test_live_servers_survive_fuzz(live):
    kind, server, emulator = live

    @settings(max_examples=60, deadline=None)
    @given(st.lists(ANY_BYTES, min_size=1, max_size=4))
    def feed(chunks):
        if kind == "tcp":
            host, port = server.address.rsplit(":", 1)
            with socket.create_connection((host, int(port)), timeout=2) as sock:
                for chunk in chunks:
                    sock.sendall(chunk)
        else:
            import os
            fd = os.open(server.address, os.O_RDWR | os.O_NOCTTY)
            try:
                for chunk in chunks:
                    os.write(fd, chunk)
            finally:
                os.close(fd)
    feed()
    time.sleep(0.1)
    assert emulator.stats["fatek_internal_error"] == 0
    # Still serving a well-behaved client after all that.
    from hil.families.fbs.transport.fatek import FatekTransport
    url = f"socket://{server.address}" if kind == "tcp" else server.address
    with FatekTransport(url, timeout=1.0) as client:
        client.write("R1000", 1234)
        assert client.read("R1000") == 1234
