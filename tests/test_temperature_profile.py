"""[temperature] and [faults.sensor_break] in a bench profile: good ones load, bad ones are refused with the reason."""

from __future__ import annotations

import pytest

from hil.bench.profile import load_profile, profile_from_dict
from hil.core.errors import ProfileError
from hil.families.fbs.address import parse
from hil.families.fbs.temperature import MODULES, SENSORS, decode_start, encode_start, parse_temperature
from tests.conftest import EMULATOR_BENCH, REPO


def _profile(temperature=None, faults=None):
    data = {"bench": {"name": "t"}}
    if temperature is not None:
        data["temperature"] = temperature
    if faults is not None:
        data["faults"] = faults
    return profile_from_dict(data)


def _temp(**changes):
    section = {"table": "R3000", "readings": "R3020", "work": "R3060",
               "modules": [{"type": "16TC", "sensor": "K"}, {"type": "16TC", "sensor": "J"}]}
    section.update(changes)
    return section


def test_the_bundled_profiles_load():
    for path in (EMULATOR_BENCH, REPO / "fixtures" / "benches" / "example-bench.toml"):
        profile = load_profile(path)
        config = parse_temperature(profile.areas["temperature"])
        assert config.points >= 2


def test_codes_are_unique_and_the_manual_counts_hold():
    assert len({m.code for m in MODULES.values()}) == 6
    assert len({s.code for s in SENSORS.values()}) == len(SENSORS) == 14  # 8 TC, 2 RTD, 4 NTC
    assert {m: MODULES[m].points for m in MODULES} == {"2TC": 2, "6TC": 6, "16TC": 16, "6RTD": 6, "16RTD": 16,
                                                      "6NTC": 6}
    for name in ("R0", "R5000", "D0", "D3999"):
        assert decode_start(encode_start(parse(name))) == parse(name)


def test_a_good_section_is_parsed():
    config = parse_temperature(_temp(unit="F", averaging=4, rate="fast",
                                     sources={"3": {"kind": "ramp", "start": 20, "per_s": 0.5}}))
    assert config.points == 32 and config.unit == "F" and config.averaging == 4 and config.rate == "fast"
    assert config.table_words()[:2] == [0xA556, 2]
    assert config.point_module(16)[0] == 1
    assert config.update_period() == 3.0  # 16TC, fast


@pytest.mark.parametrize("section, key, reason", [
    (_temp(modules=[{"type": "2TC", "sensor": "K"}] * 9), "modules", "9 modules; an FBs takes at most 8"),
    (_temp(modules=[{"type": "16TC", "sensor": "K"}, {"type": "16TC", "sensor": "K"},
                    {"type": "2TC", "sensor": "K"}, {"type": "6TC", "sensor": "K"}]),
     "modules", "40 points; an FBs measures at most 32"),
    (_temp(modules=[{"type": "6TC", "sensor": "Q"}]), "modules[0]", "unknown sensor 'Q'"),
    (_temp(modules=[{"type": "7TC", "sensor": "K"}]), "modules[0]", "unknown module '7TC'"),
    (_temp(modules=[{"type": "6RTD", "sensor": "K"}]), "modules[0]", "sensor K (TC) is not valid for an FBs-6RTD"),
    (_temp(modules=[{"type": "6NTC", "sensor": "PT100"}]), "modules[0]", "not valid for an FBs-6NTC"),
    (_temp(readings="R3004"), "readings", "overlaps the table block"),
    (_temp(work="R3040"), "work", "overlaps the readings block"),
    (_temp(work="R3000"), "work", "overlaps the table block"),
    (_temp(table="X0"), "table", "neither an R nor a D register"),
    (_temp(unit="K"), "unit", "must be \"C\" or \"F\""),
    (_temp(averaging=3), "averaging", "must be 1, 2, 4 or 8"),
    (_temp(rate="turbo"), "rate", "normal"),
    (_temp(modules=[]), "modules", "non-empty list"),
    (_temp(sources={"40": {"kind": "fixed", "celsius": 1}}), "sources.40", "not a configured point"),
])
def test_bad_sections_are_refused_with_the_key_and_reason(section, key, reason):
    with pytest.raises(ProfileError) as info:
        _profile(temperature=section)
    message = str(info.value)
    assert f"[temperature] {key}" in message and reason in message, message


def test_unknown_temperature_key_is_refused():
    with pytest.raises(ProfileError, match="unknown key.*tabel"):
        _profile(temperature=_temp(tabel="R1"))


@pytest.mark.parametrize("faults, reason", [
    ({"sensor_break": {"kind": "relay"}}, "kind: must be one of emulator, modbus-coil, plc-bit, manual"),
    ({"sensor_break": {"kind": "modbus-coil", "target": "fatek+tcp://h:500"}}, "is not a Modbus URL"),
    ({"sensor_break": {"kind": "modbus-coil", "target": "modbus+tcp://h:502", "first_coil": -1}}, "first_coil"),
    ({"sensor_break": {"kind": "plc-bit", "first": "R40"}}, "R40 is not a bit"),
    ({"sensor_break": {"kind": "plc-bit", "first": "Y40", "first_coil": 2}}, "unknown key(s)"),
    ({"heater_break": {"kind": "emulator"}}, "unknown fault"),
])
def test_bad_fault_injectors_are_refused(faults, reason):
    with pytest.raises(ProfileError) as info:
        _profile(faults=faults)
    assert reason in str(info.value)
