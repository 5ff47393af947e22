import pytest

from hil.core.errors import ProfileError
from hil.bench.profile import load_profile, profile_from_dict
from tests.conftest import REPO


def test_shipped_profiles_load():
    emulator = load_profile(REPO / "fixtures/benches/emulator.toml")
    example = load_profile(REPO / "fixtures/benches/example-bench.toml")
    assert emulator.target == "emulator" and emulator.rtc.chip == 3
    assert example.target.startswith("fatek+serial://") and not example.safety.allow_destructive
    assert len(emulator.digest) == 64


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
