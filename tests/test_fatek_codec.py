"""The FATEK codec, byte for byte against the manual's vectors, plus round trips, limits and frame faults."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.core.errors import PlcErrorReply
from hil.families.fbs.address import parse
from hil.families.fbs.protocol.fatek import (
    ERROR_CODES,
    MAX_FRAME,
    BitAction,
    ChecksumError,
    CommandMismatch,
    DetailedStatus,
    DetailedStatusReply,
    Frame,
    FrameAssembler,
    Loopback,
    MalformedFrame,
    MixedRead,
    MixedWrite,
    OverlongFrame,
    ReadBits,
    ReadEnableState,
    ReadRegisters,
    RequestError,
    RunStop,
    ShortStatus,
    StationMismatch,
    StatusReply,
    TruncatedFrame,
    WriteBits,
    WriteRegisters,
    build_frame,
    check_reply,
    checksum,
    decode_request,
    describe_frame,
    encode_error,
    encode_reply,
    encode_request,
    split_frame,
)

R12_REQUEST = b"\x02014603R0001275\x03"
R12_REPLY = b"\x020146010A57FC4000189\x03"


# --- the manual's test vectors -------------------------------------------------------------------------------
def test_read_r12_to_r14_request_is_the_manuals_bytes():
    assert encode_request(1, ReadRegisters(parse("R12"), 3)) == R12_REQUEST


def test_read_r12_to_r14_reply_decodes_to_the_manuals_values():
    command = ReadRegisters(parse("R12"), 3)
    assert command.decode(check_reply(R12_REPLY, 1, "46")) == [0x10A5, 0x7FC4, 0x0001]
    assert encode_reply(1, command, [0x10A5, 0x7FC4, 0x0001]) == R12_REPLY


def test_short_status_request():
    assert encode_request(1, ShortStatus()) == b"\x020140C7\x03"


def test_r4128_times_seven_request_and_reply_size():
    frame = encode_request(1, ReadRegisters(parse("R4128"), 7))
    assert frame == b"\x02014607R0412885\x03"
    assert len(frame) == 16
    reply = encode_reply(1, ReadRegisters(parse("R4128"), 7), list(range(7)))
    data = split_frame(reply).data
    assert len(data) == 1 + 28  # error character, then 7 × 4 hex characters


def test_checksum_includes_stx():
    # Leaving STX out is the classic client bug: the two sums differ by exactly 2.
    body = b"\x02014603R00012"
    assert checksum(body) == b"75"
    assert checksum(body[1:]) == b"73"


# --- round trips of every command -------------------------------------------------------------------------------
COMMANDS = [
    ShortStatus(), DetailedStatus(), RunStop(True), RunStop(False), BitAction(1, parse("M1952")),
    BitAction(4, parse("Y9")), ReadEnableState(parse("X0"), 256), ReadBits(parse("M100"), 17),
    WriteBits(parse("S3"), [1, 0, 1]), ReadRegisters(parse("D4054"), 1), ReadRegisters(parse("DR0"), 32),
    ReadRegisters(parse("WM800"), 4), WriteRegisters(parse("R4128"), [0, 0xFFFF, 0x1234]),
    WriteRegisters(parse("DD10"), [0xDEADBEEF]), MixedRead([parse("R4128"), parse("M1952"), parse("DRC200")]),
    MixedWrite([(parse("R5"), 7), (parse("Y0"), 1), (parse("DR100"), 0x10000)]), Loopback("HELLO 123"),
]


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: c.describe())
def test_request_round_trip(command):
    frame = encode_request(1, command)
    parsed = split_frame(frame)
    assert parsed == Frame(1, command.code, command.request_data())
    assert decode_request(parsed) == command


REPLY_RESULTS = [
    (ShortStatus(), StatusReply(0x01, 0x00, 0x00)),
    (DetailedStatus(), DetailedStatusReply(1, 1, 0, 0x40, {"R": 8072, "D": 4096, "ladder": 20480})),
    (ReadBits(parse("M0"), 5), [1, 0, 0, 1, 1]),
    (ReadEnableState(parse("X0"), 3), [0, 1, 0]),
    (ReadRegisters(parse("DR0"), 2), [0xFFFFFFFF, 1]),
    (MixedRead([parse("R1"), parse("X3"), parse("DD0")]), [0xABCD, 1, 0x12345678]),
    (Loopback("ECHO"), "ECHO"),
]


@pytest.mark.parametrize("command,result", REPLY_RESULTS, ids=lambda x: getattr(x, "code", ""))
def test_reply_round_trip(command, result):
    reply = encode_reply(7, command, result)
    decoded = command.decode(check_reply(reply, 7, command.code))
    if isinstance(result, DetailedStatusReply):
        assert (decoded.status1, decoded.unit_type, decoded.os_version) == (1, 1, 0x40)
        assert decoded.sizes["R"] == 8072 and decoded.sizes["ladder"] == 20480 and decoded.sizes["AI"] == 0
        assert decoded.os_text == "V4.0x"
    else:
        assert decoded == result


@pytest.mark.parametrize("command", [RunStop(True), BitAction(3, parse("M0")), WriteBits(parse("Y0"), [1]),
                                     WriteRegisters(parse("R0"), [1]), MixedWrite([(parse("R0"), 1)])],
                         ids=lambda c: c.code)
def test_write_replies_carry_no_data(command):
    assert command.decode(check_reply(encode_reply(1, command), 1, command.code)) is None


@settings(max_examples=60, deadline=None)
@given(start=st.integers(0, 8072 - 64), values=st.lists(st.integers(0, 0xFFFF), min_size=1, max_size=64),
       station=st.integers(1, 0xFE))
def test_register_write_and_read_round_trip_property(start, values, station):
    write = WriteRegisters(parse(f"R{start}"), values)
    if start <= 4999 and start + len(values) - 1 >= 4168:  # an FBs has no R4168–R4999: a server answers A
        with pytest.raises(RequestError) as info:
            decode_request(split_frame(encode_request(station, write)))
        assert info.value.code == "A"
    else:
        assert decode_request(split_frame(encode_request(station, write))) == write
    read = ReadRegisters(parse(f"R{start}"), len(values))
    assert read.decode(check_reply(encode_reply(station, read, values), station, "46")) == values


@settings(max_examples=40, deadline=None)
@given(bits=st.lists(st.integers(0, 1), min_size=1, max_size=256))
def test_bit_round_trip_property(bits):
    command = WriteBits(parse("M0"), bits)
    assert decode_request(split_frame(encode_request(1, command))).values == bits
    read = ReadBits(parse("M0"), len(bits))
    assert read.decode(check_reply(encode_reply(1, read, bits), 1, "44")) == bits


def test_count_256_is_sent_as_00():
    assert ReadBits(parse("M0"), 256).request_data() == "00M0000"
    assert decode_request(Frame(1, "44", "00M0000")).count == 256


# --- limits ------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("build", [
    lambda: ReadRegisters(parse("R0"), 65),
    lambda: WriteRegisters(parse("R0"), [0] * 65),
    lambda: ReadRegisters(parse("DR0"), 33),
    lambda: WriteRegisters(parse("DR0"), [0] * 33),
    lambda: ReadBits(parse("M0"), 257),
    lambda: WriteBits(parse("M0"), [0] * 257),
    lambda: ReadEnableState(parse("M0"), 257),
    lambda: MixedRead([parse(f"R{i}") for i in range(65)]),
    lambda: MixedRead([parse(f"DR{2 * i}") for i in range(33)]),
    lambda: MixedWrite([(parse(f"R{i}"), 0) for i in range(33)]),
    lambda: MixedWrite([(parse(f"DR{2 * i}"), 0) for i in range(17)]),
    lambda: Loopback("x" * 257),
], ids=["46x65", "47x65", "46dwx33", "47dwx33", "44x257", "45x257", "43x257", "48x65", "48dwx33", "49x33",
        "49dwx17", "4Ex257"])
def test_over_limit_requests_are_rejected(build):
    with pytest.raises(ValueError):
        build()


def test_at_limit_requests_are_accepted():
    ReadRegisters(parse("R0"), 64)
    ReadRegisters(parse("DR0"), 32)
    WriteBits(parse("M0"), [0] * 256)
    MixedRead([parse(f"R{i}") for i in range(64)])
    MixedWrite([(parse(f"R{i}"), 0) for i in range(32)])


def test_values_out_of_range_are_rejected_before_sending():
    with pytest.raises(ValueError):
        WriteRegisters(parse("R0"), [0x10000])
    with pytest.raises(ValueError):
        MixedWrite([(parse("DR0"), 1 << 32)])


def test_run_past_the_bank_is_an_address_error():
    with pytest.raises(ValueError, match="outside"):
        ReadRegisters(parse("R8070"), 5)


# --- parse faults: distinct exception types ---------------------------------------------------------------------
def _corrupt_checksum(frame: bytes) -> bytes:
    return frame[:-3] + (b"00" if frame[-3:-1] != b"00" else b"11") + frame[-1:]


def test_bad_checksum():
    with pytest.raises(ChecksumError):
        check_reply(_corrupt_checksum(R12_REPLY), 1, "46")


def test_wrong_station():
    with pytest.raises(StationMismatch):
        check_reply(R12_REPLY, 2, "46")


def test_wrong_command_echo():
    with pytest.raises(CommandMismatch):
        check_reply(R12_REPLY, 1, "44")


@pytest.mark.parametrize("frame", [R12_REPLY[:-1], R12_REPLY[:6], b"\x02\x03"], ids=["no-etx", "short", "empty"])
def test_truncated(frame):
    with pytest.raises(TruncatedFrame):
        split_frame(frame)


def test_over_long():
    body = b"\x0201" + b"4E" + b"A" * 600
    with pytest.raises(OverlongFrame):
        split_frame(body + checksum(body) + b"\x03")


@pytest.mark.parametrize("frame", [build_frame(1, "ZZ", ""), b"X" + R12_REPLY[1:]], ids=["command", "no-stx"])
def test_malformed(frame):
    with pytest.raises(MalformedFrame):
        split_frame(frame)


def test_station_must_be_strict_hex():
    body = b"\x02 1" + b"40"
    with pytest.raises(MalformedFrame):
        split_frame(body + checksum(body) + b"\x03")


def test_reply_without_error_character():
    with pytest.raises(TruncatedFrame):
        check_reply(build_frame(1, "46", ""), 1, "46")


def test_wrong_data_length_in_reply():
    with pytest.raises(MalformedFrame):
        ReadRegisters(parse("R12"), 4).decode(check_reply(R12_REPLY, 1, "46"))


def test_fault_types_are_distinct():
    kinds = {ChecksumError, StationMismatch, CommandMismatch, TruncatedFrame, OverlongFrame, MalformedFrame}
    assert len(kinds) == 6
    for a in kinds:
        for b in kinds - {a}:
            assert not issubclass(a, b)


# --- error codes ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("code", sorted(set(ERROR_CODES) - {"0"}))
def test_every_error_code_maps_to_plc_error_reply(code):
    with pytest.raises(PlcErrorReply) as info:
        check_reply(encode_error(1, "46", code), 1, "46")
    assert info.value.code == code
    assert info.value.meaning == ERROR_CODES[code]
    assert ERROR_CODES[code] in str(info.value)


def test_unknown_error_code_still_raises():
    with pytest.raises(PlcErrorReply, match="unknown"):
        check_reply(encode_error(1, "46", "8"), 1, "46")


# --- server-side request decoding ------------------------------------------------------------------------------------
@pytest.mark.parametrize("frame,code", [
    (Frame(1, "99", ""), "4"),  # unknown command
    (Frame(1, "46", "01R99999"), "A"),  # beyond the model
    (Frame(1, "46", "05R08070"), "A"),  # run past the end
    (Frame(1, "46", "41R00000"), "4"),  # 65 words
    (Frame(1, "46", "01Q00000"), "4"),  # not a name
    (Frame(1, "46", " 1R00000"), "4"),  # count not strict hex
    (Frame(1, "47", "02R0000000"), "4"),  # values cut short
    (Frame(1, "47", "01R00000 FFF"), "4"),  # value not strict hex
    (Frame(1, "45", "01M00002"), "2"),  # bit value not 0/1: illegal value (issue 18)
    (Frame(1, "42", "5M0000"), "2"),  # bit action 5: illegal value
    (Frame(1, "42", "3R00000"), "4"),  # 42 on a register
    (Frame(1, "41", "2"), "2"),  # RUN/STOP argument not 0/1: illegal value
    (Frame(1, "41", "11"), "4"),  # two characters: format
    (Frame(1, "42", ""), "4"),  # nothing to act on: format
    (Frame(1, "46", "01R04168"), "A"),  # an FBs has no R4168–R4999
    (Frame(1, "46", "01R04999"), "A"),
    (Frame(1, "46", "02R04167"), "A"),  # a run into them
    (Frame(1, "46", "01DR04167"), "A"),  # a 32-bit pair into them
    (Frame(1, "47", "01R045001234"), "A"),
    (Frame(1, "48", "02R00000R04200"), "A"),
    (Frame(1, "49", "01R042001234"), "A"),
    # two faults: the first in the frame decides (docs/targets.md)
    (Frame(1, "45", "01M99992"), "A"),  # name beyond the model, then bit value 2
    (Frame(1, "42", "9M9999"), "2"),  # action 9 comes before the name beyond the model
    (Frame(1, "45", "FFM00000"), "4"),  # 255 bits from M0: the second value is missing (format)
    (Frame(1, "45", "FFM00002"), "2"),  # … but the first value, 2, comes before that
    (Frame(1, "46", "41R04200"), "A"),  # the name (beyond the model) comes before the count is checked
    (Frame(1, "49", "02M00002R99999"), "2"),  # the first item's bit value 2, before the second's address
    (Frame(1, "40", "X"), "4"),  # trailing data
    (Frame(1, "4E", "x" * 257), "4"),  # loop-back too long
    (Frame(1, "44", "01WM0003"), "A"),  # W name not on a multiple of 8
])
def test_bad_requests_raise_request_error_with_the_code(frame, code):
    with pytest.raises(RequestError) as info:
        decode_request(frame)
    assert info.value.code == code


def test_describe_frame_never_raises():
    assert "read 3 from R12" in describe_frame(R12_REQUEST)
    assert "error 0" in describe_frame(R12_REPLY, reply=True)
    assert "unreadable" in describe_frame(b"garbage")
    assert "malformed" in describe_frame(build_frame(1, "46", "zz"))


# --- FrameAssembler ---------------------------------------------------------------------------------------------------
def test_assembler_resynchronises_after_garbage():
    assembler = FrameAssembler()
    assert assembler.feed(b"\xff\x00noise" + R12_REPLY + b"tail") == [R12_REPLY]
    assert assembler.dropped == len(b"\xff\x00noise") + len(b"tail")


def test_assembler_restarts_on_stx_inside_a_cut_frame():
    assembler = FrameAssembler()
    assert assembler.feed(R12_REQUEST[:7] + R12_REPLY) == [R12_REPLY]
    assert assembler.dropped == 7


def test_assembler_joins_a_frame_fed_byte_by_byte():
    assembler = FrameAssembler()
    out = []
    for i in range(len(R12_REPLY)):
        out += assembler.feed(R12_REPLY[i:i + 1])
        if i < len(R12_REPLY) - 1:
            assert assembler.pending == i + 1
    assert out == [R12_REPLY]


def test_assembler_yields_several_frames_from_one_chunk():
    assert FrameAssembler().feed(R12_REQUEST + R12_REPLY + R12_REQUEST) == [R12_REQUEST, R12_REPLY, R12_REQUEST]


def test_assembler_abandons_a_frame_that_never_ends():
    assembler = FrameAssembler()
    assert assembler.feed(b"\x02" + b"A" * (MAX_FRAME + 10)) == []
    assert assembler.overlong == 1 and assembler.pending == 0
    assert assembler.feed(b"more\x03" + R12_REPLY) == [R12_REPLY]


@settings(max_examples=60, deadline=None)
@given(noise=st.binary(max_size=40).filter(lambda b: 0x02 not in b), cut=st.integers(1, len(R12_REQUEST) - 1))
def test_assembler_finds_the_frame_after_any_noise(noise, cut):
    assembler = FrameAssembler()
    stream = noise + R12_REQUEST[:cut] + R12_REPLY
    assert assembler.feed(stream[:len(stream) // 2]) + assembler.feed(stream[len(stream) // 2:]) == [R12_REPLY]
