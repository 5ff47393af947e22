"""Recovery that trusts nothing it cannot prove (issue 25, items 1–4 and 8–12), against ``hil emulate`` as a
separate process: FATEK/TCP, Modbus/TCP and the fault rig, reached only over their wires.

Each test plants or provokes one way a journal could make recovery write what it must not, and checks the PLC
over the wire afterwards: nothing written that could not be proven, every refusal named, the journal kept.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from hil.bench.family import open_bench
from hil.bench.profile import load_profile
from hil.cli.main import main as hil
from hil.core.errors import HilError, ProfileError
from hil.core.journal import Journal, JournalError, journal_path
from hil.core.lock import BenchLock, lock_key, plc_key
from hil.families.fbs.transport.factory import open_transport
from hil.io.url import parse_target
from tests import processes
from tests.broken import BrokenEmulator  # noqa: F401 - the factory tests.broken_emulate finds here
from tests.conftest import EMULATOR_BENCH, REPO
from tests.external import bench_over_the_wire, hil_emulate

NOW = "2026-01-01T00:00:00+00:00"  # replaced by the current time in planted entries (see _stamp)


@pytest.fixture(scope="module")
def plc():
    """One ``hil emulate`` (FATEK/TCP, Modbus/TCP, the rig) for this module's tests; each leaves it as found."""
    with hil_emulate(EMULATOR_BENCH, 1.0, modbus=True) as where:
        yield where


def _url(where: dict, wire: str = "fatek-tcp") -> str:
    return f"fatek+tcp://{where['fatek-tcp']}" if wire == "fatek-tcp" else f"modbus+tcp://{where['modbus-tcp']}?unit=1"


def _profile(tmp_path: Path, where: dict, name: str = "bench", *, wire: str = "fatek-tcp", plc_id: str | None = None,
             destructive: bool = True, rig: str | None = None, volatile: str | None = None) -> Path:
    text = bench_over_the_wire(EMULATOR_BENCH.read_text(), where, 1.0, wire=wire)
    if plc_id:
        text = text.replace("[bench]\n", f'[bench]\nplc_id = "{plc_id}"\n', 1)
    if not destructive:
        text = text.replace("allow_destructive = true", "allow_destructive = false")
    if rig:
        text = text.replace(f"modbus+tcp://{where['rig-modbus-tcp']}?unit=1", rig)
    if volatile:
        text = text.replace("allow_destructive =", f"volatile = {volatile}\nallow_destructive =", 1)
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def _plc(where: dict):
    return open_transport(parse_target(_url(where)), timeout=2.0)


def _state(where: dict) -> dict:
    """What a planted journal would change: R1000–R1003, R2000, Y0, Y1, M1001, their enables, RUN/STOP, the clock."""
    with _plc(where) as t:
        words = t.read_words("R1000", 4) + t.read_words("R2000", 1)
        bits = t.read_bits("Y0", 2) + t.read_bits("M1001", 1)
        disabled = t.read_disabled("Y0", 2) + t.read_disabled("M1001", 1)
        year = t.read("R4133")
        return {"words": words, "bits": bits, "disabled": disabled, "run": t.status().running, "year": year}


def _stamp(entry: dict) -> dict:
    import datetime as dt
    return {"test": "planted", "pid": 1, "at": dt.datetime.now(dt.UTC).isoformat(), **entry}


def _journal(key: str, where: dict, **sections) -> dict:
    data = {"version": 2, "bench": key, "endpoint": lock_key(_url(where)), "plc": None, "created": NOW,
            "elements": {}, "coils": {}, "clock": None, "run": None, "disabled": []}
    data.update(sections)
    return data


def _planted(key: str, where: dict) -> dict:
    """Issue 25 item 1's journal: R2000 = 4242, Y0 = 1, Y1 disabled, STOP, the clock in 2001, and a "rig coil" on
    the PLC's own Modbus port."""
    modbus = f"modbus+tcp://{where['modbus-tcp']}?unit=1"
    return _journal(key, where, elements={"R2000": _stamp({"original": 4242, "wrote": 0}),
                                          "Y0": _stamp({"original": 1, "wrote": 0})},
                    run=_stamp({"original": False, "wrote": True}), disabled=["Y1"],
                    clock=_stamp({"plc": "2001-01-01T00:00:00", "host": 1.0e9, "scale": 1.0}),
                    coils={"planted": _stamp({"target": modbus, "coil": 0, "unit": 1, "original": True,
                                              "wrote": False})})


def _session(tmp_path: Path, bench: Path, body: str, name: str = "s") -> subprocess.CompletedProcess:
    """A pytest session in a child process on ``bench`` running one test with ``body``."""
    folder = tmp_path / name
    folder.mkdir()
    (folder / "test_it.py").write_text("import os, signal\n\n\ndef test_it(bench):\n"
                                       + "".join(f"    {line}\n" for line in body.strip().splitlines()))
    return subprocess.run([sys.executable, "-m", "pytest", str(folder), "--bench", str(bench), "-q",
                           "-p", "no:cacheprovider", "-p", "no:hypothesispytest"],
                          cwd=REPO, capture_output=True, text=True, timeout=120, env=os.environ.copy())


KILL = "os.kill(os.getpid(), signal.SIGKILL)"


def _restore(capsys, *args: str) -> tuple[int, list[str]]:
    return _restore_like(capsys, "restore", *args)


def _restore_like(capsys, *argv: str) -> tuple[int, list[str]]:
    """``hil ARGV`` in this process: its exit code and its non-empty output lines (stdout and stderr)."""
    code = hil(list(argv))
    out = capsys.readouterr()
    return code, [line for line in (out.out + out.err).splitlines() if line.strip()]


# -- item 1: a planted journal --------------------------------------------------------------------------------
@pytest.mark.e2e
def test_a_journal_in_a_bench_directory_others_can_write_is_refused_and_nothing_written(plc, tmp_path, monkeypatch,
                                                                                        capsys):
    """A 1777 bench directory (as /tmp): whoever could write there may have planted the journal."""
    shared = tmp_path / "shared"
    shared.mkdir()
    os.chmod(shared, 0o1777)
    monkeypatch.setenv("HIL_LOCK_DIR", str(shared))
    url = _url(plc)
    path = journal_path(lock_key(url), shared)
    path.write_text(json.dumps(_planted(lock_key(url), plc)))
    os.chmod(path, 0o600)
    before, raw = _state(plc), path.read_bytes()
    code, lines = _restore(capsys, url, "--bench", str(_profile(tmp_path, plc)))
    assert code != 0 and len(lines) == 1 and "writable by everyone" in lines[0], lines
    assert _state(plc) == before and path.read_bytes() == raw


def _as_nobody(code: str) -> None:
    import pwd
    nobody = pwd.getpwnam("nobody")

    def drop() -> None:
        os.setgid(nobody.pw_gid)
        os.setuid(nobody.pw_uid)
    python = "/usr/bin/python3" if os.path.exists("/usr/bin/python3") else sys.executable  # one nobody may run
    subprocess.run([python, "-c", code], check=True, preexec_fn=drop, timeout=30, cwd="/")


@pytest.mark.skipif(os.getuid() != 0, reason="a journal owned by another user can only be made as root "
                                             "(os.setuid to nobody); the directory check is tested above")
@pytest.mark.e2e
def test_a_journal_planted_by_another_user_is_refused_and_nothing_written(plc, tmp_path, capsys):
    """Another user (nobody) writes a journal named as hil names them; it is moved into our private state
    directory (as a careless copy would): refused by its owner, by `hil restore` and by the next run alike."""
    url = _url(plc)
    key = lock_key(url)
    staging = Path(tempfile.mkdtemp(prefix="hil-planted-", dir="/tmp"))  # a place nobody can reach and write
    os.chmod(staging, 0o1777)
    theirs = staging / "journal.json"
    try:
        _as_nobody(f"open({str(theirs)!r}, 'w').write({json.dumps(json.dumps(_planted(key, plc)))})")
        path = journal_path(key)
        shutil.move(theirs, path)  # a rename where it can: the owner stays nobody
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    assert os.stat(path).st_uid != os.getuid()
    before, raw = _state(plc), path.read_bytes()
    code, lines = _restore(capsys, url, "--bench", str(_profile(tmp_path, plc)))
    assert code != 0 and len(lines) == 1 and "belongs to uid" in lines[0], lines
    run = _session(tmp_path, _profile(tmp_path, plc), "bench.plc.io.write('R1000', 1)")
    assert run.returncode != 0 and "belongs to uid" in run.stdout + run.stderr, run.stdout + run.stderr
    assert _state(plc) == before and path.read_bytes() == raw


@pytest.mark.e2e
def test_an_own_journal_is_still_replayed_only_within_the_profile(plc, tmp_path, capsys):
    """The same planted content in our own file: R2000 and Y0 are not writable, Y1 neither, RUN/STOP needs
    allow_destructive, the clock's elements are writable (so it is replayed, to its offset — not to 2001 + the
    years since, which the planted origin would be checked for by the clock's own rules), and the coil is on no
    rig of the profile: each refused by name, nothing of it written, the journal kept."""
    url = _url(plc)
    key = lock_key(url)
    data = _planted(key, plc)
    data["clock"] = None  # the clock's plausibility is the clock's own check (issue 25 item 6)
    path = journal_path(key)
    path.write_text(json.dumps(data))
    os.chmod(path, 0o600)
    before = _state(plc)
    code, lines = _restore(capsys, url, "--bench", str(_profile(tmp_path, plc, destructive=False)))
    text = " ".join(lines)
    assert code == 1, lines
    for why in ("R2000: not in the profile's [safety] writable", "Y0: not in the profile's [safety] writable",
                "RUN/STOP: RUN/STOP is destructive", "Y1 not in the profile's [safety] writable",
                "is not a fault rig of this profile"):
        assert why in text, (why, text)
    assert "restored and verified" not in text
    assert _state(plc) == before
    assert Journal(key).pending


# -- item 2: save before mutate --------------------------------------------------------------------------------
@pytest.mark.e2e
def test_disk_full_twice_in_a_row_leaves_nothing_unjournaled(plc, tmp_path, monkeypatch):
    """The journal's own writes fail (ENOSPC at the os level, only for files in the bench directory): test A's
    write to R1001 is refused, so is test B's, so is every later one — none reaches the PLC."""
    bench = open_bench(load_profile(_profile(tmp_path, plc)), target=_url(plc))
    state = str(Path(os.environ["HIL_LOCK_DIR"]).resolve())
    real_write = os.write

    def full(fd: int, data: bytes) -> int:
        if os.readlink(f"/proc/self/fd/{fd}").startswith(state):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write(fd, data)
    try:
        monkeypatch.setattr(os, "write", full)
        for test, value in (("A", 1111), ("B", 2222)):
            bench.begin_test(test)
            with pytest.raises(JournalError, match="No space left"):
                bench.plc.io.write("R1001", value)
            bench.end_test()
            with _plc(plc) as t:
                assert t.read("R1001") == 0, f"test {test}'s write went out unjournaled"
        monkeypatch.setattr(os, "write", real_write)  # the disk has room again: still no write this run
        bench.begin_test("C")
        with pytest.raises(JournalError, match="could not be written earlier"):
            bench.plc.io.write("R1001", 3333)
        bench.end_test()
    finally:
        bench.close()
    with _plc(plc) as t:
        assert t.read("R1001") == 0
    assert not Journal(lock_key(_url(plc))).pending


# -- item 3: what happened since --------------------------------------------------------------------------------
@pytest.mark.e2e
def test_a_run_killed_between_journaling_a_write_and_sending_it_is_still_put_back(plc, tmp_path):
    """The journal records what is about to be written before it goes out: a run killed in between leaves the PLC
    holding what its previous write left — the run's own value, restored, not an operator's change kept."""
    url = _url(plc)
    died = _session(tmp_path, _profile(tmp_path, plc, "first"),
                    "bench.plc.io.write('R1000', 1111)\n"
                    "import gc\nfrom hil.families.fbs.transport.guard import GuardedTransport\n"
                    "guard = next(o for o in gc.get_objects() if isinstance(o, GuardedTransport))\n"
                    f"guard.inner._write_words = lambda *a: {KILL}  # dies once 2222 is journaled, before it is sent\n"
                    "bench.plc.io.write('R1000', 2222)")
    assert died.returncode == -signal.SIGKILL, died.stdout
    entry = Journal(lock_key(url)).data["elements"]["R1000"]
    assert (entry["original"], entry["wrote"], entry["earlier"]) == (0, 2222, 1111)
    with _plc(plc) as t:
        assert t.read("R1000") == 1111
    try:
        nxt = _session(tmp_path, _profile(tmp_path, plc, "second"), "pass", "next")
        assert nxt.returncode == 0, nxt.stdout
        with _plc(plc) as t:
            assert t.read("R1000") == 0
        assert not Journal(lock_key(url)).pending
    finally:
        with _plc(plc) as t:
            t.write("R1000", 0)
        journal_path(lock_key(url)).unlink(missing_ok=True)


@pytest.mark.e2e
@pytest.mark.parametrize("command", [("restore",), ("rtc", "sync")], ids=["hil-restore", "direct-command"])
def test_a_dead_runs_fun86_rewrites_are_put_back_by_every_recovery(plc, tmp_path, capsys, command):
    """WR is no element the profile lets a test write, but FUN86 rewrites it because of one (EN).  Every recovery —
    `hil restore` (the bench's) and the one a direct command (`hil rtc sync`) runs first — knows the profile's FUN86
    boxes as the run's bench did: it puts a dead run's WR back after EN and reads it back, instead of refusing it."""
    url = _url(plc)
    key = lock_key(url)
    data = _journal(key, plc, elements={"M0": _stamp({"original": 0, "wrote": 0, "earlier": 1}),
                                        "R300": _stamp({"original": 0, "wrote": None})})
    path = journal_path(key)
    path.write_text(json.dumps(data))
    os.chmod(path, 0o600)
    with _plc(plc) as t:
        t.write("R300", 0x03FF)  # what FUN86 left in WR+0 while the run had EN on (every point normal)
    try:
        code, lines = _restore_like(capsys, *command, url, "--bench", str(_profile(tmp_path, plc)))
        text = " ".join(lines)
        assert code == 0, lines
        assert "R300 = 0" in text and "M0 = 0" in text, text
        with _plc(plc) as t:
            assert (t.read("R300"), t.read("M0")) == (0, 0)
        assert not Journal(key).pending
    finally:
        with _plc(plc) as t:
            t.write("R300", 0)
        path.unlink(missing_ok=True)


@pytest.mark.e2e
def test_an_operators_change_after_a_crash_is_kept_and_reported(plc, tmp_path):
    """A run writes R1000, R1001 and STOPs the PLC, then dies; an operator writes R1000 = 5555.  The next run
    (allow_destructive off) leaves R1000 at 5555 and the PLC in STOP, lists both, puts R1001 back, fails."""
    url = _url(plc)
    died = _session(tmp_path, _profile(tmp_path, plc, "first"),
                    f"bench.plc.io.write_words('R1000', [1111, 2222])\nbench.plc.io.set_running(False)\n{KILL}")
    assert died.returncode == -signal.SIGKILL, died.stdout
    with _plc(plc) as t:
        t.write("R1000", 5555)
    try:
        nxt = _session(tmp_path, _profile(tmp_path, plc, "second", destructive=False), "pass", "next")
        with _plc(plc) as t:
            assert t.read_words("R1000", 2) == [5555, 0] and t.status().running is False
        assert nxt.returncode != 0
        assert "R1000 reads 5555, the run wrote 1111 (original 0)" in nxt.stdout, nxt.stdout
        assert "RUN/STOP: RUN/STOP is destructive" in nxt.stdout and "R1001 = 0" in nxt.stdout
        left = Journal(lock_key(url))
        assert set(left.elements()) == {"R1000"} and left.extra("run") is not None
    finally:
        with _plc(plc) as t:
            t.write("R1000", 0)
            t.set_running(True)
        journal_path(lock_key(url)).unlink(missing_ok=True)


# -- item 4: one lock and one journal per PLC --------------------------------------------------------------------
@pytest.mark.e2e
def test_fatek_then_modbus_to_one_plc_share_one_lock_and_one_recovery(plc, tmp_path):
    died = _session(tmp_path, _profile(tmp_path, plc, "fatek", plc_id="line-3"),
                    f"bench.plc.io.write('R1002', 77)\n{KILL}")
    assert died.returncode == -signal.SIGKILL, died.stdout
    key = plc_key(_url(plc), "line-3")
    assert Journal(key).pending and not Journal(lock_key(_url(plc, "modbus-tcp"))).pending
    over_modbus = _profile(tmp_path, plc, "modbus", wire="modbus-tcp", plc_id="line-3")
    with BenchLock(_url(plc), key=key).acquire():  # a FATEK run holds the PLC: the Modbus run must not start
        busy = _session(tmp_path, over_modbus, "pass", "busy")
        assert busy.returncode != 0 and "is in use by" in busy.stdout + busy.stderr, busy.stdout + busy.stderr
    nxt = _session(tmp_path, over_modbus, "pass", "next")
    assert nxt.returncode == 0, nxt.stdout
    assert "restored and verified (read back): R1002 = 0" in nxt.stdout
    with _plc(plc) as t:
        assert t.read("R1002") == 0
    assert not Journal(key).pending


@pytest.mark.e2e
def test_a_journal_from_another_plc_at_the_same_endpoint_is_not_replayed(plc, tmp_path, capsys):
    """The journal's PLC identity (command 53; each emulator has a serial of its own) is not this PLC's."""
    url = _url(plc)
    key = lock_key(url)
    data = _journal(key, plc, elements={"R1003": _stamp({"original": 0, "wrote": 9})},
                    plc={"unit type": "01", "io code": "00", "os": "V4.0x", "serial": "0123456789abcdef"})
    journal_path(key).write_text(json.dumps(data))
    with _plc(plc) as t:
        t.write("R1003", 9)
    try:
        code, lines = _restore(capsys, url, "--bench", str(_profile(tmp_path, plc)))
        assert code == 1 and "the PLC reached now is" in " ".join(lines), lines
        with _plc(plc) as t:
            assert t.read("R1003") == 9
    finally:
        with _plc(plc) as t:
            t.write("R1003", 0)


# -- item 8: malformed journals ---------------------------------------------------------------------------------
def _malformed(key: str, where: dict) -> dict[str, tuple[bytes, str]]:
    good = _journal(key, where, elements={"R1000": _stamp({"original": 0, "wrote": 1})})
    text = json.dumps(good)
    return {
        "version 0": (json.dumps({**good, "version": 0}).encode(), "version 0"),
        "version 1": (json.dumps({**good, "version": 1}).encode(), "version 1"),
        "version 3": (json.dumps({**good, "version": 3}).encode(), "version 3"),
        "another bench": (json.dumps({**good, "bench": "tcp://10.0.0.9:500"}).encode(), "belongs to bench"),
        "null": (b"null", "not a journal"),
        "[]": (b"[]", "not a journal"),
        "NaN": (text.replace('"original": 0', '"original": NaN').encode(), "NaN is not a number"),
        "truncated": (text[: len(text) // 2].encode(), "damaged"),
    }


CASES = ["version 0", "version 1", "version 3", "another bench", "null", "[]", "NaN", "truncated"]


@pytest.mark.e2e
@pytest.mark.parametrize("case", CASES)
def test_a_malformed_journal_gives_one_clear_line_and_is_kept(plc, tmp_path, capsys, case):
    url = _url(plc)
    key = lock_key(url)
    raw, why = _malformed(key, plc)[case]
    path = journal_path(key)
    path.write_bytes(raw)
    bench = str(_profile(tmp_path, plc))
    code, lines = _restore(capsys, url, "--bench", bench)
    assert code != 0 and len(lines) == 1 and why in lines[0] and str(path) in lines[0], lines
    code, lines = _restore(capsys, "--show")
    assert code == 0 and len(lines) == 1 and lines[0].startswith("refused") and why in lines[0], lines
    assert path.read_bytes() == raw


@pytest.mark.e2e
def test_show_names_a_journal_whose_bench_differs_from_its_file_name(plc, tmp_path, capsys):
    url = _url(plc)
    wrong = _journal("tcp://10.0.0.9:500", plc, elements={"R1000": _stamp({"original": 0, "wrote": 1})})
    path = journal_path(lock_key(url))
    path.write_text(json.dumps(wrong))
    code, lines = _restore(capsys, "--show")
    assert len(lines) == 1 and "belongs to bench" in lines[0] and "nothing pending" not in lines[0], lines


@pytest.mark.e2e
def test_an_out_of_range_value_blocks_no_other_entry(plc, tmp_path, capsys):
    url = _url(plc)
    key = lock_key(url)
    data = _journal(key, plc, elements={"R1000": _stamp({"original": 70000, "wrote": 1}),
                                        "R1001": _stamp({"original": 0, "wrote": 9})})
    journal_path(key).write_text(json.dumps(data))
    with _plc(plc) as t:
        t.write("R1001", 9)
    code, lines = _restore(capsys, "--show", "--bench", str(_profile(tmp_path, plc)))
    assert any("would restore: R1001 to 0 (reads 9, as the run left it)" in line for line in lines), lines
    code, lines = _restore(capsys, url, "--bench", str(_profile(tmp_path, plc)))
    text = " ".join(lines)
    assert code == 1 and "R1001 = 0" in text and "R1000: malformed: value 70000" in text, lines
    with _plc(plc) as t:
        assert t.read("R1001") == 0
    assert set(Journal(key).data["elements"]) == {"R1000"}  # kept, for a look by hand
    journal_path(key).unlink()


# -- item 9: volatile ----------------------------------------------------------------------------------------------
@pytest.mark.e2e
def test_volatile_overlapping_writable_is_refused(tmp_path, plc):
    with pytest.raises(ProfileError, match=r"volatile and writable overlap at R1000, R1001"):
        load_profile(_profile(tmp_path, plc, volatile='["R4128-R4135", "R1000-R1001"]'))
    load_profile(EMULATOR_BENCH)  # the clock's R4128–R4134 may be both: the clock restore puts them back


@pytest.mark.e2e
def test_a_journaled_element_now_volatile_is_dropped_not_retried_forever(plc, tmp_path, capsys):
    """A scan counter journaled while the profile forgot it was volatile: once the profile says so, recovery
    drops it (and says so) instead of failing its read-back on every run."""
    url = _url(plc)
    key = lock_key(url)
    journal_path(key).write_text(json.dumps(_journal(key, plc, elements={
        "R3999": _stamp({"original": 5, "wrote": 6})})))
    code, lines = _restore(capsys, url, "--bench", str(_profile(tmp_path, plc, volatile='["R4128-R4135", "R3999"]')))
    assert code == 0 and "R3999: volatile in the profile" in " ".join(lines), lines
    assert not Journal(key).pending


# -- item 10: the rig is a separate device ---------------------------------------------------------------------
@pytest.mark.e2e
def test_a_rig_on_the_plcs_own_modbus_port_is_refused(plc, tmp_path, capsys):
    own = f"modbus+tcp://{plc['modbus-tcp']}?unit=1"
    profile = load_profile(_profile(tmp_path, plc, rig=own))
    bench = open_bench(profile, target=_url(plc))
    try:
        with pytest.raises(HilError, match="it is the PLC's own Modbus port"):
            bench.faults.get("sensor_break")
    finally:
        bench.close()
    url = _url(plc)
    key = lock_key(url)
    journal_path(key).write_text(json.dumps(_journal(key, plc, coils={"c": _stamp(
        {"target": own, "coil": 0, "unit": 1, "original": True, "wrote": False})})))
    code, lines = _restore(capsys, url, "--bench", str(_profile(tmp_path, plc, "own", rig=own)))
    assert code == 1 and "it is the PLC's own Modbus port" in " ".join(lines), lines
    with _plc(plc) as t:
        assert t.read("Y0") == 0


# -- item 11: verified means read back ----------------------------------------------------------------------------
def _actions_journal(key: str, where: dict) -> dict:
    return _journal(key, where, elements={"R1002": _stamp({"original": 0, "wrote": 5})},
                    run=_stamp({"original": True, "wrote": False}), disabled=["M1001"])


def _leave_changed(where: dict) -> None:
    with _plc(where) as t:
        t.write("R1002", 5)
        t.set_running(False)
        t.bit_action("M1001", 1)


@pytest.mark.e2e
def test_the_verified_list_is_exactly_what_was_read_back(plc, tmp_path, capsys):
    url = _url(plc)
    key = lock_key(url)
    journal_path(key).write_text(json.dumps(_actions_journal(key, plc)))
    _leave_changed(plc)
    code, lines = _restore(capsys, url, "--bench", str(_profile(tmp_path, plc)))
    assert code == 0, lines
    verified = lines[0].split("restored and verified (read back): ")[1].split(" — ")[0].split("; ")
    assert sorted(verified) == ["M1001 enabled (read back, command 43)", "R1002 = 0", "RUN/STOP = RUN"]
    with _plc(plc) as t:
        assert t.read("R1002") == 0 and t.status().running and t.read_disabled("M1001", 1) == [0]


@pytest.mark.e2e
def test_a_run_killed_before_its_return_to_run_went_out_is_put_back_in_run(plc, tmp_path, capsys):
    # the run sent STOP, then journaled RUN ("wrote": true, the STOP kept as "earlier") and died before command 41
    # went out: the PLC is in STOP, what the run's write before left — put back in RUN, not called changed
    url = _url(plc)
    key = lock_key(url)
    journal_path(key).write_text(json.dumps(_journal(key, plc, run=_stamp({"original": True, "wrote": True,
                                                                          "earlier": False}))))
    with _plc(plc) as t:
        t.set_running(False)
    code, lines = _restore(capsys, url, "--bench", str(_profile(tmp_path, plc)))
    assert code == 0 and "RUN/STOP = RUN" in " ".join(lines), lines
    with _plc(plc) as t:
        assert t.status().running


def never_enables(emulator, profile, epoch) -> None:
    """A PLC that acknowledges command 42 "enable" and keeps the bit disabled."""
    class Sticky(bytearray):
        def __setitem__(self, index, value):
            if value:
                super().__setitem__(index, value)
    emulator.memory.disabled["M"] = Sticky(emulator.memory.disabled["M"])


@pytest.mark.e2e
def test_an_enable_that_does_not_read_back_is_not_called_verified(tmp_path, capsys):
    spec = "tests.test_recovery_trust:BrokenEmulator:never_enables"
    with hil_emulate(EMULATOR_BENCH, 1.0, broken=spec) as where:
        url = _url(where)
        key = lock_key(url)
        journal_path(key).write_text(json.dumps(_actions_journal(key, where)))
        _leave_changed(where)
        code, lines = _restore(capsys, url, "--bench", str(_profile(tmp_path, where)))
        text = " ".join(lines)
        assert code == 1 and "M1001 still read as disabled (command 43)" in text, lines
        verified = text.split("restored and verified (read back): ")[1].split(" — ")[0].split("; ")
        assert sorted(verified) == ["R1002 = 0", "RUN/STOP = RUN"]
        assert Journal(key).extra("disabled") == ["M1001"]  # kept: not restored


# -- item 12: the bundled profile is the emulator's --------------------------------------------------------------
@pytest.mark.e2e
def test_a_plc_named_by_target_alone_does_not_get_the_emulators_profile(plc, tmp_path, capsys):
    (tmp_path / "test_it.py").write_text("def test_it(bench):\n    bench.plc.io.write('R1000', 1)\n")
    run = subprocess.run([sys.executable, "-m", "pytest", str(tmp_path), "--target", _url(plc), "-q",
                          "-p", "no:cacheprovider", "-p", "no:hypothesispytest"], cwd=tmp_path, capture_output=True,
                         text=True, timeout=120, env=os.environ.copy())
    assert run.returncode != 0 and "names a PLC, and no --bench profile was given" in run.stdout + run.stderr, \
        run.stdout + run.stderr
    code, lines = _restore_like(capsys, "run", "--target", _url(plc))  # hil run gives pytest the default by name
    assert code == 4 and len(lines) == 1 and "names a PLC, and no --bench profile was given" in lines[0], lines
    with _plc(plc) as t:
        assert t.read("R1000") == 0


@pytest.mark.skipif(os.getuid() != 0 or not os.path.exists("/usr/bin/python3"),
                    reason="a second user's run can only be made as root (os.setuid to nobody)")
@pytest.mark.timeout(300)  # a hang guard: two cold starts of the system's Python as nobody (no bytecode cache)
def test_two_users_runs_on_one_plc_are_kept_apart(monkeypatch):
    """Issue 25 item 4: the lock directory is shared by every user of the host, so another user's run on the same
    PLC holds the same lock (both ways round)."""
    base = Path(tempfile.mkdtemp(prefix="hil-locks-", dir="/tmp"))
    os.chmod(base, 0o755)
    monkeypatch.setenv("HIL_LOCK_DIR", str(base / "locks"))
    import pwd
    monkeypatch.setenv("HIL_BENCH_GROUP", str(pwd.getpwnam("nobody").pw_gid))  # the bench group: nobody's (issue 40)
    url = "fatek+tcp://192.0.2.7:500"
    hold = ("import sys; from hil.core.lock import BenchLock, BenchBusy\n"
            f"try:\n    lock = BenchLock({url!r}).acquire()\nexcept BenchBusy as exc:\n    print(exc); sys.exit(3)\n"
            "print('held', flush=True); sys.stdin.read()\n")
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    import pwd
    nobody = pwd.getpwnam("nobody")

    def drop() -> None:
        os.setgid(nobody.pw_gid)
        os.setgroups([nobody.pw_gid])
        os.setuid(nobody.pw_uid)
    try:
        with BenchLock(url).acquire():  # ours first: theirs is refused, naming us
            theirs = subprocess.run(["/usr/bin/python3", "-c", hold], preexec_fn=drop, env=env, cwd="/",
                                    capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL)  # hang guard
            assert theirs.returncode == 3 and "is in use by" in theirs.stdout, theirs.stdout + theirs.stderr
        other = processes.spawn(["/usr/bin/python3", "-c", hold], preexec_fn=drop, env=env, cwd="/",
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        try:
            assert other.stdout.readline().strip() == "held"
            with pytest.raises(HilError, match="in use by .*user nobody"):
                BenchLock(url).acquire()
        finally:
            other.stdin.close()
            other.wait(timeout=120)  # a hang guard: it exits when its stdin closes
    finally:
        shutil.rmtree(base, ignore_errors=True)


@pytest.mark.e2e
def test_an_operators_forced_bit_stays_forced_after_recovery(plc, tmp_path, capsys):
    """Enable states journaled with command 43 (the kind issue 25 item 7 journals) come back exactly, read back:
    a bit the operator had disabled is disabled again, one that was enabled is enabled."""
    url = _url(plc)
    key = lock_key(url)
    journal_path(key).write_text(json.dumps(_journal(key, plc, enable={
        "M1001": _stamp({"disabled": True, "wrote": False}), "M1002": _stamp({"disabled": False, "wrote": True})})))
    with _plc(plc) as t:
        t.bit_action("M1002", 1)  # the dead run disabled M1002 and enabled M1001
    try:
        code, lines = _restore(capsys, url, "--bench", str(_profile(tmp_path, plc)))
        assert code == 0, lines
        assert "M1001 disabled (read back, command 43)" in lines[0] and "M1002 enabled (read back" in lines[0]
        with _plc(plc) as t:
            assert t.read_disabled("M1001", 2) == [1, 0]
    finally:
        with _plc(plc) as t:
            t.bit_action("M1001", 2)
            t.bit_action("M1002", 2)
