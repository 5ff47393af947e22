"""One bench directory for every user of a bench (issue 40, items 7 and 11): the bench's locks and its journals in
one place, the bench group's (mode 2770, files 0660), so the next run finds what another user's dead run left;
a directory anyone could write or someone else's is refused; and a serial line another process keeps is named
(pid, command) after a bounded wait instead of hanging the command with no output.

The runs are real processes: ``hil emulate`` over FATEK/TCP, a pytest run SIGKILLed with its write out, the next
run in another user's environment (its own state directory and home), a process holding a pty's line lock.
"""

from __future__ import annotations

import os
import pty
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import pytest

from hil.core.errors import HilError
from hil.core.journal import Journal, JournalRefused, journal_path
from hil.core.lock import BenchLock, lock_key
from hil.families.fbs.transport.factory import open_transport
from hil.io.url import parse_target
from tests import processes
from tests.conftest import EMULATOR_BENCH, REPO
from tests.external import bench_over_the_wire, hil_emulate

DIES = """
import sys

def test_writes_then_dies(bench):
    bench.plc.io.write_words("R100", [{value}])
    print("written", flush=True)
    sys.stdin.readline()  # killed here, its write out and journaled
"""
NEXT = "def test_next(bench):\n    pass\n"


@pytest.fixture(scope="module")
def plc():
    with hil_emulate(EMULATOR_BENCH, 1.0) as where:
        yield where


def _profile(tmp_path: Path, where: dict) -> Path:
    path = tmp_path / "bench.toml"
    path.write_text(bench_over_the_wire(EMULATOR_BENCH.read_text(), where, 1.0))
    return path


def _r100(where: dict) -> int:
    with open_transport(parse_target(f"fatek+tcp://{where['fatek-tcp']}"), timeout=10.0) as t:
        return t.read_words("R100", 1)[0]


def _user_env(home: Path) -> dict[str, str]:
    """Another user's environment: their own home and state directory; the bench directory is the host's."""
    home.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("HIL_STATE_DIR", "XDG_STATE_HOME")}
    return {**env, "HOME": str(home), "HIL_STATE_DIR": str(home / "state"), "PYTHONUNBUFFERED": "1"}


def _pytest(tests: Path, profile: Path, env: dict[str, str], **kwargs) -> subprocess.Popen:
    return processes.spawn([sys.executable, "-m", "pytest", str(tests), "--bench", str(profile), "-q", "-s",
                            "-p", "no:cacheprovider", "-p", "no:hypothesispytest"], cwd=REPO, env=env, text=True,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, **kwargs)


# -- item 7: a dead run's journal is found by the next run, whoever started either --------------------------------
@pytest.mark.e2e
def test_a_journal_another_users_killed_run_left_is_recovered_by_the_next_run(plc, tmp_path):
    """Run A (user A: its own home and state directory) writes R100 and is SIGKILLed; run B (user B: another home,
    another state directory) on the same bench finds A's journal beside the lock, puts R100 back, and says so."""
    profile = _profile(tmp_path, plc)
    original = _r100(plc)
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "test_dies.py").write_text(DIES.format(value=(original + 77) & 0xFFFF))
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "test_next.py").write_text(NEXT)
    run_a = _pytest(tmp_path / "a", profile, _user_env(tmp_path / "home-a"), stdin=subprocess.PIPE)
    for line in run_a.stdout:  # a hang guard: pytest-timeout (pyproject's, the child's too) ends a stuck run
        if "written" in line:
            break
    processes.end(run_a, signal.SIGKILL, grace=0)
    assert _r100(plc) == (original + 77) & 0xFFFF, "run A's write is on the PLC"
    key = lock_key(f"fatek+tcp://{plc['fatek-tcp']}")
    assert Journal(key).pending and not list((tmp_path / "home-a" / "state").glob("journal-*")), \
        "run A's journal is beside the bench's lock, not in A's own state directory"
    mode = stat.S_IMODE(os.stat(journal_path(key)).st_mode)
    assert mode == 0o660 and stat.S_IMODE(os.stat(journal_path(key).parent).st_mode) == 0o2770

    run_b = _pytest(tmp_path / "b", profile, _user_env(tmp_path / "home-b"))
    out, _ = run_b.communicate(timeout=120)  # a hang guard
    assert run_b.returncode == 0, out[-3000:]
    assert "hil bench recovery: a previous run" in out and "restored and verified" in out, out[-3000:]
    assert f"pid {run_a.pid}; its journal {journal_path(key)}" in out, f"whose and where are said: {out[-3000:]}"
    assert _r100(plc) == original and not Journal(key).pending


AS_ROOT = pytest.mark.skipif(os.getuid() != 0 or not os.path.exists("/usr/bin/python3"),
                             reason="another user can only be played as root (os.setuid to nobody)")


def _as_nobody(code: str) -> subprocess.CompletedProcess:
    """``code`` run by the system's Python as the user nobody (the project's venv is root's: stdlib-only code),
    with this test's bench directory and group, and a home and state directory of its own (none)."""
    import pwd
    nobody = pwd.getpwnam("nobody")

    def drop() -> None:
        os.setgid(nobody.pw_gid)
        os.setgroups([nobody.pw_gid])
        os.setuid(nobody.pw_uid)
    env = {**os.environ, "PYTHONPATH": str(REPO), "HOME": "/nonexistent", "HIL_STATE_DIR": "/nonexistent"}
    return processes.run(["/usr/bin/python3", "-c", code], preexec_fn=drop, cwd="/", timeout=120, env=env)


def _nobody() -> tuple[int, int, str]:
    """The user nobody's uid, its group's gid and that group's name (the bench group of these tests)."""
    import grp
    import pwd
    nobody = pwd.getpwnam("nobody")
    return nobody.pw_uid, nobody.pw_gid, grp.getgrgid(nobody.pw_gid).gr_name


@pytest.fixture
def group_bench_dir(monkeypatch):
    """A bench directory shared with the user nobody through nobody's group (the bench group)."""
    base = Path(tempfile.mkdtemp(prefix="hil-bench-", dir="/tmp"))
    os.chmod(base, 0o755)
    monkeypatch.setenv("HIL_LOCK_DIR", str(base / "bench"))
    monkeypatch.setenv("HIL_BENCH_GROUP", _nobody()[2])
    yield base / "bench"
    shutil.rmtree(base, ignore_errors=True)


@AS_ROOT
@pytest.mark.e2e
def test_a_journal_of_another_user_in_the_bench_group_is_recovered(plc, tmp_path, group_bench_dir):
    """The user nobody, a member of the bench group, journals a write to R100 (and the write goes out) and dies;
    root's next run on the bench recovers it: the journal is nobody's file, the bench group's, and trusted."""
    profile = _profile(tmp_path, plc)
    original = _r100(plc)
    key = lock_key(f"fatek+tcp://{plc['fatek-tcp']}")
    Journal(key)  # the bench directory, created as hil creates it: the bench group's, 2770
    info = os.stat(group_bench_dir)
    uid, gid, _ = _nobody()
    assert stat.S_IMODE(info.st_mode) == 0o2770 and info.st_gid == gid
    wrote = (original + 5) & 0xFFFF
    theirs = _as_nobody(f"from hil.core.journal import Journal\nj = Journal({key!r})\nj.test = 'nobody_s_test'\n"
                        f"j.add_elements({{'R100': {original}}}, {{'R100': {wrote}}})\n")
    assert theirs.returncode == 0, theirs.stderr
    assert os.stat(journal_path(key)).st_uid == uid
    with open_transport(parse_target(f"fatek+tcp://{plc['fatek-tcp']}"), timeout=10.0) as t:
        t.write_words("R100", [wrote])  # nobody's write, out before its run died
    (tmp_path / "next").mkdir()
    (tmp_path / "next" / "test_next.py").write_text(NEXT)
    run = _pytest(tmp_path / "next", profile, {**os.environ, "PYTHONUNBUFFERED": "1"})
    out, _ = run.communicate(timeout=120)  # a hang guard
    assert run.returncode == 0 and "restored and verified" in out and "user nobody" in out, out[-3000:]
    assert _r100(plc) == original and not Journal(key).pending


# -- item 11: a bench directory that is not safe to share is refused --------------------------------------------
def test_a_world_writable_bench_directory_is_refused_naming_it(tmp_path, monkeypatch):
    """Even with the sticky bit (as /tmp): anyone could plant a journal there for the next run to replay."""
    loose = tmp_path / "loose"
    loose.mkdir()
    os.chmod(loose, 0o1777)
    monkeypatch.setenv("HIL_LOCK_DIR", str(loose))
    with pytest.raises(HilError) as info:
        BenchLock("fatek+tcp://127.0.0.1:500").acquire()
    text = str(info.value)
    assert str(loose) in text and "mode 1777" in text and "writable by everyone" in text and "chmod 2770" in text
    with pytest.raises(JournalRefused, match="writable by everyone"):
        Journal(lock_key("fatek+tcp://127.0.0.1:500"))
    assert not list(loose.iterdir()), "nothing created in it"


def test_a_sticky_shared_bench_directory_is_refused(tmp_path, monkeypatch):
    """With the sticky bit one user of the bench could not replace or remove another's journal: recovery would
    fail half-way, so the directory is refused before anything is written."""
    sticky = tmp_path / "sticky"
    sticky.mkdir()
    os.chmod(sticky, 0o3770)
    monkeypatch.setenv("HIL_LOCK_DIR", str(sticky))
    with pytest.raises(HilError, match=f"{sticky} .*has the sticky bit .*chmod 2770"):
        BenchLock("fatek+tcp://127.0.0.1:500").acquire()


def test_a_journal_an_earlier_hil_left_in_the_state_directory_is_not_forgotten(tmp_path):
    """Upgrading with a journal pending in ~/.local/state/hil (where journals were): the next run does not start
    as if nothing were pending — it refuses, saying where the journal is and where to move it."""
    key = lock_key("fatek+tcp://127.0.0.1:500")
    new = journal_path(key)
    old = Path(os.environ["HIL_STATE_DIR"]) / new.name
    old.parent.mkdir(parents=True, exist_ok=True)
    old.write_text("{}")
    journal = Journal(key)  # refused as a whole: pending, named by recovery, and nothing written over it
    assert journal.pending and str(old) in journal.refused and f"mv {old} {new}" in journal.refused
    with pytest.raises(JournalRefused, match="refusing every write"):
        journal.add_elements({"R1": 0}, {"R1": 1})


def test_hil_restore_refuses_a_world_writable_bench_directory(tmp_path):
    loose = tmp_path / "loose"
    loose.mkdir()
    os.chmod(loose, 0o777)
    proc = processes.run([sys.executable, "-m", "hil.cli.main", "restore", "--show"], cwd=REPO, timeout=60,
                         env={**os.environ, "HIL_LOCK_DIR": str(loose)})
    assert proc.returncode != 0 and "writable by everyone" in proc.stderr + proc.stdout, proc.stderr


@AS_ROOT
def test_a_bench_directory_that_is_not_the_users_or_groups_is_refused(group_bench_dir):
    """Seen by the user nobody: a directory of another user's (uid 1234) and group, and one of root's whose group is
    not the bench group (nobody's): each refused, naming the directory, its owner and group, and what to do."""
    code = ("from hil.core.lock import BenchLock\nfrom hil.core.errors import HilError\n"
            "try:\n    BenchLock('fatek+tcp://127.0.0.1:500').acquire()\nexcept HilError as exc:\n"
            "    print(exc); raise SystemExit(4)\n")
    group_bench_dir.mkdir(mode=0o770)
    os.chown(group_bench_dir, 1234, 1234)
    theirs = _as_nobody(code)
    assert theirs.returncode == 4 and str(group_bench_dir) in theirs.stdout, theirs.stdout + theirs.stderr
    assert "owner uid 1234" in theirs.stdout and "not shared with a group of yours" in theirs.stdout, theirs.stdout
    assert "chgrp BENCH-GROUP" in theirs.stdout and "HIL_LOCK_DIR" in theirs.stdout, theirs.stdout
    os.chown(group_bench_dir, 0, 0)
    os.chmod(group_bench_dir, 0o2770)
    theirs = _as_nobody(code)
    _, gid, name = _nobody()
    assert theirs.returncode == 4 and f"is not the bench group {name} ({gid})'s" in theirs.stdout, theirs.stdout


def test_a_new_bench_directory_is_the_bench_groups(tmp_path, monkeypatch):
    monkeypatch.setenv("HIL_LOCK_DIR", str(tmp_path / "bench"))
    monkeypatch.setenv("HIL_BENCH_GROUP", str(os.getegid()))
    with BenchLock("fatek+tcp://127.0.0.1:500").acquire() as lock:
        info = os.stat(lock.directory)
        assert stat.S_IMODE(info.st_mode) == 0o2770 and info.st_gid == os.getegid()
        assert stat.S_IMODE(os.stat(lock.path).st_mode) == 0o660
    monkeypatch.setenv("HIL_BENCH_GROUP", "no-such-group-hil")
    with pytest.raises(HilError, match="HIL_BENCH_GROUP=no-such-group-hil: no such group"):
        BenchLock("fatek+tcp://127.0.0.1:500").acquire()


@AS_ROOT
def test_a_lock_in_a_shared_directory_without_setgid_still_gets_the_bench_group(group_bench_dir):
    """An administrator's ``chmod 770`` (no setgid): hil's files still get the directory's group, so the next
    user of the bench can take the lock and recover the journal."""
    group_bench_dir.mkdir(mode=0o770)
    gid = _nobody()[1]
    os.chown(group_bench_dir, 0, gid)
    with BenchLock("fatek+tcp://127.0.0.1:500").acquire() as lock:
        info = os.stat(lock.path)
        assert info.st_gid == gid and stat.S_IMODE(info.st_mode) == 0o660
    journal = Journal(lock_key("fatek+tcp://127.0.0.1:500"))
    journal.add_elements({"R100": 1}, {"R100": 2})
    assert os.stat(journal.path).st_gid == gid


# -- item 11: the serial line's lock is waited for with a bound, and its holder named -----------------------------
HOLDS_THE_LINE = """
import sys
from hil.io.shared_line import SharedLine
line = SharedLine({device!r}, taken=lambda suspect: None, leaving=lambda: False)
with line:
    print("holding", flush=True)
    sys.stdin.readline()
"""


def test_a_line_another_process_keeps_is_named_after_the_wait(tmp_path, monkeypatch):
    """A process holds a pty's line lock and does not let go: ``hil probe`` on that pty gives up after
    $HIL_LINE_WAIT seconds naming the holder's pid and command (exit 4), instead of hanging with no output."""
    leader, follower = pty.openpty()
    device = os.ttyname(follower)
    holder = processes.spawn([sys.executable, "-c", textwrap.dedent(HOLDS_THE_LINE.format(device=device)),
                              "--the-holders-own-argument"], cwd=REPO, text=True, stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE)
    try:
        assert holder.stdout.readline().strip() == "holding"
        proc = processes.run([sys.executable, "-m", "hil.cli.main", "probe", f"fatek+serial://{device}"], cwd=REPO,
                             timeout=120, env={**os.environ, "HIL_LINE_WAIT": "0.5"})  # a hang guard
        text = proc.stdout + proc.stderr
        assert proc.returncode != 0, text
        assert f"is held by pid {holder.pid}" in text and "--the-holders-own-argument" in text, text
        assert "HIL_LINE_WAIT" in text and "waited 0.5 s" in text, text
    finally:
        holder.stdin.close()
        processes.end(holder, signal.SIGKILL, grace=0)
        os.close(leader)
        os.close(follower)


@AS_ROOT
def test_a_line_lock_file_another_user_closed_is_named_with_what_to_do(group_bench_dir):
    """A line's lock file left mode 0600 by another user (root, here): the user nobody of the bench group cannot
    open it; the error names the file, its mode and owner and what to do, rather than "permission denied"."""
    leader, follower = pty.openpty()
    try:
        device = os.ttyname(follower)
        from hil.io.shared_line import SharedLine
        SharedLine(device, taken=lambda suspect: None, leaving=lambda: False).close()
        path = next(group_bench_dir.glob("line-*.lock"))
        os.chmod(path, 0o600)
        theirs = _as_nobody("from hil.io.shared_line import SharedLine\nfrom hil.core.errors import HilError\n"
                            f"try:\n    SharedLine({device!r}, taken=lambda s: None, leaving=lambda: False)\n"
                            "except HilError as exc:\n    print(exc); raise SystemExit(4)\n")
        text = theirs.stdout + theirs.stderr
        assert theirs.returncode == 4 and str(path) in text and "mode 0600" in text, text
        assert "owner root (uid 0)" in text and "chmod 0660" in text, text
    finally:
        os.close(leader)
        os.close(follower)


def test_a_bench_lock_held_without_a_record_is_named_by_the_kernel(tmp_path):
    """A process that holds the bench's lock file but wrote no holder record (another tool, an older hil): the
    refusal still names its pid and command, from the kernel's lock table."""
    path = BenchLock("fatek+tcp://127.0.0.1:500").path
    BenchLock("fatek+tcp://127.0.0.1:500").acquire().release()  # the file, as hil creates it (empty: released)
    code = (f"import fcntl, os, sys\nfd = os.open({str(path)!r}, os.O_RDONLY)\nfcntl.flock(fd, fcntl.LOCK_EX)\n"
            "print('holding', flush=True)\nsys.stdin.readline()\n")
    holder = processes.spawn([sys.executable, "-c", code, "--a-tool-of-its-own"], text=True, stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE)
    try:
        assert holder.stdout.readline().strip() == "holding"
        with pytest.raises(HilError) as info:
            BenchLock("fatek+tcp://127.0.0.1:500").acquire()
        text = str(info.value)
        assert f"in use by pid {holder.pid} of user " in text and "--a-tool-of-its-own" in text, text
    finally:
        holder.stdin.close()
        processes.end(holder, signal.SIGKILL, grace=0)
