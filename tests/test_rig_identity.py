"""A fault rig is switched only once it is proven a separate device, and recovery writes only the coils the profile
lets its injectors switch (issue 40, items 2 and 3) — against ``hil emulate`` as a separate process (FATEK/TCP, its
own Modbus/TCP port, the relay rig), reached only over the wire, the state directory a temp dir.

The PLC's own Modbus port serves its outputs as coils: "coil 0" there is Y0.  Whatever cannot be decided — a PLC
clock that reads 0, a rig that does not answer, an answer that proves nothing — is refused on every path: a fault
injection, the next run's recovery, ``hil rtc sync``, ``hil restore``.
"""

from __future__ import annotations

import json
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from hil.bench.family import open_bench
from hil.bench.profile import load_profile
from hil.core.errors import HilError
from hil.core.journal import Journal, journal_path
from hil.core.lock import lock_key
from hil.families.fbs.injectors.modbus_coil import ModbusCoilSensorBreak
from hil.families.fbs.recovery import rig_key
from tests import processes
from tests.conftest import EMULATOR_BENCH, REPO
from tests.external import hil_emulate
from tests.test_recovery_trust import KILL, _journal, _plc, _profile, _restore, _session, _stamp, _url

NO_CLOCK = ('chip = "S-35390A"', 'chip = "none"')  # an FBs without an RTC chip: R4128–R4134 read 0


@pytest.fixture(scope="module")
def plc():
    """``hil emulate`` with its clock running: FATEK/TCP, its own Modbus/TCP port and the relay rig."""
    with hil_emulate(EMULATOR_BENCH, 1.0, modbus=True) as where:
        yield where


@pytest.fixture(scope="module")
def clockless(tmp_path_factory):
    """The same, for a PLC whose clock reads 0 (no RTC chip fitted)."""
    path = tmp_path_factory.mktemp("clockless") / "clockless.toml"
    path.write_text(EMULATOR_BENCH.read_text().replace(*NO_CLOCK))
    with hil_emulate(path, 1.0, modbus=True) as where:
        yield where


def _own_port(where: dict, unit: int = 1) -> str:
    return f"modbus+tcp://{where['modbus-tcp']}?unit={unit}"


def _bench(tmp_path: Path, where: dict, rig: str | None = None, *, name: str = "bench",
           clock: bool = True, coils: dict[str, str] | None = None) -> Path:
    """A profile for the PLC behind ``where`` over FATEK/TCP, its faults on ``rig`` (default: the relay rig);
    ``clock=False`` for the clockless PLC; ``coils``: fault → its rig's coil allow-list."""
    path = _profile(tmp_path, where, name, rig=rig)
    text = path.read_text()
    if not clock:
        text = text.replace(*NO_CLOCK)
    for fault, allowed in (coils or {}).items():
        text = text.replace(f"[faults.{fault}]\n", f'[faults.{fault}]\ncoils = "{allowed}"\n', 1)
    path.write_text(text)
    return path


def _y0(where: dict) -> int:
    with _plc(where) as t:
        return t.read("Y0")


def _rig_coils(where: dict, coils: list[int]) -> list[int]:
    rig = ModbusCoilSensorBreak(f"modbus+tcp://{where['rig-modbus-tcp']}?unit=1")
    try:
        return rig.guard().inner.read_coils(coils)
    finally:
        rig.close()


def _switch_rig(where: dict, items: list[tuple[int, int]]) -> None:
    """The operator's hand on the relay module (unguarded)."""
    rig = ModbusCoilSensorBreak(f"modbus+tcp://{where['rig-modbus-tcp']}?unit=1")
    try:
        rig.guard().inner.write_coils(items)
    finally:
        rig.close()


def _plant_coil(where: dict, rig: str) -> Path:
    """A journal as the issue's run left it: rig coil 0 at ``rig`` switched off (original 1) — on the PLC's own
    Modbus port, coil 0 is Y0."""
    key = lock_key(_url(where))
    endpoint, unit = rig_key(rig)
    path = journal_path(key)
    path.write_text(json.dumps(_journal(key, where, coils={f"{endpoint}#unit{unit}/coil0": _stamp(
        {"target": rig, "coil": 0, "unit": unit, "original": True, "wrote": False})})))
    return path


def _hil(*argv: str) -> subprocess.CompletedProcess:
    """``hil ARGV`` as a user runs it: its own process, this test's state directory."""
    return processes.run([sys.executable, "-m", "hil.cli.main", *argv], timeout=120, cwd=REPO)


# -- item 2: a rig that is not proven a separate device is never switched -------------------------------------------
@pytest.mark.e2e
def test_a_fault_injection_on_the_plcs_own_port_is_refused_when_its_clock_reads_0(clockless, tmp_path):
    """The PLC's clock reads 0, so its read-out proves nothing: the run's injection is refused, Y0 stays 0."""
    profile = _bench(tmp_path, clockless, _own_port(clockless), clock=False)
    run = _session(tmp_path, profile, "bench.faults.sensor_break.open(0)")
    out = run.stdout + run.stderr
    assert run.returncode != 0 and "cannot be told apart from the PLC under test" in out, out
    assert "the PLC's clock reads 0" in out and "refused" in out, out
    assert _y0(clockless) == 0


@pytest.mark.e2e
def test_rtc_sync_refuses_to_recover_a_rig_coil_on_the_plcs_own_port(plc, tmp_path):
    """`hil rtc sync` recovers first; a journaled "rig coil" that is the PLC's Y0 is refused, not "restored and
    verified", and the journal kept for a person to look at."""
    path = _plant_coil(plc, _own_port(plc))
    done = _hil("rtc", "sync", _url(plc), "--bench", str(_bench(tmp_path, plc, _own_port(plc))))
    out = done.stdout + done.stderr
    assert done.returncode != 0 and "it is the PLC's own Modbus port" in out, out
    assert "restored and verified" not in out and "not going on" in out, out
    assert _y0(plc) == 0 and path.exists() and Journal(lock_key(_url(plc))).pending
    path.unlink()


@pytest.mark.e2e
@pytest.mark.parametrize("command", ["run", "rtc sync"])
def test_recovery_refuses_a_rig_coil_on_the_own_port_of_a_plc_whose_clock_reads_0(clockless, tmp_path, command):
    """The next run and `hil rtc sync` alike: undecidable is refused, Y0 is not switched."""
    path = _plant_coil(clockless, _own_port(clockless))
    profile = _bench(tmp_path, clockless, _own_port(clockless), clock=False)
    if command == "run":
        done = _session(tmp_path, profile, "pass")
    else:
        done = _hil("rtc", "sync", _url(clockless), "--bench", str(profile))
    out = done.stdout + done.stderr
    assert done.returncode != 0 and "cannot be told apart from the PLC under test" in out, out
    assert _y0(clockless) == 0 and Journal(lock_key(_url(clockless))).pending
    path.unlink()


@pytest.fixture
def silent() -> Iterator[str]:
    """A Modbus/TCP "rig" that accepts connections and never answers."""
    with socket.create_server(("127.0.0.1", 0)) as server:
        yield f"modbus+tcp://127.0.0.1:{server.getsockname()[1]}?unit=1"


def _nobody_listening() -> str:
    with socket.create_server(("127.0.0.1", 0)) as server:
        port = server.getsockname()[1]
    return f"modbus+tcp://127.0.0.1:{port}?unit=1"


@pytest.mark.e2e
@pytest.mark.parametrize("case", ["unreachable", "silent", "the PLC's port, another unit"])
def test_a_rig_whose_identity_cannot_be_read_is_refused_for_injection_and_recovery(plc, tmp_path, capsys, silent,
                                                                                   case):
    """Nothing listening, a device that never answers, the PLC's own port answering exception 0BH for another
    unit: none proves a separate device, so neither an injection nor `hil restore` switches a coil there."""
    rig = {"unreachable": _nobody_listening(), "silent": silent,
           "the PLC's port, another unit": _own_port(plc, unit=2)}[case]
    bench = open_bench(load_profile(_bench(tmp_path, plc, rig)), target=_url(plc))
    try:
        with pytest.raises(HilError, match="cannot be told apart from the PLC under test.* refused"):
            bench.faults.get("sensor_break")
    finally:
        bench.close()
    key = lock_key(_url(plc))
    path = _plant_coil(plc, rig)
    code, lines = _restore(capsys, _url(plc), "--bench", str(_bench(tmp_path, plc, rig, name="again")))
    assert code != 0 and "cannot be told apart from the PLC under test" in " ".join(lines), lines
    assert _y0(plc) == 0 and Journal(key).pending
    path.unlink()


@pytest.mark.e2e
def test_the_relay_rig_is_proven_separate_and_switched(plc, tmp_path):
    """The relay module answers a read of R4128… with exception 01 (it has no registers): a separate device."""
    bench = open_bench(load_profile(_bench(tmp_path, plc)), target=_url(plc))
    try:
        bench.begin_test("t")
        bench.faults.sensor_break.open(1)
        assert _rig_coils(plc, [1]) == [1]
        bench.end_test()
    finally:
        bench.close()
    assert _rig_coils(plc, [1]) == [0]


# -- item 3: recovery writes only the coils the profile allows, each run of coils on its own -------------------------
@pytest.mark.e2e
def test_recovery_leaves_a_journaled_coil_outside_the_profiles_allow_list(plc, tmp_path):
    """A run opens sensor 2 (coil 2) and point 0's heater circuit (coil 32) and is killed.  The next run's profile
    allows coils 0–3, 36–39 and 64–67 on that rig: coil 2 is put back, coil 32 is not written — named, kept."""
    died = _session(tmp_path, _bench(tmp_path, plc),
                    f"bench.faults.sensor_break.open(2)\nbench.faults.heater_open.inject(0)\n{KILL}", name="dies")
    assert _rig_coils(plc, [2, 32]) == [1, 1], died.stdout + died.stderr
    narrow = _bench(tmp_path, plc, name="narrow",
                    coils={"sensor_break": "0-3", "heater_open": "36-39", "ssr_short": "64-67"})
    try:
        run = _session(tmp_path, narrow, "pass", name="next")
        out = run.stdout + run.stderr
        assert run.returncode != 0, out
        assert "coil 32 is not one the profile lets its injectors switch" in out and "0-3, 36-39, 64-67" in out, out
        assert _rig_coils(plc, [2, 32]) == [0, 1]
        assert [k.rpartition("/")[2] for k in Journal(lock_key(_url(plc))).coils()] == ["coil32"]
    finally:
        _switch_rig(plc, [(32, 0)])
        journal_path(lock_key(_url(plc))).unlink(missing_ok=True)


@pytest.mark.e2e
def test_two_journaled_coils_in_different_banks_are_read_each_on_its_own(plc, tmp_path):
    """A run opens sensor 2 (coil 2) and is killed; its journal also names coil 200 of a second bank the next run's
    profile allows ([faults.ssr_short] first_coil = 200) and this relay module does not have.  Coil 200's read
    fails (exception 02) — and coil 2 is still put back and verified; coil 200 is named and kept."""
    died = _session(tmp_path, _bench(tmp_path, plc), f"bench.faults.sensor_break.open(2)\n{KILL}", name="dies")
    assert _rig_coils(plc, [2]) == [1], died.stdout + died.stderr
    key = lock_key(_url(plc))
    data = json.loads(journal_path(key).read_text())
    (coil2,) = [k for k in data["coils"] if k.endswith("/coil2")]
    data["coils"][coil2.replace("/coil2", "/coil200")] = {**data["coils"][coil2], "coil": 200}
    journal_path(key).write_text(json.dumps(data))
    banks = _bench(tmp_path, plc, name="banks")
    banks.write_text(banks.read_text().replace("first_coil = 64", "first_coil = 200"))
    try:
        run = _session(tmp_path, banks, "pass", name="next")
        out = run.stdout + run.stderr
        assert run.returncode != 0, out
        assert f"rig coil {coil2} = 0" in out and "coil200 (original 0)" in out, out
        assert _rig_coils(plc, [2]) == [0]
        assert [k.rpartition("/")[2] for k in Journal(key).coils()] == ["coil200"]
    finally:
        journal_path(key).unlink(missing_ok=True)
