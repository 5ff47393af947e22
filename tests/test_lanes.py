"""Lanes (hil.plugin.lanes): one run's lanes in pytest-xdist workers sharing one PLC — over one serial line taken
in turn by whole exchanges (hil.io.shared_line), each lane journaling in its own file, the run failing when a lane
leaves the PLC changed, and a dead lane's journal replayed."""

from __future__ import annotations

import fcntl
import json
import multiprocessing
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from hil.core.journal import Journal, journal_path, lane_of
from hil.io.shared_line import SharedLine
from hil.io.url import parse_target
from hil.plugin import lanes
from tests.conftest import EMULATOR_BENCH, REPO
from tests.external import bench_over_the_wire, emulate_process, hil_emulate

LINE = "115200 7E1"  # 9600 costs minutes of line time here: benchmarks/run.py measures that one


@pytest.fixture
def private_dirs(tmp_path, monkeypatch):
    """This test's own lock and state directories (for its subprocesses too)."""
    monkeypatch.setenv("HIL_LOCK_DIR", str(tmp_path / "locks"))
    monkeypatch.setenv("HIL_STATE_DIR", str(tmp_path / "state"))
    return tmp_path


# -- the shared line ----------------------------------------------------------------------------------------------
def _hold_and_die(device: str, ready) -> None:
    line = SharedLine(device, taken=lambda suspect: None, leaving=lambda: False)
    line.__enter__()  # in the middle of an exchange…
    ready.set()
    time.sleep(60)  # …killed here


def test_a_holder_killed_mid_exchange_makes_the_next_one_resynchronise(private_dirs):
    """The mark is "suspect" while the line is held: a lane killed in the middle of an exchange (its late reply may
    still come) leaves it so, and the next holder is told; a clean release clears it."""
    device = str(private_dirs / "ttyFAKE")
    Path(device).touch()
    ctx = multiprocessing.get_context("fork")
    ready = ctx.Event()
    proc = ctx.Process(target=_hold_and_die, args=(device, ready))
    proc.start()
    assert ready.wait(60), "hang guard: the holder did not take the line within 60 s"
    seen: list[bool] = []
    line = SharedLine(device, taken=seen.append, leaving=lambda: False)
    proc.kill()
    proc.join()
    with line:  # the kernel dropped the dead holder's lock
        pass
    with line:
        pass
    assert seen == [True, False], "killed mid-exchange: suspect once; after a clean release: not"
    line.close()


class _Timers:
    """threading.Timer for hil.io.shared_line, fired by the test: LINGER's end is an event the test decides, not a
    stretch of host time a loaded host's stall could pass for."""

    def __init__(self) -> None:
        self.made: list[_Timer] = []

    def __call__(self, interval: float, function) -> _Timer:
        timer = _Timer(interval, function)
        self.made.append(timer)
        return timer


class _Timer:
    daemon = False

    def __init__(self, interval: float, function) -> None:
        self.interval, self.function = interval, function
        self.started = self.cancelled = False

    def start(self) -> None:
        self.started = True

    def cancel(self) -> None:
        self.cancelled = True

    def fire(self) -> None:
        """LINGER has passed (as a started Timer would run it)."""
        assert self.started and not self.cancelled
        self.function()


def test_a_foreground_client_keeps_the_line_across_back_to_back_exchanges(private_dirs, monkeypatch):
    """A background client (a named lane) asks only while no foreground client (the main lane) wants the line:
    during an exchange and for LINGER after it, so between back-to-back exchanges it cannot get in; once the
    foreground client pauses it can.  LINGER's timer is the test's (fired when the test says the pause is long
    enough): back to back is every exchange before the timer of the one before it fired, whatever the host does."""
    from hil.io import shared_line
    timers = _Timers()
    monkeypatch.setattr(shared_line, "threading", SimpleNamespace(RLock=threading.RLock, Timer=timers))
    device = str(private_dirs / "ttyFAKE")
    Path(device).touch()
    fore = SharedLine(device, taken=lambda s: None, leaving=lambda: False, background=False)
    back = SharedLine(device, taken=lambda s: None, leaving=lambda: False, background=True)
    got = threading.Event()

    def background() -> None:
        with back:
            got.set()

    with fore:
        asker = threading.Thread(target=background, daemon=True)
        asker.start()
        # a short look suffices: a slow host can only make the background client later, never let it in
        assert not got.wait(0.1), "the background client took a line the foreground client holds"
    for _ in range(20):  # back to back: each exchange before the last one's LINGER ended
        with fore:
            pass
        assert not got.is_set(), "a background exchange came between two back-to-back foreground ones"
    assert [t.interval for t in timers.made] == [shared_line.LINGER] * 21, "each exchange kept the line LINGER more"
    assert all(t.cancelled for t in timers.made[:-1]), "each back-to-back exchange took over the wait before it"
    timers.made[-1].fire()  # the foreground client paused: LINGER after its last exchange has passed
    assert got.wait(60), "hang guard: the foreground client paused but the background one did not get the line"
    asker.join(60)
    fore.close()
    back.close()


def _exchange_own_register(url: str, register: str, rounds: int, out) -> None:
    from hil.families.fbs.transport.factory import open_transport
    wrong = 0
    # a reply timeout of 30 s is a hang guard: on a busy host the other process's turn and hil emulate's reply may
    # take over a second, which the default (a bench's 1 s) would call lost
    with open_transport(parse_target(url), timeout=30.0) as transport:
        for n in range(rounds):
            transport.write(register, n)
            wrong += transport.read(register) != n
        out.put((register, wrong, transport.requests))


@pytest.mark.e2e
def test_two_processes_take_turns_on_one_paced_line_with_no_reply_crossed(private_dirs):
    """Two clients in two processes on ``hil emulate``'s paced pty, each writing and reading back its own register
    back to back (60 rounds each): every exchange is whole (no process reads the other's reply), so 0 wrong
    values."""
    profile = private_dirs / "emulated.toml"
    profile.write_text(EMULATOR_BENCH.read_text().replace("[emulator]\n", f'[emulator]\nline = "{LINE}"\n', 1))
    ctx = multiprocessing.get_context("spawn")
    with emulate_process(profile, 1.0, {"fatek-serial": "--fatek-serial"}) as where:
        url = f"fatek+serial://{where['fatek-serial']}?baudrate=115200&bytesize=7&parity=E&station=1"
        out = ctx.Queue()
        procs = [ctx.Process(target=_exchange_own_register, args=(url, reg, 60, out)) for reg in ("R1000", "R1001")]
        for proc in procs:
            proc.start()
        for proc in procs:
            proc.join(120)
        results = sorted(out.get(timeout=5) for _ in procs)
    assert [(reg, wrong) for reg, wrong, _ in results] == [("R1000", 0), ("R1001", 0)]
    assert all(requests >= 120 for _, _, requests in results)


# -- lane journals ----------------------------------------------------------------------------------------------
def test_a_lanes_journal_is_named_by_its_lane_and_found_beside_the_runs(tmp_path):
    key = "tcp://127.0.0.1:500"
    own = Journal(key, tmp_path)
    assert lane_of(own.path) is None and own.lane_names() == []
    lane = Journal(key, tmp_path, lane="gw1")
    lane.add_elements({"R1000": 5}, {"R1000": 6})
    assert lane.path == journal_path(key, tmp_path, "gw1") and lane_of(lane.path) == "gw1"
    found = [own.lane_journal(name) for name in own.lane_names()]
    assert [(j.lane, j.elements()) for j in found] == [("gw1", {"R1000": 5})]
    assert lane.lane_names() == [], "a lane's journal has no lanes of its own"
    from hil.core.journal import inspect  # what hil restore --show lists: a lane's file is a journal of the PLC too
    shown_key, shown, refused = inspect(lane.path)
    assert (shown_key, refused, shown.lane, shown.elements()) == (key, None, "gw1", {"R1000": 5})
    with pytest.raises(Exception, match="lane name"):
        journal_path(key, tmp_path, "../x")


# -- which runs may have lanes ------------------------------------------------------------------------------------
@pytest.mark.parametrize("url, dist, problem", [
    ("emulator", "load", None),  # each worker builds its own emulator
    ("fatek+tcp://127.0.0.1:500", "each", None),
    ("fatek+serial:///dev/ttyUSB0", "each", None),
    ("fatek+serial:///dev/ttyUSB0", "load", "--dist each"),
    ("fatek+rfc2217://127.0.0.1:3001", "each", "cannot share a fatek+rfc2217 wire"),
    ("modbus+rtu:///dev/ttyUSB0?unit=1", "each", "cannot share a modbus+rtu wire"),
])
def test_only_a_wire_lanes_can_share_and_dist_each_run_lanes_on_a_plc(url, dist, problem):
    config = SimpleNamespace(option=SimpleNamespace(dist=dist))
    said = lanes.check_run(config, parse_target(url))
    assert (said is None) if problem is None else (problem in said), said


# -- a run with lanes, end to end ---------------------------------------------------------------------------------
def _bench_on_the_paced_pty(tmp: Path, where: dict[str, str]) -> Path:
    url = f"fatek+serial://{where['fatek-serial']}?baudrate=115200&bytesize=7&parity=E&stopbits=1&station=1"
    bench = tmp / "bench.toml"
    bench.write_text(bench_over_the_wire(EMULATOR_BENCH.read_text(), where, 1.0, url=url))
    return bench


def _paced_emulator(tmp: Path):
    profile = tmp / "emulated.toml"
    profile.write_text(EMULATOR_BENCH.read_text().replace("[emulator]\n", f'[emulator]\nline = "{LINE}"\n', 1))
    return emulate_process(profile, 1.0, {"fatek-serial": "--fatek-serial", "rig-modbus-tcp": "--rig-modbus-tcp"})


def _lanes_run(tmp: Path, bench: Path, *tests: str, timeout: float = 240, **env: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pytest", *tests, "--bench", str(bench), "-n", "2", "--dist", "each",
                           "-v", "-p", "no:cacheprovider", "-p", "no:hypothesispytest",
                           f"--junitxml={tmp / 'junit.xml'}"], cwd=REPO, capture_output=True, text=True,
                          timeout=timeout, env={**os.environ, "PYTHONUNBUFFERED": "1", **env})


def test_the_smoke_and_rtc_suites_run_in_two_lanes_on_one_paced_line(private_dirs):
    """``hil run --lanes 2`` as pytest runs it, against ``hil emulate`` on its paced pty: the RTC suite in the clock
    lane, the smoke suite in the main lane, each lane in one worker, every test once; both lanes leave the PLC as
    found (no journal left), and the run is PASSED.  A lane waits for the other's turns on the line however long
    they take: the line wait ($HIL_LINE_WAIT, here 50 ms, far under one lane's busy stretch) bounds only a wait
    for a process that is not of this run."""
    with _paced_emulator(private_dirs) as where:
        bench = _bench_on_the_paced_pty(private_dirs, where)
        # the RTC suite's sets and read-outs (its midnights and running clock are a bench second each)
        run = _lanes_run(private_dirs, bench, str(REPO / "suites" / "test_smoke.py"),
                         str(REPO / "suites" / "test_rtc.py"), "-k", "smoke or sunday or r4135 or overwrites",
                         HIL_LINE_WAIT="0.05")
    out = run.stdout
    assert run.returncode == 0, out[-3000:]
    assert "ended without a word on the PLC" not in out, "each lane said how it left the PLC (its safety report)"
    workers = {}
    for worker, _outcome, nodeid in re.findall(r"\[(gw\d)\] \[ *\d+%\] (PASSED|SKIPPED|FAILED|ERROR) (\S+)", out):
        workers.setdefault(nodeid.split("::")[0], set()).add(worker)
    rtc, smoke = workers["suites/test_rtc.py"], workers["suites/test_smoke.py"]
    assert len(rtc) == 1 and len(smoke) == 1 and rtc != smoke, workers
    import xml.etree.ElementTree as ET
    cases = [(c.get("classname"), c.get("name"))
             for c in ET.parse(private_dirs / "junit.xml").getroot().iter("testcase")]
    assert len(cases) == len(set(cases)) and len(cases) >= 8, f"every test once: {sorted(cases)}"
    assert "hil: PASSED" in out or "PASSED" in out.splitlines()[-1], out[-1500:]
    left = list((private_dirs / "locks").glob("journal-*.json"))
    assert all(not Journal(json.loads(p.read_text())["bench"], p.parent, lane=lane_of(p)).pending for p in left)


LANE_MODULE = """
import os, signal, time
import pytest
pytestmark = pytest.mark.lane("{lane}")

def test_writes_then_dies(bench):
    bench.plc.io.write_words("{register}", [{value}])
    {kill}
    time.sleep(30 if {die} else 0)
"""


# (the gate kills the whole run; a lone worker killed is the matrix's: the gate's time)
@pytest.mark.parametrize("who", [pytest.param("worker", marks=pytest.mark.matrix), "run"])
def test_a_lane_killed_with_a_write_out_is_put_back(private_dirs, who):
    """A lane's worker SIGKILLed after its write: its lane journal holds the original.  ``worker``: the controller
    (still holding the locks) replays it before the run ends — the run is not PASSED, the PLC is as found.
    ``run``: the whole run killed (the controller first) — the next run's recovery replays the lane's journal."""
    tests = private_dirs / "lanes"
    tests.mkdir()
    kill = ("os.kill(os.getpid(), signal.SIGKILL)" if who == "worker"  # the worker alone
            else "os.kill(os.getppid(), signal.SIGKILL); os.kill(os.getpid(), signal.SIGKILL)")  # the controller too
    (tests / "test_dies.py").write_text(LANE_MODULE.format(lane="clock", register="R1000", value=77, die=True,
                                                           kill=kill))
    (tests / "test_main.py").write_text(LANE_MODULE.format(lane="main", register="R1001", value=5, die=False,
                                                           kill="pass"))
    (private_dirs / "next").mkdir()
    (private_dirs / "next" / "test_next.py").write_text("def test_next(bench):\n    pass\n")
    from hil.families.fbs.transport.factory import open_transport
    with _paced_emulator(private_dirs) as where:
        bench = _bench_on_the_paced_pty(private_dirs, where)
        url = f"fatek+serial://{where['fatek-serial']}?baudrate=115200&bytesize=7&parity=E&station=1"

        def registers() -> list[int]:
            with open_transport(parse_target(url), timeout=30.0) as transport:  # a hang guard, as above
                return transport.read_words("R1000", 2)

        assert registers() == [0, 0]
        run = subprocess.Popen([sys.executable, "-m", "pytest", str(tests), "--bench", str(bench), "-n", "2",
                                "--dist", "each", "-p", "no:cacheprovider", "-p", "no:hypothesispytest"],
                               cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                               start_new_session=True)
        out, _ = run.communicate(timeout=180)
        assert run.returncode != 0, "a run whose lane died is never PASSED"
        if who == "run":
            os.killpg(run.pid, signal.SIGKILL)  # the worker left behind, if any
            lane_journals = list((private_dirs / "locks").glob("journal-*.lane-*.json"))
            assert lane_journals, "the dead lane's journal is on disk"
            assert registers()[0] == 77, "nothing could put the lane's write back yet"
            nxt = subprocess.run([sys.executable, "-m", "pytest", str(private_dirs / "next"), "--bench", str(bench),
                                  "-p", "no:cacheprovider", "-q"], cwd=REPO, capture_output=True, text=True,
                                 timeout=120)
            assert nxt.returncode == 0 and "hil bench recovery: a previous run" in nxt.stdout, nxt.stdout[-2000:]
        else:
            assert "lane gw0 ended without a word on the PLC" in out, out[-3000:]
            assert "hil bench recovery: a previous run" in out, out[-3000:]
        assert registers() == [0, 0], out[-3000:]
    left = list((private_dirs / "locks").glob("journal-*.json"))
    assert all(not Journal(json.loads(p.read_text())["bench"], p.parent, lane=lane_of(p)).pending for p in left)


def test_a_lane_that_leaves_the_plc_changed_fails_the_run(private_dirs):
    """A worker that says it left the PLC changed (its safety report) fails the controller's run, whatever the
    tests' outcomes, and the run's word on the PLC names the lane."""
    from hil.plugin.safety import AS_FOUND, PLC_LEFT
    config = SimpleNamespace(stash={}, pluginmanager=SimpleNamespace(get_plugin=lambda name: None))
    config.stash[lanes._LANES_LEFT] = {}
    for worker, said in (("gw0", AS_FOUND), ("gw1", "the PLC is NOT as it was found: 1 element still changed")):
        lanes.pytest_testnodedown(SimpleNamespace(config=config, gateway=SimpleNamespace(id=worker),
                                                  workeroutput={lanes.LEFT: said}), None)
    session = SimpleNamespace(config=config, exitstatus=0)
    lanes._the_runs_word(session)
    assert session.exitstatus == pytest.ExitCode.TESTS_FAILED
    assert config.stash[PLC_LEFT].startswith("lane gw1: the PLC is NOT as it was found")


def _borrow_and_hold(address: str, inherited: int, said) -> None:
    from hil.core.lease import borrow
    os.close(inherited)  # (fork's copy of the lender's own descriptor: only what is borrowed may hold the lock)
    fds = borrow(address)
    said.put([os.get_inheritable(fd) for fd in fds])
    time.sleep(60)  # killed here


def test_a_borrowed_lock_file_holds_the_lock_after_the_lender_closed_its_own(tmp_path):
    """hil.core.lease: what a worker borrows is the controller's own open lock file, so the flock outlives the
    controller's descriptor until the worker is gone; close-on-exec, so nothing the worker starts holds it; lent
    only to the lender's own children."""
    from hil.core.errors import HilError
    from hil.core.lease import LockLender, borrow
    path = tmp_path / "bench.lock"
    own = os.open(path, os.O_RDWR | os.O_CREAT)
    fcntl.flock(own, fcntl.LOCK_EX | fcntl.LOCK_NB)
    lender = LockLender([own])
    ctx = multiprocessing.get_context("fork")
    said = ctx.Queue()
    worker = ctx.Process(target=_borrow_and_hold, args=(lender.address, own, said))
    worker.start()
    other = os.open(path, os.O_RDWR)
    try:
        assert said.get(timeout=60) == [False], "one lock file borrowed, close-on-exec"  # a hang guard
        with pytest.raises(HilError, match="lends them only to its run's own workers"):
            borrow(lender.address)  # this process is not the lender's child
        lender.close()
        os.close(own)  # the controller gone (its descriptor closed, no unlock)
        with pytest.raises(BlockingIOError):
            fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
        worker.kill()  # the last worker gone
        worker.join(60)
        fcntl.flock(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
    finally:
        worker.kill()
        os.close(other)


HOLDING_MODULE = """
import os
from pathlib import Path
import pytest
pytestmark = pytest.mark.lane("{lane}")

def test_holds_its_lane(bench):
    bench.plc.io.write_words("{register}", [{value}])
    Path({ready!r}).write_text(str(os.getpid()))
    for _ in range(1200):  # mid-test for a minute at most (a hang guard): the run is killed long before
        bench.plc.io.read_words("{register}", 1)
        bench.wait(0.05)
"""


def _gone(pid: int) -> bool:
    """The process has exited (a zombie until its new parent reaps it, or reaped)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] in "ZX"
    except (FileNotFoundError, ProcessLookupError):
        return True


#: the kernel's flag on a task inside exit() (include/linux/sched.h): set before it closes any file, so a process
#: seen with it is past its last write, whatever files its descriptor table still lists
PF_EXITING = 0x4


def _holds_nothing(pid: int) -> bool:
    """The process is gone, or inside its exit (which closes its sockets to the PLC and its lock files one by one,
    so its descriptor table may still list some just after the bench's lock is free): it can write nothing more."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return fields[0] in "ZX" or bool(int(fields[6]) & PF_EXITING) or not os.listdir(f"/proc/{pid}/fd")
    except (FileNotFoundError, ProcessLookupError):
        return True


def test_a_controller_killed_takes_its_lanes_with_it_and_keeps_the_bench_until_they_are_gone(private_dirs):
    """``hil run --lanes 2`` against ``hil emulate`` (FATEK/TCP), both lanes mid-test, their values on the PLC: the
    controller SIGKILLed alone.  The bench's lock is free only once no worker holds a file any more — a second run
    finds it busy until then — and no worker writes after (each lane's value stays, unrestored, until the next run
    replays the lanes' journals)."""
    from hil.core.lock import BenchBusy, BenchLock
    from hil.families.fbs.transport.factory import open_transport
    from tests import processes
    tests = private_dirs / "lanes"
    tests.mkdir()
    ready = {lane: private_dirs / f"{lane}.pid" for lane in ("clock", "main")}
    for (lane, register, value) in (("clock", "R1000", 77), ("main", "R1001", 5)):
        (tests / f"test_{lane}.py").write_text(HOLDING_MODULE.format(lane=lane, register=register, value=value,
                                                                     ready=str(ready[lane])))
    (private_dirs / "next").mkdir()
    (private_dirs / "next" / "test_next.py").write_text("def test_next(bench):\n    pass\n")
    with hil_emulate(EMULATOR_BENCH, 1.0) as where:
        bench = private_dirs / "bench.toml"
        bench.write_text(bench_over_the_wire(EMULATOR_BENCH.read_text(), where, 1.0))
        url = f"fatek+tcp://{where['fatek-tcp']}"

        def registers() -> list[int]:
            with open_transport(parse_target(url), timeout=30.0) as transport:
                return transport.read_words("R1000", 2)

        run = processes.spawn([sys.executable, "-m", "hil.cli.main", "run", "--bench", str(bench), "--lanes", "2",
                               "--junitxml", str(private_dirs / "r" / "junit.xml"), "--", str(tests), "-p",
                               "no:cacheprovider"], cwd=private_dirs, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
        try:
            deadline = time.monotonic() + 180  # a hang guard: two workers start and open the bench
            while not all(path.exists() and path.read_text() for path in ready.values()):
                assert run.poll() is None, "the run ended before both lanes were mid-test"
                assert time.monotonic() < deadline, "hang guard: the lanes never got mid-test"
                time.sleep(0.05)
            workers = [int(path.read_text()) for path in ready.values()]
            lock = BenchLock(url)
            with pytest.raises(BenchBusy):
                lock.acquire()
            os.kill(run.pid, signal.SIGKILL)  # the controller alone
            deadline = time.monotonic() + 60  # a hang guard
            while True:
                try:
                    lock.acquire()
                    break
                except BenchBusy:
                    assert time.monotonic() < deadline, "hang guard: the bench stayed locked"
                    time.sleep(0.01)
            busy = {pid for pid in workers if not _holds_nothing(pid)}
            assert not busy, f"the bench's lock was free while worker(s) {busy} still held files"
            left = registers()
            assert left == [77, 5], f"a lane wrote after its controller died: {left}"
            deadline = time.monotonic() + 60  # a hang guard: they are past closing their files
            while not all(_gone(pid) for pid in workers):
                assert time.monotonic() < deadline, "hang guard: a worker outlived its controller"
                time.sleep(0.01)
            assert registers() == left, "a worker wrote after the lock was free"
            lock.release()
        finally:
            processes.end(run, signal.SIGKILL, grace=0)
        nxt = subprocess.run([sys.executable, "-m", "pytest", str(private_dirs / "next"), "--bench", str(bench),
                              "-p", "no:cacheprovider", "-q"], cwd=REPO, capture_output=True, text=True, timeout=120)
        assert nxt.returncode == 0 and "hil bench recovery: a previous run" in nxt.stdout, nxt.stdout[-2000:]
        assert registers() == [0, 0], nxt.stdout[-2000:]


def test_a_lane_whose_controller_is_gone_stops_before_its_next_test():
    """The controller holds the run's locks; once it is gone (killed: the kernel dropped them) a lane must not go on
    writing to a PLC another run may now hold."""
    alive = SimpleNamespace(config=SimpleNamespace(workerinput={lanes.LEASE: os.getppid(), "workerid": "gw0"}))
    lanes.pytest_runtest_setup(alive)  # its controller is its parent: on it goes
    gone = SimpleNamespace(config=SimpleNamespace(workerinput={lanes.LEASE: os.getppid() + 99999, "workerid": "gw1"}))
    with pytest.raises(pytest.exit.Exception, match="controller .* is gone.*lane gw1 stops"):
        lanes.pytest_runtest_setup(gone)


def test_a_client_opening_a_shared_line_leaves_the_holders_reply_alone(private_dirs):
    """pyserial's open flushes the tty's input queue, which on a shared line is every lane's: a client opens the
    port only in its turn, so a reply already on its way to the lane holding the line is not thrown away (it was:
    a lane that started late made another's write "unanswered" on a busy host)."""
    from hil.families.fbs.protocol.fatek import FrameAssembler, Loopback, encode_request
    from hil.families.fbs.sim.plc import Emulator
    from hil.families.fbs.sim.serve_fatek import start_fatek_pty
    from hil.families.fbs.transport.fatek import FatekTransport
    server = start_fatek_pty(Emulator())
    holder = FatekTransport(server.address, timeout=30.0)
    late: list[FatekTransport] = []
    opener = threading.Thread(target=lambda: late.append(FatekTransport(server.address, timeout=30.0)))
    try:
        with holder._lock:  # the holder's exchange, by hand: the request out, the reply waiting unread
            holder._line.write(encode_request(1, Loopback("AB")))
            deadline = time.monotonic() + 20  # a hang guard
            while not holder._line.pending():
                assert time.monotonic() < deadline, "hang guard: the emulator never answered"
                time.sleep(0.001)
            opener.start()  # another lane's client opens the port now
            opener.join(0.5)  # (a slow host only delays it: this wait cannot make the test fail)
            assembler = FrameAssembler()
            while not (frames := assembler.feed(holder._line.receive(0.2))):
                assert time.monotonic() < deadline, "the holder's reply was thrown away by the other client's open"
        assert b"AB" in frames[0], frames  # the loop-back's own reply
    finally:
        opener.join(60)
        for client in [holder, *late]:
            client.close()
        server.stop()
