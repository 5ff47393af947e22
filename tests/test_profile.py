import re

import pytest

from hil.bench.profile import load_profile, profile_from_dict
from hil.core.errors import ProfileError
from tests.conftest import REPO


def test_shipped_profiles_load():
    emulator = load_profile(REPO / "fixtures/benches/emulator.toml")
    example = load_profile(REPO / "fixtures/benches/example-bench.toml")
    assert emulator.target == "emulator" and emulator.rtc.chip == 3
    assert example.target == "emulator" and not example.safety.allow_destructive  # reaches no hardware as written
    assert len(emulator.digest) == 64


def test_the_example_reaches_no_hardware_until_edited(tmp_path):
    """Issue 40 item 5: the example newcomers copy (and the error for a bare --target pointed them to) had an
    active relay-module rig at a LAN address with no coil allow-list.  As written it reaches nothing; uncommented,
    its PLC and rig parts load and say what to change (placeholders, not a real-looking address), and the rig has
    its allow-list."""
    text = (REPO / "fixtures/benches/example-bench.toml").read_text()
    example = load_profile(REPO / "fixtures/benches/example-bench.toml")
    assert example.target == "emulator" and example.faults == {}
    assert "192.168." not in text and "PLC-IP" in text and "RELAY-MODULE-IP" in text
    edited = text.replace('# target = "fatek+tcp://PLC-IP:500"', 'target = "fatek+tcp://PLC-IP:500"')
    for line in ("[faults.sensor_break]", 'kind = "modbus-coil"\n', "target = \"modbus+tcp://RELAY-MODULE-IP",
                 "first_coil = 0", "coils = "):  # the sensor-break rig's keys, as its comment says
        edited = edited.replace("# " + line, line, 1)
    (tmp_path / "mine.toml").write_text(edited)
    mine = load_profile(tmp_path / "mine.toml")
    assert mine.target == "fatek+tcp://PLC-IP:500" and mine.station == 1
    assert mine.faults["sensor_break"]["coils"] and "RELAY-MODULE-IP" in mine.faults["sensor_break"]["target"]


@pytest.mark.parametrize("bench, says", [
    ({"station": 3, "target": "fatek+tcp://h:500?station=1"}, "station = 3, but [bench] target says station=1"),
    ({"station": 2, "target": "modbus+tcp://h:502?unit=5"}, "station = 2, but [bench] target says unit=5"),
    ({"target": "fatek+tcp://h:500?station=0"}, "station=0 must be 1–254"),
])
def test_a_profile_naming_two_stations_is_refused(bench, says):
    with pytest.raises(ProfileError, match=re.escape(says)):
        profile_from_dict({"bench": {"name": "b", **bench}})


def test_the_station_comes_from_one_place():
    """[bench] station, else the target's ?station=/?unit=, else 1; every wire then carries it."""
    from hil.bench.profile import plc_target
    assert profile_from_dict({"bench": {"name": "b", "target": "fatek+tcp://h:500?station=7"}}).station == 7
    profile = profile_from_dict({"bench": {"name": "b", "station": 3, "target": "modbus+tcp://h:502"}})
    assert plc_target(profile).params["unit"] == 3
    assert plc_target(profile, "modbus+tcp://h:502?timeout=1").params == {"timeout": 1.0, "unit": 3}
    assert plc_target(profile, "emulator+modbus-tcp").params == {}  # the emulator answers as the profile's station


def test_can_write_checks_whole_elements():
    profile = profile_from_dict({"bench": {"name": "b"}, "safety": {"writable": ["R10-R11", "M8-M23"]}})
    assert profile.can_write("R10") and profile.can_write("DR10") and profile.can_write("WM8")
    assert not profile.can_write("DR11") and not profile.can_write("R12") and not profile.can_write("WM16")


@pytest.mark.parametrize("data, message", [
    ({}, "missing the \\[bench\\] section"),
    ({"bench": {}}, "\\[bench\\] name is required"),
    ({"bench": {"name": "b", "colour": "red"}}, "unknown key\\(s\\) in \\[bench\\]: colour"),
    ({"bench": {"name": "b"}, "extras": {}}, "unknown section \\[extras\\]"),
    ({"bench": {"name": "b", "station": 300}}, "station = 300 must be 1–254"),
    ({"bench": {"name": "b", "time_scale": "fast"}}, "time_scale must be a float"),
    ({"bench": {"name": "b", "target": "ftp://x"}}, "\\[bench\\] target: cannot use target"),
    ({"bench": {"name": "b"}, "safety": {"writable": ["R99999"]}}, "writable: 'R99999' is outside"),
    ({"bench": {"name": "b"}, "safety": {"writable": ["R5-M7"]}}, "mixes R and M"),
    ({"bench": {"name": "b"}, "safety": {"writable": ["R9-R5"]}}, "runs backwards"),
    ({"bench": {"name": "b"}, "rtc": {"chip": "DS1307"}}, "chip must be 0–3"),
    ({"bench": {"name": "b"}, "rtc": {"start": "yesterday"}}, "\\[rtc\\] start"),
])
def test_bad_profiles_name_the_key(data, message):
    with pytest.raises(ProfileError, match=message):
        profile_from_dict(data)


def test_missing_and_malformed_files(tmp_path):
    with pytest.raises(ProfileError, match="cannot read bench profile"):
        load_profile(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[bench\nname = 1")
    with pytest.raises(ProfileError, match="not valid TOML"):
        load_profile(bad)
