"""Issue 40, items 1 and 4: a PLC is reached at the profile's station on every wire and by every command, and only
ever with a profile that names it.

Two ``hil emulate`` processes stand in for the PLCs of a multidrop line: one answering as station (and Modbus unit)
3, one as 1 — a request to the wrong one gets no FATEK reply, a Modbus gateway error.  The commands run as a user
types them (``python -m hil``), each profile a file in a temp dir."""

from __future__ import annotations

import contextlib
import re
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from hil.families.fbs.transport.factory import open_transport
from tests.conftest import EMULATOR_BENCH
from tests.external import bench_over_the_wire, emulate_process
from tests.test_cli_entry import EXIT_USAGE, hil

WIRES = {"fatek-tcp": "--fatek-tcp", "modbus-tcp": "--modbus-tcp", "rig-modbus-tcp": "--rig-modbus-tcp"}
#: a test that writes a scratch word the profile allows (and reads it back): it passes only at the right station
WRITES = 'def test_it(bench):\n    bench.plc.io.write("R1000", 1)\n    assert bench.plc.io.read("R1000") == 1\n'


def _at_station(station: int) -> str:
    text = EMULATOR_BENCH.read_text()
    assert re.search(r"(?m)^station = 1$", text)
    return re.sub(r"(?m)^station = 1$", f"station = {station}", text)


@pytest.fixture(scope="module")
def line(tmp_path_factory) -> Iterator[dict[int, dict[str, str]]]:
    """Station → its endpoints: ``hil emulate`` as station 3 and as station 1."""
    where = tmp_path_factory.mktemp("line")
    served = {}
    with contextlib.ExitStack() as stack:
        for station in (3, 1):
            profile = where / f"station-{station}.toml"
            profile.write_text(_at_station(station))
            served[station] = stack.enter_context(emulate_process(profile, 1.0, WIRES))
        yield served


def _profile(tmp_path: Path, where: dict[str, str], url: str, station: int = 3, name: str = "bench.toml") -> Path:
    """A bench's profile for the PLC at ``url`` (its rig ``where``'s): ``[bench] station`` says which one it is."""
    path = tmp_path / name
    path.write_text(bench_over_the_wire(_at_station(station), where, 1.0, url=url))
    return path


def _fatek(where: dict[str, str]) -> str:
    return f"fatek+tcp://{where['fatek-tcp']}"


def _modbus(where: dict[str, str]) -> str:
    return f"modbus+tcp://{where['modbus-tcp']}"


def _said(done: subprocess.CompletedProcess) -> str:
    return " ".join((done.stdout + done.stderr).split())


def _scratch(url: str) -> int:
    """R1000 as the PLC at ``url`` holds it, read over a wire of its own."""
    link = open_transport(url, timeout=5.0)
    try:
        return link.read("R1000")
    finally:
        link.close()


@pytest.mark.e2e
# (the Modbus wire of the one decision in the matrix: the gate's time)
@pytest.mark.parametrize("wire, param", [(_fatek, "station"), pytest.param(_modbus, "unit", marks=pytest.mark.matrix)],
                         ids=["fatek", "modbus"])
def test_the_profiles_station_is_the_one_every_command_reaches(line, wire, param, tmp_path: Path) -> None:
    bench = str(_profile(tmp_path, line[3], wire(line[3])))
    (tmp_path / "test_it.py").write_text(WRITES)
    for command in (["probe", "--bench", bench], ["rtc", "read", "--bench", bench],
                    ["run", "-q", "--bench", bench, "--", "test_it.py"]):
        done = hil(*command, cwd=tmp_path)
        assert done.returncode == 0, f"hil {' '.join(command)}: {_said(done)}"
        if command[0] == "probe":
            assert f"{param}=3" in _said(done), _said(done)  # the PLC it names: the profile's station
    # the same profile aimed where station 3 is not: nothing answers it as station 3, and station 1 there —
    # somebody else's PLC — does not answer for it nor get its write
    elsewhere = str(_profile(tmp_path, line[1], wire(line[1]) + "?timeout=0.5&retries=0", name="elsewhere.toml"))
    for command in (["probe", "--bench", elsewhere], ["run", "-q", "--bench", elsewhere, "--", "test_it.py"]):
        done = hil(*command, cwd=tmp_path)
        # (exit 4 saying no station 3 answered — FATEK: no reply; Modbus/TCP: the server serves no unit 3 — not any
        # failure: a crash or a profile error would be another)
        said = _said(done)
        assert done.returncode == 4 and ("no reply" in said or "serves no unit 3" in said), \
            f"hil {' '.join(command)}: {said}"
    assert _scratch(f"{wire(line[1])}?{param}=1") == 0


@pytest.mark.e2e
# (one decision, plc_target, for both wires: the Modbus case of it runs in the matrix — the gate's time)
@pytest.mark.parametrize("wire, param", [(_fatek, "station"), pytest.param(_modbus, "unit", marks=pytest.mark.matrix)],
                         ids=["fatek", "modbus"])
def test_a_url_naming_another_station_than_the_profile_is_a_profile_error(line, wire, param, tmp_path: Path) -> None:
    url = wire(line[1])
    bench = str(_profile(tmp_path, line[1], url))
    (tmp_path / "test_it.py").write_text(WRITES)
    other = f"{url}?{param}=1"
    for command in (["probe", other, "--bench", bench], ["rtc", "read", other, "--bench", bench],
                    ["run", "-q", "--bench", bench, "--target", other, "--", "test_it.py"]):
        done = hil(*command, cwd=tmp_path)
        said = _said(done)
        assert done.returncode == EXIT_USAGE, f"hil {' '.join(command)}: {said}"
        assert "[bench] station = 3" in said and f"{param}=1" in said and "one PLC has one station" in said, said
    assert _scratch(other) == 0  # station 1 untouched
    # the profile itself saying two stations is refused when it is read
    both = tmp_path / "both.toml"
    both.write_text(bench_over_the_wire(_at_station(3), line[1], 1.0, url=other))
    done = hil("probe", "--bench", str(both), cwd=tmp_path)
    said = _said(done)
    assert done.returncode == EXIT_USAGE and "[bench] station = 3" in said and f"says {param}=1" in said, said


@pytest.mark.e2e
def test_a_live_target_runs_only_with_a_profile_that_names_it(line, tmp_path: Path) -> None:
    """``hil run -- … --target URL`` used to run under the emulator's profile (RUN/STOP allowed, broad writable
    ranges): the default ``--bench`` hil run passes by name hid the refusal."""
    url = _fatek(line[1]) + "?station=1"
    (tmp_path / "test_it.py").write_text(WRITES)
    another = _profile(tmp_path, line[1], _modbus(line[1]), station=1, name="another.toml")  # another bench's PLC
    runs = {
        "pytest's --target after --": (["run", "-q", "--", "test_it.py", "--target", url],
                                       "names a PLC, and no --bench profile was given"),
        "--target without --bench": (["run", "-q", "--target", url, "--", "test_it.py"],
                                     "names a PLC, and no --bench profile was given"),
        "the emulator's profile by name": (["run", "-q", "--bench", "emulator", "--", "test_it.py", "--target", url],
                                           "is for the emulator"),
        "another bench's profile": (["run", "-q", "--bench", str(another), "--target", url, "--", "test_it.py"],
                                    "is not the PLC the profile"),
    }
    for case, (command, why) in runs.items():
        done = hil(*command, cwd=tmp_path)
        said = _said(done)
        assert done.returncode == EXIT_USAGE, f"{case}: {said}"
        assert why in said and "--bench" in said and f"hil init {url}" in said, f"{case}: {said}"
    assert _scratch(url) == 0  # nothing was written
    # and the profile that names it runs
    named = _profile(tmp_path, line[1], url, station=1, name="named.toml")
    done = hil("run", "-q", "--bench", str(named), "--target", url, "--", "test_it.py", cwd=tmp_path)
    assert done.returncode == 0, _said(done)
