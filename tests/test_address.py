"""FBs element names: every kind, both spellings (human and frame), ranges and errors."""

from __future__ import annotations

import pytest

from hil.core.errors import AddressError
from hil.families.fbs.address import Address, is_valid, parse, parse_range, span, take_frame_name

# (human name, kind, index, frame form, width in bits)
KINDS = [
    ("X0", "X", 0, "X0000", 1), ("Y9", "Y", 9, "Y0009", 1), ("M1952", "M", 1952, "M1952", 1),
    ("S1000", None, None, None, None),  # S0–S999 only: checked below as an error
    ("S999", "S", 999, "S0999", 1), ("T255", "T", 255, "T0255", 1), ("C10", "C", 10, "C0010", 1),
    ("R4128", "R", 4128, "R04128", 16), ("D4054", "D", 4054, "D04054", 16), ("RT12", "RT", 12, "RT0012", 16),
    ("RC12", "RC", 12, "RC0012", 16), ("WX0", "WX", 0, "WX0000", 16), ("WY8", "WY", 8, "WY0008", 16),
    ("WM800", "WM", 800, "WM0800", 16), ("WS16", "WS", 16, "WS0016", 16), ("WT0", "WT", 0, "WT0000", 16),
    ("WC240", "WC", 240, "WC0240", 16), ("DR0", "DR", 0, "DR00000", 32), ("DD10", "DD", 10, "DD00010", 32),
    ("DRT0", "DRT", 0, "DRT0000", 32), ("DRC200", "DRC", 200, "DRC0200", 32), ("DWX0", "DWX", 0, "DWX0000", 32),
    ("DWY8", "DWY", 8, "DWY0008", 32), ("DWM0", "DWM", 0, "DWM0000", 32), ("DWS8", "DWS", 8, "DWS0008", 32),
    ("DWT0", "DWT", 0, "DWT0000", 32), ("DWC224", "DWC", 224, "DWC0224", 32),
]
VALID = [k for k in KINDS if k[1] is not None]


@pytest.mark.parametrize("name,kind,index,frame,bits", VALID, ids=[k[0] for k in VALID])
def test_parse_and_format_every_kind(name, kind, index, frame, bits):
    a = parse(name)
    assert a == Address(kind, index)
    assert str(a) == name
    assert a.fatek_name == frame
    assert a.bits == bits
    assert a.words == (2 if bits == 32 else 1)
    assert a.is_bit == (bits == 1)
    assert parse(frame) == a  # the frame form parses too
    assert parse(name.lower()) == a  # and so does lower case


@pytest.mark.parametrize("name,kind,index,frame,bits", VALID, ids=[k[0] for k in VALID])
def test_frame_name_lengths_by_width(name, kind, index, frame, bits):
    # Bits are 5 characters, 16-bit 6, 32-bit 7 — the receiver relies on it (names are not delimited).
    assert len(frame) == {1: 5, 16: 6, 32: 7}[bits]
    assert take_frame_name(frame + "R00001", 0) == (parse(name), len(frame))


def test_take_frame_name_walks_a_mixed_list():
    text = "R04128M1952DRC0200DWM0000RT0012"
    pos, names = 0, []
    while pos < len(text):
        a, pos = take_frame_name(text, pos)
        names.append(str(a))
    assert names == ["R4128", "M1952", "DRC200", "DWM0", "RT12"]


def test_take_frame_name_rejects_garbage():
    with pytest.raises(AddressError):
        take_frame_name("Q12345", 0)
    with pytest.raises(AddressError):
        take_frame_name("R041", 0)  # cut short


@pytest.mark.parametrize("name", ["R99999", "Q12", "WM3", "M2002", "X256", "R8072", "D4096", "RT256", "RC200",
                                  "DRC199", "DRC256", "DR8071", "DD4095", "WM1992", "DWM1976", "WX248", "S1000",
                                  "", "R", "12", "R-1", "R4.5", "R123456", "M 1"])
def test_invalid_names(name):
    with pytest.raises(AddressError):
        parse(name)
    assert not is_valid(name)


def test_error_messages_say_what_is_wrong():
    with pytest.raises(AddressError, match="outside the FBs range of R: R0–R8071"):
        parse("R99999")
    with pytest.raises(AddressError, match="not an FBs element name"):
        parse("Q12")
    with pytest.raises(AddressError, match="multiple of 8"):
        parse("WM3")


def test_non_string_is_an_address_error():
    with pytest.raises(AddressError):
        parse(12)  # type: ignore[arg-type]


@pytest.mark.parametrize("name", ["M2001", "X255", "R8071", "D4095", "RT255", "RC199", "DRC255", "DR8070",
                                  "DD4094", "WM1984", "DWM1968", "WX240", "DWX224"])
def test_last_valid_element_of_each_bank(name):
    assert is_valid(name)


def test_span_and_offsets():
    assert [str(a) for a in span("R4128", 3)] == ["R4128", "R4129", "R4130"]
    assert [str(a) for a in span("WM800", 3)] == ["WM800", "WM816", "WM832"]  # packed words step by 16 bits
    assert [str(a) for a in span("DWM0", 2)] == ["DWM0", "DWM32"]
    assert [str(a) for a in span("DRC254", 2)] == ["DRC254", "DRC255"]
    with pytest.raises(AddressError, match="run past the end"):
        span("R8070", 3)
    with pytest.raises(AddressError):
        span("R0", 0)


def test_paired_32_bit_runs_do_not_overlap():
    # A FATEK 46 run of DR names moves two registers per value: DR0 = R0:R1, the next is DR2 = R2:R3.
    assert str(parse("DR0").offset(1)) == "DR2"
    assert [str(a) for a in span("DD10", 3)] == ["DD10", "DD12", "DD14"]


def test_elements_covered():
    assert [str(a) for a in parse("DR10").elements()] == ["R10", "R11"]
    assert len(list(parse("WM800").elements())) == 16
    assert [str(a) for a in parse("M5").elements()] == ["M5"]


def test_parse_range():
    assert [str(a) for a in parse_range("R4128-R4131")] == ["R4128", "R4129", "R4130", "R4131"]
    assert parse_range("M1952") == [parse("M1952")]
    assert parse_range("r1 - r2") == [parse("R1"), parse("R2")]
    with pytest.raises(AddressError, match="mixes"):
        parse_range("R1-D2")
    with pytest.raises(AddressError, match="backwards"):
        parse_range("R5-R1")
    with pytest.raises(AddressError):
        parse_range("R8000-R9000")
