"""The S7-200 SMART time buffer codec, S7 operands, the S7 Modbus map and the profile sections."""

from __future__ import annotations

import datetime as dt

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hil.bench.profile import load_profile, profile_from_dict
from hil.core.errors import AddressError, ProfileError, UnreachableAddress
from hil.families.s7smart.address import parse_s7, parse_s7_range
from hil.families.s7smart.protocol import timebuf
from hil.families.s7smart.protocol.modbus_map import S7ModbusMap
from tests.conftest import REPO


def test_encode_is_bcd_with_sunday_one():
    assert timebuf.encode(dt.datetime(2012, 3, 4, 17, 45, 10)) == bytes.fromhex("1203041745100001")
    assert timebuf.encode(timebuf.POWER_LOSS_TIME) == bytes.fromhex("0001010000000007")  # Saturday


@given(st.datetimes(min_value=dt.datetime(2000, 1, 1), max_value=dt.datetime(2099, 12, 31, 23, 59, 59)))
def test_round_trip(when):
    when = when.replace(microsecond=0)
    buffer = timebuf.encode(when)
    assert timebuf.decode(buffer, check_weekday=True) == when
    assert timebuf.int_to_bcd(timebuf.encode_int(when)) == buffer


@pytest.mark.parametrize("hex_, problem", [
    ("2402301200000000", "day 30 does not exist in 2024-02"),
    ("2302291200000000", "day 29 does not exist in 2023-02"),
    ("2102290000000000", "day 29 does not exist in 2021-02"),
    ("2413011200000000", "month 13"),
    ("2400011200000000", "month 0"),
    ("2401012400000000", "hour 24"),
    ("2401010A1A000000", "hour not BCD, minute not BCD"),
    ("2401010000000100", "reserved 1"),
])
def test_invalid_buffers_are_0007(hex_, problem):
    with pytest.raises(timebuf.TimeBufferError, match=problem) as info:
        timebuf.decode(bytes.fromhex(hex_))
    assert info.value.code == 0x0007


def test_weekday_is_ignored_unless_asked():
    assert timebuf.decode(bytes.fromhex("2406150830000003")) == dt.datetime(2024, 6, 15, 8, 30)
    with pytest.raises(timebuf.TimeBufferError, match="weekday"):
        timebuf.decode(bytes.fromhex("2406150830000008"), check_weekday=True)


def test_leap_years_through_2099():
    for year in range(2000, 2100):
        leap = year % 4 == 0
        buffer = bytes([timebuf.to_bcd(year - 2000), 0x02, 0x29, 0, 0, 0, 0, 1])
        assert (not timebuf.problems([timebuf.from_bcd(b) for b in buffer])) == leap, year


def test_set_rtc_i_integers():
    assert timebuf.int_to_bcd(bytes([24, 6, 15, 8, 30, 0, 0, 7])) == bytes.fromhex("2406150830000007")
    with pytest.raises(timebuf.TimeBufferError):
        timebuf.int_to_bcd(bytes([124, 6, 15, 8, 30, 0, 0, 7]))


def test_operands():
    assert str(parse_s7("vw104")) == "VW104" and parse_s7("VW104").size == 2
    assert parse_s7("V100.3").bit == 3 and str(parse_s7("SM4.3")) == "SM4.3"
    assert [str(a) for a in parse_s7_range("Q0.6-Q1.1")] == ["Q0.6", "Q0.7", "Q1.0", "Q1.1"]
    for bad in ("R100", "V100.8", "VB99999", "VX1"):
        with pytest.raises(AddressError):
            parse_s7(bad)


def test_modbus_map_holdstart():
    m = S7ModbusMap(hold_start=100, max_hold=10)
    assert m.registers_for(100, 2) == (0, 1) and m.registers_for(103, 2) == (1, 2) and m.v_byte(3) == 106
    with pytest.raises(UnreachableAddress, match="VB120.*HoldStart VB100"):
        m.registers_for(120, 1)
    assert m.bit_number(parse_s7("Q1.2")) == 10


def test_shipped_s7_profiles_load():
    emu = load_profile(REPO / "fixtures/benches/s7-200smart.toml")
    real = load_profile(REPO / "fixtures/benches/example-s7-200smart.toml")
    assert emu.family == real.family == "s7-200smart"
    assert real.target.startswith("s7+tcp://") and emu.target == "emulator+s7-tcp"  # the native wire first
    assert load_profile(REPO / "fixtures/benches/emulator.toml").family == "fbs"


BASE = {"bench": {"name": "b", "family": "s7-200smart"}}
RTC = {"set_trigger": "V100.0", "read_trigger": "V100.1", "set_buffer": "VB110", "read_buffer": "VB130",
       "eno": "V102.0", "error": "VW104"}


@pytest.mark.parametrize("data, message", [
    ({"bench": {"name": "b", "family": "s5"}}, "family = 's5' must be one of"),
    ({"bench": {"name": "b"}, "s7": {}}, "set \\[bench\\] family"),
    ({**BASE, "safety": {"writable": ["R100"]}}, "not an S7-200 SMART operand"),
    ({**BASE, "s7": {"cpu": "CPU224"}}, "not an S7-200 SMART CPU"),
    ({**BASE, "s7": {"hold_start": "VW0"}}, "must be a V byte"),
    ({**BASE, "s7rtc": {**RTC, "eno": "VB102"}}, "eno = 'VB102' must be a bit"),
    ({**BASE, "s7rtc": {**RTC, "read_buffer": "VB114"}}, "set_buffer and read_buffer overlap"),
    ({**BASE, "s7rtc": {k: v for k, v in RTC.items() if k != "error"}}, "error is required"),
    ({**BASE, "s7rtc": {**RTC, "error": "MW0"}}, "not an S7-200 SMART operand|must be in V"),
])
def test_bad_s7_profiles_name_the_key(data, message):
    with pytest.raises(ProfileError, match=message):
        profile_from_dict(data)


def test_the_emulated_clock_keeps_two_digit_years_past_2099():
    """The manual: the clock keeps only the year's last two digits — one second after 2099-12-31 23:59:59 it reads
    00-01-01 00:00:00 (the emulator's clock must not stop at a year READ_RTC cannot encode)."""
    from hil.families.s7smart.sim.emulator import S7Clock
    clock = S7Clock()
    clock.load(10.0, dt.datetime(2099, 12, 31, 23, 59, 59))
    assert clock.read_rtc(10.5) == (bytes.fromhex("99 12 31 23 59 59 00 05"), 0)
    assert clock.read_rtc(11.0) == (bytes.fromhex("00 01 01 00 00 00 00 07"), 0)
