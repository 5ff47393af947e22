"""A labgrid place's resources → target URLs and the fault rig; the ``[labgrid]`` profile section; the command
line's refusals.  ``tests/data/labgrid/show-acquired.txt`` is what labgrid-client 26.0.1 printed for an acquired
place (trimmed to six resources); tests/test_lab_of_benches.py runs all of it against a real coordinator."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
from pathlib import Path

import pytest

from hil.bench.lab.client import LabError, Place, Resource, parse_places
from hil.bench.lab.resolve import ranges, resolve
from hil.bench.lab.spec import LabSpec, parse_tags
from hil.bench.profile import check_profile, lab_request, load_profile, profile_from_dict
from hil.core.errors import HilError, ProfileError
from tests.conftest import EMULATOR_BENCH, REPO

SHOW = (REPO / "tests" / "data" / "labgrid" / "show-acquired.txt").read_text()


@pytest.fixture
def place() -> Place:
    return parse_places(SHOW)[0]


def test_show_output_is_read_into_the_place_and_its_resources(place):
    assert (place.name, place.tags, place.acquired) == ("bench1", {"family": "fbs", "rtc": "s35390a"}, "vm/root")
    by_name = {r.name: r for r in place.resources}
    assert sorted(by_name) == ["plc-ethernet", "plc-port0", "relay-0", "relay-1", "relay-15", "relay-2"]
    assert by_name["plc-port0"].cls == "NetworkSerialPort" and by_name["plc-port0"].params["port"] == 35165
    assert by_name["relay-15"].path == "exp1/fbs-bench/ModbusTCPCoil/relay-15"
    assert by_name["plc-ethernet"].exporter_host == "localhost" and not by_name["plc-ethernet"].isolated


def test_places_listing_without_resources():
    listed = parse_places("Place 'a':\n  tags: family=fbs\n  matches:\n    x/y/*\n  acquired: None\n"
                          "  acquired resources:\n  reservation: T0K3N\nPlace 'b':\n  matches:\n  acquired: h/u\n")
    assert [(p.name, p.tags, p.acquired, p.reservation) for p in listed] == [
        ("a", {"family": "fbs"}, None, "T0K3N"), ("b", {}, "h/u", None)]


def test_the_wire_and_every_resolvable_resource_get_urls(place):
    lab = resolve(LabSpec(place="bench1", coordinator="localhost:4000"), place, token="T", station=3)
    assert lab.target == "fatek+tcp://127.0.0.1:44607?station=3"  # the only NetworkService wins by default
    assert dict(lab.urls)["plc-port0"] == "fatek+rfc2217://127.0.0.1:35165?baudrate=9600&station=3"
    assert lab.rig == "modbus+tcp://127.0.0.1:41921?unit=1" and lab.rig_coils == {0, 1, 2, 15}
    assert (lab.exporters, lab.exporter_hosts, lab.wire) == (
        ("exp1",), ("localhost",), "exp1/fbs-bench/NetworkService/plc-ethernet")
    props = dict(lab.properties())
    assert props["hil.lab.rig"] == "modbus+tcp://127.0.0.1:41921?unit=1 coils 0-2, 15"
    assert props["hil.lab.tags"] == "family=fbs rtc=s35390a" and props["hil.lab.reserved_by"] == "place bench1"
    assert lab.lock_target == "labgrid://127.0.0.1:4000/bench1"  # hil's local lock: the place on its coordinator


@pytest.mark.parametrize("spec, url", [
    (LabSpec(wire="plc-port0", params=(("parity", "E"), ("bytesize", 7))),
     "fatek+rfc2217://127.0.0.1:35165?baudrate=9600&station=1&parity=E&bytesize=7"),
    (LabSpec(wire="plc-port0", protocol="modbus"), "modbus+rfc2217://127.0.0.1:35165?baudrate=9600&unit=1"),
    (LabSpec(protocol="modbus"), "modbus+tcp://127.0.0.1:44607?unit=1"),
])
def test_the_wire_speaks_what_the_profile_says(place, spec, url):
    assert resolve(dataclasses.replace(spec, place="bench1"), place).target == url


@pytest.mark.parametrize("port, url", [(502, "modbus+tcp://10.0.0.5:502?unit=1"), (102, "s7+tcp://10.0.0.5:102"),
                                       (500, "fatek+tcp://10.0.0.5:500?station=1")])
def test_a_network_service_port_picks_the_protocol(port, url):
    service = Resource("plc", "e", "g", "NetworkService", "plc", {"address": "10.0.0.5", "port": port})
    assert resolve(LabSpec(place="p"), Place("p", resources=(service,))).target == url


@pytest.mark.parametrize("change, message", [
    (lambda rs: rs + [dataclasses.replace(rs[0], name="second", resource="second")],
     "2 NetworkService resources .*name the PLC's wire with \\[labgrid\\] wire"),
    (lambda rs: [r for r in rs if r.cls == "ModbusTCPCoil"], "has no PLC wire"),
    (lambda rs: [_with(r, host="10.9.9.9:502") if r.name == "relay-2" else r for r in rs], "on 2 hosts"),
    (lambda rs: [_with(r, invert=True) if r.name == "relay-1" else r for r in rs], "relay-1 are inverted"),
    (lambda rs: [_with(r, extra={"proxy": "h", "proxy_required": True}) if r.cls == "NetworkService" else r
                 for r in rs], "isolated"),
])
def test_what_hil_cannot_use_is_refused_naming_it(place, change, message):
    broken = dataclasses.replace(place, resources=tuple(change(list(place.resources))))
    with pytest.raises(LabError, match=message):
        resolve(LabSpec(place="bench1"), broken)


@pytest.mark.parametrize("params, why", [({"protocol": "raw"}, "not RFC 2217"), ({"port": None}, "no port yet")])
def test_a_serial_port_hil_cannot_reach_is_unusable(place, params, why):
    broken = dataclasses.replace(place, resources=tuple(
        _with(r, **params) if r.cls == "NetworkSerialPort" else r for r in place.resources))
    assert why in dict(resolve(LabSpec(place="bench1"), broken).urls)["plc-port0"]
    with pytest.raises(LabError, match=why):
        resolve(LabSpec(place="bench1", wire="plc-port0"), broken)


def test_a_missing_wire_name_lists_what_the_place_has(place):
    with pytest.raises(LabError, match="no resource named 'plc'.*plc-ethernet \\(NetworkService\\)"):
        resolve(LabSpec(place="bench1", wire="plc"), place)


def test_the_rig_fills_faults_that_name_no_target(place):
    lab = resolve(LabSpec(place="bench1", rig="relay-[01]"), place)
    data = lab.apply({"bench": {"name": "b"}, "labgrid": {"place": "bench1"},
                      "faults": {"sensor_break": {"kind": "modbus-coil", "first_coil": 0},
                                 "heater_open": {"kind": "modbus-coil", "target": "modbus+tcp://rig2:502"}}})
    assert "labgrid" not in data and data["bench"]["target"] == lab.target
    assert data["faults"]["sensor_break"] == {"kind": "modbus-coil", "first_coil": 0,
                                              "target": "modbus+tcp://127.0.0.1:41921?unit=1", "coils": "0-1"}
    assert data["faults"]["heater_open"] == {"kind": "modbus-coil", "target": "modbus+tcp://rig2:502"}
    with pytest.raises(ProfileError, match="coils: the coils a labgrid place holds"):
        lab.apply({"faults": {"sensor_break": {"kind": "modbus-coil", "coils": "0-3"}}})
    without = resolve(LabSpec(place="bench1", rig="nothing-*"), place)
    with pytest.raises(ProfileError, match="place bench1 has none"):
        without.apply({"faults": {"sensor_break": {"kind": "modbus-coil"}}})


def test_ranges():
    assert ranges(frozenset({5, 0, 1, 2, 7, 8})) == "0-2, 5, 7-8"
    assert ranges(frozenset({3})) == "3"


# -- the profile and the command line ---------------------------------------------------------------------------
def lab_bench(tmp_path: Path, labgrid: str, *, target: bool = False) -> Path:
    text = EMULATOR_BENCH.read_text()
    if not target:
        text = re.sub(r'(?m)^target = "emulator"\n', "", text)
    path = tmp_path / "lab.toml"
    path.write_text(text + "\n[labgrid]\n" + labgrid)
    return path


def test_a_lab_profile_loads_only_with_its_place(tmp_path, place):
    path = lab_bench(tmp_path, 'tags = {family = "fbs", rtc = "s35390a"}\n')
    with pytest.raises(ProfileError, match="takes its PLC from a labgrid place tagged family=fbs rtc=s35390a"):
        load_profile(path)
    spec = lab_request(path)
    assert spec.filters == {"family": "fbs", "rtc": "s35390a"}
    assert check_profile(path, spec).target == "fatek+tcp://labgrid.invalid"  # checked, never connected to
    lab = resolve(spec, place)
    profile = load_profile(path, lab=lab)
    assert profile.target == lab.target and profile.lab is lab
    assert lab_request(path, place="other").filters == {"name": "other"}  # the command line wins


@pytest.mark.parametrize("labgrid, target, message", [
    ('place = "a"\n', True, "\\[bench\\] target and \\[labgrid\\] both say where the PLC is"),
    ('place = "a"\ntags = {family = "fbs"}\n', False, "gives both place and tags"),
    ('place = "a"\ncolour = "red"\n', False, "unknown key\\(s\\) in \\[labgrid\\]: colour"),
    ('tags = {Family = "fbs"}\n', False, "\\[labgrid\\] tags: labgrid tag Family='fbs'"),
    ('place = "a"\nprotocol = "profibus"\n', False, "protocol = 'profibus' must be one of fatek, modbus, s7"),
])
def test_bad_labgrid_sections_name_the_key(tmp_path, labgrid, target, message):
    path = lab_bench(tmp_path, labgrid, target=target)
    with pytest.raises(ProfileError, match=message):
        check_profile(path, lab_request(path))


def test_tags_from_the_command_line():
    assert parse_tags("family=fbs, rtc=s35390a") == (("family", "fbs"), ("rtc", "s35390a"))
    with pytest.raises(HilError, match="tags are KEY=VALUE"):
        parse_tags("family")
    with pytest.raises(ProfileError, match="name a place"):
        LabSpec().overridden()


def test_a_plain_profile_is_unchanged_without_a_place():
    assert lab_request(EMULATOR_BENCH) is None
    assert profile_from_dict({"bench": {"name": "b"}}).lab is None


@pytest.mark.parametrize("argv, says", [
    (["run", "--bench", "LAB", "--target", "emulator"], "--target and labgrid place a both say where the PLC is"),
    (["run", "--bench", "LAB", "--bench", "LAB", "--lg-place", "x"], "name each bench's place in its profile"),
    (["probe", "--bench", "LAB"], "takes its PLC from labgrid place a: `hil run --bench"),
    (["run", "--lg-reserve", "Family=x"], "tags are KEY=VALUE"),
])
def test_the_command_line_refuses_in_one_line(tmp_path, argv, says):
    path = lab_bench(tmp_path, 'place = "a"\n')
    proc = subprocess.run([sys.executable, "-m", "hil.cli.main", *(str(path) if a == "LAB" else a for a in argv)],
                          capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert proc.returncode == 4 and says in " ".join(proc.stderr.split()), proc.stderr


def test_benches_that_are_places_run_in_parallel_each_reserving_its_own(tmp_path):
    from hil.cli.many import plan
    first = lab_bench(tmp_path, 'place = "a"\n')
    second = tmp_path / "second.toml"
    second.write_text(first.read_text().replace('name = "emulator"', 'name = "other"', 1))
    assert [run.name for run in plan([str(first), str(second)], str(tmp_path / "junit.xml"))] == ["emulator", "other"]


def _with(resource: Resource, **params: object) -> Resource:
    return dataclasses.replace(resource, params={**resource.params, **params})
