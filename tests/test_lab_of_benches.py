"""A lab of benches (issue 17): a real labgrid coordinator and exporter on 127.0.0.1 publish a ``hil emulate`` — its
FATEK/TCP port as a NetworkService, its pty as a RawSerialPort (the exporter serves it through ser2net as RFC 2217:
a NetworkSerialPort), its fault rig's coils as ModbusTCPCoil resources — and ``hil run`` processes queue for the
places, run the RTC and temperature suites through them, and let go however they end.

All at once, so the test costs about two suite runs of wall time:

* A ``--lg-place bench1`` runs the suites; B ``--lg-reserve "family=fbs rtc=s35390a"`` (only bench1 has both tags)
  queues behind it, shows that it waits, and runs once A has let go — from the ``hil[labgrid]`` environment when
  there is one (labgrid-client beside its Python), A from the test environment (stock pyserial;
  ``HIL_LABGRID_CLIENT``);
* C queues for bench1 too and is stopped with SIGTERM while queued: its reservation is cancelled;
* D runs on a place whose PLC is switched off: the run fails, and the place is released;
* E holds bench2 — the same PLC through another resource — and waits for hil's local lock on the PLC's endpoint,
  which A holds (the second guard beside labgrid's); stopped with SIGTERM while it holds the place: released;
* F gives up on bench1 after ``--lg-wait 2``; G asks for tags no place has and is refused at once.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from tests import processes
from tests.conftest import EMULATOR_BENCH, REPO
from tests.external import RIG_FIRST_COIL, emulate_process
from tests.labgrid_lab import MISSING, RunningLab, refused_port, running_lab, wait_for
from tests.test_bench_mode import bench_like

#: the matrix, not the gate (scripts/e2e_matrix.py, which also makes .venv-labgrid): two suite runs of wall time
pytestmark = [pytest.mark.matrix, pytest.mark.skipif(MISSING is not None, reason=MISSING or "")]

#: temperature first: its polled waits do not mind the other runs starting beside A; the RTC suite's one-second
#: windows then have the host to themselves
SUITES = [str(REPO / "suites" / "test_temperature.py"), str(REPO / "suites" / "test_rtc.py")]
SMOKE = [str(REPO / "suites" / "test_smoke.py")]
SCALE = 2.0  # the emulator's time scale: A's RTC and temperature suites (≈ 60 bench s) hold bench1 ≈ 30 s, long
#: enough for E to reach the PLC's lock while A holds it on a busy CI host (at 5, and once at 3, A finished first)
TAGS = "family=fbs rtc=s35390a"
PLACES = {"bench1": ("lab-host/fbs-bench/*", TAGS), "bench2": ("lab-host/fbs-bench-twin/*", "family=fbs twin=yes"),
          "dead": ("lab-host/switched-off/*", "family=fbs")}


def exporter_config(emulated: dict[str, str], dead_port: int) -> str:
    """What a lab admin writes for a FATEK bench (docs/lab.md), pointed at ``hil emulate``."""
    host, port = emulated["fatek-tcp"].rsplit(":", 1)
    rig = emulated["rig-modbus-tcp"]
    return f"""\
fbs-bench:
  plc-ethernet:
    cls: NetworkService
    address: {host}
    port: {port}
    username: ""
  plc-port0:
    cls: RawSerialPort
    port: {emulated["fatek-serial"]}
    speed: 9600
{{% for coil in range(96) %}}
  relay-{{{{ coil }}}}:
    cls: ModbusTCPCoil
    host: "{rig}"
    coil: {{{{ coil }}}}
{{% endfor %}}
fbs-bench-twin:
  plc-ethernet:
    cls: NetworkService
    address: {host}
    port: {port}
    username: ""
  relay-0:
    cls: ModbusTCPCoil
    host: "{rig}"
    coil: 0
switched-off:
  plc-ethernet:
    cls: NetworkService
    address: 127.0.0.1
    port: {dead_port}
    username: ""
  relay-0:
    cls: ModbusTCPCoil
    host: "{rig}"
    coil: 0
"""


def lab_profile(text: str) -> str:
    """The emulator's profile as a lab bench's: no target (the place gives it), the rig's coils from the place."""
    text = re.sub(r'(?m)^target = "emulator"\n', "", text)
    text = re.sub(r"(?m)^time_scale = .*", f"time_scale = {SCALE}", text)
    text = re.sub(r'(?m)^\[faults\.(\w+)\]\nkind = "emulator".*$',
                  lambda m: f'[faults.{m[1]}]\nkind = "modbus-coil"\nfirst_coil = {RIG_FIRST_COIL[m[1]]}', text)
    assert 'kind = "emulator"' not in text and "target =" not in text
    return text + '\n[labgrid]\nwire = "plc-ethernet"\nrig = "relay-*"\n'


def start(lab: RunningLab, tmp: Path, name: str, reserve: list[str], tests: list[str], *pytest_args: str,
          python: Path | None = None) -> tuple[subprocess.Popen, Path]:
    """``hil run`` on the lab bench, from ``python``'s environment (labgrid-client beside it) or from this one
    (labgrid-client named by HIL_LABGRID_CLIENT); output to ``<name>.log``."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    env.pop("HIL_LABGRID_CLIENT", None)
    if python is None:
        env["HIL_LABGRID_CLIENT"] = str(lab.bin / "labgrid-client")
    else:  # that environment's hil is a copy (pip install 'hil[labgrid]'): this tree's code, its packages
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    log = tmp / f"{name}.log"
    with open(log, "w") as out:
        proc = processes.spawn(
            [str(python or sys.executable), "-m", "hil.cli.main", "run", "--bench", str(tmp / "lab.toml"),
             "--lg-coordinator", lab.coordinator, *reserve, "--junitxml", str(tmp / f"{name}.xml"),
             "--html", str(tmp / f"{name}.html"), "--", *tests, *pytest_args, "-p", "no:cacheprovider", "-rfE"],
            stdout=out, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, cwd=tmp, env=env)
    return proc, log


def fatek_status_through_ser2net(lab: RunningLab) -> str:
    """Hold bench1 with its serial port as the wire: the URL hil resolves for the NetworkSerialPort reaches the
    emulator's pty through the ser2net the exporter started (pyserial's RFC 2217 client, 7E1 set over the protocol),
    and the PLC answers a FATEK status request (command 40)."""
    import serial

    from hil.bench.lab.client import LabgridClient
    from hil.bench.lab.session import LabSession
    from hil.bench.lab.spec import LabSpec
    from hil.families.fbs.protocol.fatek import build_frame
    session = LabSession(LabSpec(place="bench1", coordinator=lab.coordinator, wire="plc-port0"),
                         client=LabgridClient(lab.coordinator, str(lab.bin / "labgrid-client")))
    held = session.open()
    try:
        found = re.fullmatch(r"fatek\+rfc2217://([\d.]+):(\d+)\?baudrate=9600&station=1", held.target)
        assert found, held.target
        port = serial.serial_for_url(f"rfc2217://{found[1]}:{found[2]}?ign_set_control", baudrate=9600, bytesize=7,
                                     parity="E", timeout=5)
        try:
            port.write(build_frame(1, "40"))
            return port.read_until(b"\x03").decode("ascii", "replace")
        finally:
            port.close()
    finally:
        assert session.close() == []


def properties(junit: Path) -> dict[str, str]:
    suite = ET.parse(junit).getroot().find("testsuite")
    assert suite is not None
    return {p.get("name"): p.get("value") for p in suite.iter("property")}


@pytest.mark.timeout(420)
def test_runs_queue_for_labgrid_places_and_always_let_go(tmp_path):
    emulated = tmp_path / "emulated.toml"
    emulated.write_text(bench_like(EMULATOR_BENCH.read_text()))
    (tmp_path / "lab.toml").write_text(lab_profile(emulated.read_text()))
    wires = {"fatek-tcp": "--fatek-tcp", "fatek-serial": "--fatek-serial", "rig-modbus-tcp": "--rig-modbus-tcp"}
    started = time.monotonic()
    with emulate_process(emulated, SCALE, wires) as emu, refused_port() as dead, \
            running_lab(tmp_path / "lab", exporter_config(emu, dead), PLACES) as lab:
        print(f"lab up after {time.monotonic() - started:.1f} s")
        a, a_log = start(lab, tmp_path, "A", ["--lg-place", "bench1"], SUITES)
        wait_for(a_log, r"labgrid place bench1 acquired", 60, a)
        b, b_log = start(lab, tmp_path, "B", ["--lg-reserve", TAGS], SUITES, python=lab.hil_python)
        c, c_log = start(lab, tmp_path, "C", ["--lg-place", "bench1"], SMOKE)
        d, d_log = start(lab, tmp_path, "D", ["--lg-place", "dead"], SMOKE)
        e, e_log = start(lab, tmp_path, "E", ["--lg-place", "bench2"], SMOKE, "--hil-lock-wait", "300")
        f, f_log = start(lab, tmp_path, "F", ["--lg-place", "bench1", "--lg-wait", "2"], SMOKE)
        g, g_log = start(lab, tmp_path, "G", ["--lg-reserve", "family=s7"], SMOKE)

        c_token = wait_for(c_log, r"queued for labgrid place bench1 \(reservation (\w+)", 60, c).group(1)
        c.send_signal(signal.SIGTERM)
        # E holds bench2; next, before collecting anything, it waits for A's lock on the PLC (hil.plugin.preflight)
        wait_for(e_log, r"labgrid place bench2 acquired", 60, e)
        time.sleep(1.0)
        assert a.poll() is None, "A finished before E reached the PLC's lock: the lock wait was not exercised"
        e.send_signal(signal.SIGTERM)
        runs = {"A": (a, a_log), "B": (b, b_log), "C": (c, c_log), "D": (d, d_log), "E": (e, e_log), "F": (f, f_log),
                "G": (g, g_log)}
        codes = {name: proc.wait(timeout=300) for name, (proc, _) in runs.items()}
        logs = {name: log.read_text() for name, (_, log) in runs.items()}
        print(f"all runs done after {time.monotonic() - started:.1f} s: exit codes {codes}")
        events = lab.events("bench1")
        status = fatek_status_through_ser2net(lab)
        reservations = lab.client("reservations")
        shown = {place: lab.client("show", place=place) for place in PLACES}

    for name in ("A", "B"):  # both ran the suites, one after the other, on bench1
        assert codes[name] == 0, logs[name][-5000:]
        assert re.search(r"\d+ passed", logs[name]) and " failed" not in logs[name].splitlines()[-2], logs[name][-3000:]
    a_props, b_props = properties(tmp_path / "A.xml"), properties(tmp_path / "B.xml")
    for props in (a_props, b_props):
        assert props["hil.lab.place"] == "bench1"
        assert props["hil.lab.tags"] == TAGS
        assert props["hil.lab.exporter"] == "lab-host"
        assert props["hil.lab.coordinator"] == lab.coordinator
        assert props["hil.target"] == f"fatek+tcp://{emu['fatek-tcp']}?station=1"
        assert re.fullmatch(r"fatek\+rfc2217://127\.0\.0\.1:\d+\?baudrate=9600&station=1",
                            props["hil.lab.url.plc-port0"])
        assert props["hil.lab.rig"] == f"modbus+tcp://{emu['rig-modbus-tcp']}?unit=1 coils 0-95"
        assert "bench1" in (tmp_path / "A.html").read_text()
    assert a_props["hil.lab.reserved_by"] == "place bench1"
    assert b_props["hil.lab.reserved_by"] == f"tags {TAGS}"
    assert "queued for a labgrid place tagged family=fbs rtc=s35390a" in logs["B"]
    assert events == ["acquired", "released", "acquired", "released"], events  # A, then B; C never got in
    assert float(b_props["hil.lab.waited_s"]) > 1.0  # B waited in the queue for A

    assert status.startswith("\x020140"), status  # station 01 answered command 40, error code 0

    assert codes["C"] == 2, logs["C"][-3000:]  # SIGTERM while queued: interrupted, its reservation cancelled
    assert c_token not in reservations, reservations
    assert codes["D"] == 4, logs["D"][-3000:]  # the PLC does not answer: one line before collection, let go
    assert "labgrid place dead released" in logs["D"]
    assert codes["E"] == 2, logs["E"][-3000:]  # held bench2, waited for A's endpoint lock, SIGTERM: let go
    assert "labgrid place bench2 released" in logs["E"]
    assert "hil bench -" not in logs["E"]  # the panel of an open bench: E never opened it (A's lock kept it out)
    assert codes["F"] == 4 and "allocated to reservation" in logs["F"] and "within 2 s" in logs["F"], (
        logs["F"][-3000:])  # --lg-wait
    assert "labgrid reservation" in logs["F"] and "cancelled" in logs["F"]
    assert codes["G"] == 4, logs["G"][-3000:]  # tags no place has: refused at once, naming the places there are
    assert "no place on coordinator" in logs["G"] and "bench1 (family=fbs rtc=s35390a)" in logs["G"]
    for place, text in shown.items():
        assert "acquired: None" in text, f"{place} is still acquired:\n{text}"
    assert not reservations.strip(), reservations
