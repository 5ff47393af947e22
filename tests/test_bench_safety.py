"""Bench safety (issue 15): the durable journal, the PLC's own side effects, the clock's offset, retried
restores, one run per PLC whatever the spelling, and a lock directory nobody can plant a link in."""

from __future__ import annotations

import contextlib
import datetime as dt
import json
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from hil.bench.profile import load_profile
from hil.core.errors import HilError, RestoreError
from hil.core.journal import Journal
from hil.core.lock import BenchBusy, BenchLock, lock_dir, lock_key
from hil.families.fbs.bench import Bench
from hil.families.fbs.rtc_time import RtcTime
from tests import processes
from tests.conftest import EMULATOR_BENCH, REPO
from tests.external import bench_over_the_wire, hil_emulate


# -- the journal file ----------------------------------------------------------------------------------------------
def test_journal_is_on_disk_with_bench_test_and_pid_and_keeps_the_first_original(tmp_path):
    journal = Journal("tcp://127.0.0.1:500", tmp_path)
    journal.test = "suites/test_x.py::test_y"
    journal.add_elements({"R100": 7})
    journal.add_elements({"R100": 9, "M1": 1})  # R100 keeps its first (older) original
    data = json.loads(journal.path.read_text())  # what a fresh process would see
    assert data["bench"] == "tcp://127.0.0.1:500"
    assert data["elements"]["R100"]["original"] == 7 and data["elements"]["M1"]["original"] == 1
    assert data["elements"]["R100"]["test"] == "suites/test_x.py::test_y"
    assert data["elements"]["R100"]["pid"] == os.getpid()
    assert os.stat(journal.path).st_mode & 0o777 == 0o660  # the bench group's: the next user recovers it
    assert Journal("tcp://127.0.0.1:500", tmp_path).elements() == {"R100": 7, "M1": 1}
    journal.drop_elements(["R100", "M1"])
    assert not journal.path.exists() and not list(tmp_path.glob(".*tmp"))


# -- side effects: FUN86 loads its defaults into PR/IR/DR on EN's first rising edge -----------------------------
def test_tuned_gains_are_restored_after_a_passing_test_switched_en_on():
    bench = Bench(load_profile(EMULATOR_BENCH), target="emulator")
    try:
        pid = bench.plc.pid
        inst = pid.config.instances[0]
        tuned = {str(inst.operand(k, p)): v for p in inst.points for k, v in (("pr", 250), ("ir", 20), ("dr", 40))}
        bench.raw.write_many(tuned)
        bench.begin_test("test_only_switches_en_on")
        pid.enable(inst, True, heating=True)  # the test writes EN and H/C only
        bench.wait(5)
        assert pid.gains(inst.points[0]) == (110, 17, 50), "precondition: FUN86's first execution loaded its defaults"
        bench.end_test()
        assert bench.raw.read_many(list(tuned)) == list(tuned.values())
    finally:
        bench.close()


# -- benches reached over a wire: `hil emulate` as a separate process ------------------------------------------
class Proxy:
    """A TCP forwarder to the PLC that can be taken away (connections refused and cut) and brought back."""

    def __init__(self, upstream: str) -> None:
        host, port = upstream.rsplit(":", 1)
        self.upstream = (host, int(port))
        self.up = True
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.conns: list[socket.socket] = []
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self.server.accept()
            except OSError:
                return
            if not self.up:
                client.close()
                continue
            upstream = socket.create_connection(self.upstream)
            self.conns += [client, upstream]
            for a, b in ((client, upstream), (upstream, client)):
                threading.Thread(target=self._pipe, args=(a, b), daemon=True).start()

    def _pipe(self, a: socket.socket, b: socket.socket) -> None:
        try:
            while self.up:
                data = a.recv(65536)
                if not data:
                    break
                b.sendall(data)
        except OSError:
            pass
        for s in (a, b):
            with contextlib.suppress(OSError):
                s.close()

    def away(self) -> None:
        self.up = False
        for s in self.conns:
            try:
                s.shutdown(socket.SHUT_RDWR)
                s.close()
            except OSError:
                pass
        self.conns.clear()

    def back(self) -> None:
        self.up = True

    def close(self) -> None:
        self.away()
        self.server.close()


@pytest.fixture(scope="module")
def emulated(tmp_path_factory):
    path = tmp_path_factory.mktemp("emulated") / "emulated.toml"
    path.write_text(EMULATOR_BENCH.read_text())
    with hil_emulate(path, 1) as where:
        yield where


def _profile(tmp_path, where, target=None):
    text = bench_over_the_wire(EMULATOR_BENCH.read_text(), where, 1)
    text = text.replace("timeout = ", "timeout = 0.5 #", 1) if "timeout = " in text else text
    if target:
        text = text.replace(f'target = "fatek+tcp://{where["fatek-tcp"]}"', f'target = "{target}"')
    path = tmp_path / "bench.toml"
    path.write_text(text)
    return load_profile(path)


@pytest.mark.e2e
def test_a_restore_that_fails_while_the_plc_is_away_is_completed_when_it_returns(tmp_path, emulated):
    proxy = Proxy(emulated["fatek-tcp"])
    bench = Bench(_profile(tmp_path, emulated, f"fatek+tcp://127.0.0.1:{proxy.port}"))
    try:
        original = bench.raw.read("R100")
        bench.begin_test("test_one")
        bench.plc.io.write("R100", (original + 1234) & 0xFFFF)
        proxy.away()
        with pytest.raises(RestoreError):
            bench.end_test()
        assert "R100" in Journal(bench.journal.key).elements(), "the unrestored original stays on disk"
        proxy.back()
        bench.begin_test("test_two")  # the next test first completes the restore
        assert bench.raw.read("R100") == original
        assert not bench.journal.path.exists()
    finally:
        bench.close()
        proxy.close()


def _offset(bench) -> float:
    """The PLC clock minus the host's wall clock (UTC), seconds."""
    plc = RtcTime.from_registers(bench.raw.read_words("R4128", 7)).to_datetime()
    host = dt.datetime.now(dt.UTC).replace(tzinfo=None)
    return (plc - host).total_seconds()


@pytest.mark.e2e
def test_a_far_time_zone_leaves_the_clocks_offset_unchanged(tmp_path, emulated, monkeypatch):
    bench = Bench(_profile(tmp_path, emulated))
    try:
        before = _offset(bench)
        monkeypatch.setenv("TZ", "Asia/Tokyo")
        time.tzset()
        bench.begin_test("test_sets_the_clock")
        bench.plc.rtc.set(dt.datetime(2099, 12, 31, 23, 59))
        bench.end_test()
        after = _offset(bench)
        assert abs(after - before) < 2.0, f"the clock's offset from host time moved by {after - before:.1f} s"
    finally:
        monkeypatch.delenv("TZ")
        time.tzset()
        bench.close()


# -- one run per PLC, whatever the spelling ------------------------------------------------------------------------
@pytest.mark.parametrize("other", ["fatek+tcp://localhost:500", "FATEK+TCP://127.0.0.1", "fatek+tcp://127.0.0.1:500/",
                                   "fatek+tcp://LOCALHOST/?station=1"])
def test_two_spellings_of_one_plc_are_one_bench(other):
    assert lock_key(other) == lock_key("fatek+tcp://127.0.0.1:500")
    with BenchLock("fatek+tcp://127.0.0.1:500").acquire(), pytest.raises(BenchBusy):
        BenchLock(other).acquire()


def test_different_ports_are_different_benches():
    assert lock_key("fatek+tcp://127.0.0.1:500") != lock_key("fatek+tcp://127.0.0.1:501")


def test_an_rfc2217_line_is_keyed_by_its_servers_endpoint():
    """Whichever protocol the line behind an RFC 2217 server speaks, one server port is one bench."""
    assert lock_key("fatek+rfc2217://LOCALHOST:3001/?station=1") == "tcp://127.0.0.1:3001"
    assert lock_key("modbus+rfc2217://127.0.0.1:3001?unit=1") == lock_key("fatek+rfc2217://localhost:3001")
    assert lock_key("fatek+rfc2217://127.0.0.1:3001") != lock_key("fatek+rfc2217://127.0.0.1:3002")


def test_a_planted_symlink_at_the_lock_path_is_refused(tmp_path, monkeypatch):
    monkeypatch.setenv("HIL_LOCK_DIR", str(tmp_path / "locks"))
    victim = tmp_path / "victim"
    victim.write_text("precious")
    lock = BenchLock("fatek+tcp://127.0.0.1:500")
    lock.directory.mkdir(mode=0o700)
    os.symlink(victim, lock.path)
    with pytest.raises(HilError, match="symbolic link"):
        lock.acquire()
    assert victim.read_text() == "precious"


def test_the_lock_directory_is_shared_by_every_user_of_the_host(tmp_path, monkeypatch):
    """Issue 25 item 4, issue 40 item 11: two users on one host are kept apart — one directory for all, the bench
    group's (2770, each lock file 0660, tests/test_bench_dir.py); a world-writable directory is refused."""
    monkeypatch.delenv("HIL_LOCK_DIR", raising=False)
    assert lock_dir() == Path("/var/tmp/hil")  # the same for every user, and it outlives a reboot
    monkeypatch.setenv("HIL_LOCK_DIR", str(tmp_path / "locks"))
    with BenchLock("fatek+tcp://127.0.0.1:500").acquire() as lock:
        assert os.stat(lock.path.parent).st_mode & 0o7777 == 0o2770
        assert os.stat(lock.path).st_mode & 0o777 == 0o660
    loose = tmp_path / "loose"
    loose.mkdir()
    os.chmod(loose, 0o777)
    with pytest.raises(HilError, match="writable by everyone"):
        BenchLock("fatek+tcp://127.0.0.1:500", loose).acquire()


@pytest.mark.e2e
def test_hil_rtc_set_refuses_while_a_run_holds_the_bench(tmp_path, emulated):
    url = f"fatek+tcp://{emulated['fatek-tcp']}"
    other = url.replace("127.0.0.1", "localhost")
    with BenchLock(url).acquire():
        proc = subprocess.run([sys.executable, "-m", "hil.cli.main", "rtc", "set", other, "2099-12-31 23:59:00"],
                              capture_output=True, text=True, cwd=REPO, timeout=60, env=os.environ.copy())
    assert proc.returncode == 4, proc.stdout + proc.stderr
    assert "in use by pid" in proc.stderr


# -- recovery first ----------------------------------------------------------------------------------------------
@pytest.mark.e2e
def test_a_dead_runs_journal_is_replayed_by_the_next_session_loudly(tmp_path, emulated, pytester):
    profile = _profile(tmp_path, emulated)
    bench = Bench(profile)
    original = bench.raw.read_many(["R100", "M0"])
    bench.begin_test("test_that_died")
    bench.plc.io.write_many({"R100": (original[0] + 77) & 0xFFFF, "M0": 1})
    bench.close()  # a run that died: no restore; the journal stays behind
    assert Journal(bench.journal.key).pending
    pytester.makepyfile(test_next="def test_next(bench):\n    pass\n")
    junit = tmp_path / "junit.xml"
    result = pytester.runpytest_inprocess("--bench", str(profile.path), "-q", f"--junitxml={junit}",
                                          "-p", "no:cacheprovider", "-p", "no:hypothesispytest")
    result.assert_outcomes(passed=2)
    result.stdout.fnmatch_lines(
        ["*hil bench recovery: a previous run on tcp://127.0.0.1:* died*restored and verified*"])
    xml = junit.read_text()
    assert 'name="hil_bench_recovery"' in xml and 'name="bench_recovery"' in xml
    import xml.etree.ElementTree as ET
    suite = ET.fromstring(xml).find("testsuite")
    assert any(p.get("name") == "hil_bench_recovery" and "restored and verified" in p.get("value", "")
               for p in suite.findall("properties/property")), "recovery is a testsuite property"
    recovery = next(c for c in suite.iter("testcase") if c.get("name") == "bench_recovery")
    assert recovery.get("classname") == "hil.bench"  # not an empty classname (issue 24)
    assert ET.fromstring(xml).get("name") == f"hil run on bench {profile.name}"  # not pytest's "pytest tests"
    check = Bench(profile)
    try:
        assert check.raw.read_many(["R100", "M0"]) == original
        assert not check.journal.path.exists()
    finally:
        check.close()


# -- no unguarded path from a suite --------------------------------------------------------------------------------
BYPASSES = '''
import pytest
from hil.core.errors import WriteRefused
from hil.plugin.pytest_plugin import BENCH_SESSION


@pytest.fixture
def real(request):  # the harness's own bench, to count what reached the PLC
    return request.config.stash[BENCH_SESSION].bench


def _sent(real):
    return real.raw.emulator.stats["requests"]


@pytest.mark.parametrize("path", ["raw", "io", "journal", "faults.bench", "plc.io.inner", "plc.io._write_words",
                                  "plc.io._write_many", "plc.io._exchange", "plc.rtc.plc.io.inner",
                                  "faults.sensor_break._set"])
def test_no_way_round_the_guard(bench, path):
    obj = bench
    with pytest.raises(AttributeError):
        for part in path.split("."):
            obj = getattr(obj, part)


def test_run_stop_refused_without_destructive(bench, real):
    before = _sent(real)
    with pytest.raises(WriteRefused, match="command 41"):
        bench.plc.io.set_running(False)
    assert _sent(real) == before and real.raw.status().running


def test_bit_action_on_a_bit_outside_the_allow_list_refused(bench, real):
    before = _sent(real)
    with pytest.raises(WriteRefused):
        bench.plc.io.bit_action("M502", 1)
    assert _sent(real) == before


def test_disable_a_writable_bit(bench, real):
    bench.plc.io.bit_action("M1000", 1)
    assert real.raw.read_disabled("M1000") == [1]


def test_it_was_re_enabled(bench, real):
    assert real.raw.read_disabled("M1000") == [0]


def test_cannot_write_outside_the_allow_list(bench, real):
    before = _sent(real)
    with pytest.raises(WriteRefused):
        bench.plc.io.write_words("R2000", [1])
    assert _sent(real) == before
'''


def test_every_bypass_is_refused_before_a_byte_is_sent(pytester):
    text = EMULATOR_BENCH.read_text().replace('target = "emulator"', 'target = "emulator+fatek-tcp"')
    text = text.replace("allow_destructive = true", "allow_destructive = false")
    bench = pytester.makefile(".toml", bench=text)
    pytester.makepyfile(test_bypass=BYPASSES)
    result = pytester.runpytest_inprocess("--bench", str(bench), "-p", "no:cacheprovider", "-p", "no:hypothesispytest")
    result.assert_outcomes(passed=15)


@pytest.mark.e2e
def test_a_fault_rig_pointing_at_the_plc_under_test_is_refused(tmp_path, emulated):
    text = bench_over_the_wire(EMULATOR_BENCH.read_text(), emulated, 1)
    plc = emulated["fatek-tcp"]
    text = text.replace(f'modbus+tcp://{emulated["rig-modbus-tcp"]}', f"modbus+tcp://localhost:{plc.rsplit(':', 1)[1]}")
    path = tmp_path / "bench.toml"
    path.write_text(text)
    bench = Bench(load_profile(path))
    try:
        with pytest.raises(HilError, match="is the PLC under test"):
            bench.faults.sensor_break.open(0)
    finally:
        bench.close()


@pytest.mark.e2e
def test_rig_coils_have_their_own_allow_list(tmp_path, emulated):
    text = bench_over_the_wire(EMULATOR_BENCH.read_text(), emulated, 1)
    text = text.replace("first_coil = 0", 'first_coil = 0\ncoils = "0-3"', 1)
    path = tmp_path / "bench.toml"
    path.write_text(text)
    bench = Bench(load_profile(path))
    try:
        bench.begin_test("t")
        bench.faults.sensor_break.open(2)
        with pytest.raises(HilError, match="not in \\[faults\\] coils"):
            bench.faults.sensor_break.open(5)
        bench.end_test()
    finally:
        bench.close()


# -- no wrong values from late replies -----------------------------------------------------------------------------
def test_delayed_duplicates_never_make_a_wrong_original_or_a_false_verified_restore():
    """Replies repeated 1–50 ms later ("echo" in the wire fault plan) land after the next request; every read is
    fenced (4E loop-back with a nonce), so neither a plain read nor the guard's journal takes one for its answer."""
    import dataclasses
    profile = dataclasses.replace(load_profile(EMULATOR_BENCH), wire_faults={"echo": 0.3, "seed": 7})
    bench = Bench(profile, target="emulator+fatek-tcp")
    try:
        plan = bench.raw.server.faults
        plan.enabled = False
        truth = {f"R{1000 + k}": 100 + k for k in range(40)}
        bench.raw.write_many(truth)
        plan.enabled = True
        plain = [f"{n} = {got}, is {v}" for _ in range(5) for n, v in truth.items() if (got := bench.raw.read(n)) != v]
        wrong = []
        for name, value in truth.items():
            bench.begin_test(name)
            bench.plc.io.write(name, 9999)
            if bench.io.journal[list(bench.io.journal)[0]] != value:
                wrong.append(f"{name}: journaled {bench.io.journal}")
            bench.end_test()
        plan.enabled = False
        time.sleep(0.1)
        bench.raw.reopen()
        assert [bench.raw.read(n) for n in truth] == list(truth.values())
        assert wrong == [], wrong
        assert plain == [], plain
        assert bench.raw.fenced_out > 0, "the fault plan must land repeats in reads, or this test proves nothing"
    finally:
        bench.close()


# -- signals -------------------------------------------------------------------------------------------------------
def test_a_signal_during_a_restore_waits_for_it_and_a_second_one_changes_nothing():
    import signal as sig

    from hil.core import signals
    signals.install()
    finished = []
    try:
        with pytest.raises(KeyboardInterrupt, match="SIGTERM"), signals.shielded():
            os.kill(os.getpid(), sig.SIGTERM)
            time.sleep(0.05)
            os.kill(os.getpid(), sig.SIGHUP)  # a second signal while the restore runs
            time.sleep(0.05)
            finished.append("restore")
        assert finished == ["restore"]
        os.kill(os.getpid(), sig.SIGTERM)  # the run is unwinding: later signals do not abandon that
        time.sleep(0.05)
    finally:
        signals.uninstall()


SLEEPER = '''
import time

def test_writes_then_hangs(bench):
    bench.plc.io.write("R1000", 4242)
    print("written", flush=True)
    time.sleep(60)
'''


@pytest.mark.e2e
@pytest.mark.parametrize("signame", ["SIGHUP", "SIGTERM"])
def test_sighup_and_sigterm_unwind_and_restore(tmp_path, emulated, signame):
    import signal as sig
    profile = _profile(tmp_path, emulated)
    (tmp_path / "test_sleeper.py").write_text(SLEEPER)
    bench = Bench(profile)
    try:
        before = bench.raw.read("R1000")
        child = processes.spawn([sys.executable, "-m", "pytest", str(tmp_path / "test_sleeper.py"), "-s", "-q",
                                  "--bench", str(profile.path), "-p", "no:cacheprovider", "-p", "no:hypothesispytest"],
                                 cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                 env=os.environ.copy())
        for line in child.stdout:
            if "written" in line:
                break
        assert bench.raw.read("R1000") == 4242
        child.send_signal(getattr(sig, signame))
        child.wait(timeout=30)
        assert bench.raw.read("R1000") == before
        assert not Journal(bench.journal.key).pending
    finally:
        bench.close()


def test_a_session_ending_with_values_unrestored_fails_naming_each(pytester):
    text = EMULATOR_BENCH.read_text().replace('target = "emulator"', 'target = "emulator+fatek-tcp"')
    bench = pytester.makefile(".toml", bench=text.replace("time_scale = 1.0", "time_scale = 1.0\ntimeout = 0.5"))
    pytester.makepyfile(test_gone='''
import pytest
from hil.plugin.pytest_plugin import BENCH_SESSION


def test_writes_then_the_plc_goes_for_good(bench, request):
    bench.plc.io.write_many({"R1000": 42, "M1000": 1})
    request.config.stash[BENCH_SESSION].bench.raw.server.stop()
''')
    result = pytester.runpytest_inprocess("--bench", str(bench), "-q", "-p", "no:cacheprovider",
                                          "-p", "no:hypothesispytest")
    assert result.ret != 0
    result.stdout.fnmatch_lines(["*the PLC is NOT as it was found — still unrestored*R1000 (original 0)*"
                                 "M1000 (original 0)*"])


@pytest.mark.e2e
def test_hil_restore_shows_and_replays_a_dead_runs_journal(tmp_path, emulated):
    profile = _profile(tmp_path, emulated)
    bench = Bench(profile)
    original = bench.raw.read("R1001")
    bench.begin_test("suites/test_x.py::test_died")
    bench.plc.io.write("R1001", (original + 5) & 0xFFFF)
    bench.close()  # died: nothing restored
    run = lambda *args: subprocess.run([sys.executable, "-m", "hil.cli.main", "restore", *args],  # noqa: E731
                                       capture_output=True, text=True, cwd=REPO, timeout=60, env=os.environ.copy())
    shown = run("--show")
    assert shown.returncode == 0 and "R1001" in shown.stdout and "test_died" in shown.stdout, shown.stdout
    done = run("--bench", str(profile.path))
    assert done.returncode == 0 and "restored and verified" in done.stdout, done.stdout + done.stderr
    check = Bench(profile)
    try:
        assert check.raw.read("R1001") == original and not check.journal.path.exists()
    finally:
        check.close()
    assert "nothing pending" in run("--show").stdout
