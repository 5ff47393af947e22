"""A history store's password is never shown (issue 40, item 12): given in the URL's user part, in its query
(``?password=``) or typed with a raw '@', it appears in none of the places a run or ``hil history`` shows or writes
the URL — the world-readable lock file, a second run's "in use by" message, the console, the HTML report, ``hil
history list`` — and a store that cannot be reached is one line naming it (password hidden), exit 4, no traceback.

Against ``hil emulate`` as a separate process (a real target takes the bench lock) and a real PostgreSQL server
(tests/pg_server.py: trust authentication, so any password is let in)."""

from __future__ import annotations

import json
import signal
import socket
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from hil.core.lock import BenchLock
from hil.core.redact import hide_password, hide_passwords
from hil.history.config import normalise
from tests import processes
from tests.conftest import EMULATOR_BENCH, REPO
from tests.external import bench_over_the_wire, hil_emulate
from tests.history_runs import env, wait_for, write_tests
from tests.pg_server import NO_POSTGRES, Cluster

#: the password's two halves: neither may appear anywhere (a raw '@' once made "@ss@db" show the second)
FIRST, SECOND = "Zq7xk", "Wv9yq"


@pytest.mark.parametrize("url, shown", [
    ("postgresql+psycopg://hil:Zq7xk@db:5432/h", "postgresql+psycopg://hil:***@db:5432/h"),
    ("postgresql://hil@db/h?sslmode=require&password=Zq7xk", "postgresql://hil@db/h?sslmode=require&password=***"),
    ("postgresql://hil:Zq7xk@Wv9yq@db/h", "postgresql://hil:***@db/h"),
    ("postgresql://hil:Zq7xk/Wv9yq@db/h", "postgresql://hil:***@db/h"),
    ("sqlite:////home/a@b/history.sqlite", "sqlite:////home/a@b/history.sqlite"),
    ("fatek+tcp://10.0.0.5:500?station=3", "fatek+tcp://10.0.0.5:500?station=3"),
])
def test_every_form_of_password_is_hidden_and_nothing_else(url, shown):
    assert hide_password(url) == shown
    line = f"hil run --bench b.toml -- --hil-history={url} -k quick"
    assert hide_passwords(line) == f"hil run --bench b.toml -- --hil-history={shown} -k quick"


def test_a_raw_at_in_the_password_reaches_the_host_meant():
    """The user part runs to the last '@' before the path: quoted, the driver gets host ``db`` and the whole
    password (unquoted, it tried host "Wv9yq@db" and its error quoted that)."""
    assert normalise("postgresql://hil:Zq7xk@Wv9yq@db/h") == "postgresql+psycopg://hil:Zq7xk%40Wv9yq@db/h"
    assert normalise("postgresql://hil:pw@db/my@db") == "postgresql+psycopg://hil:pw@db/my@db"


@pytest.fixture(scope="module")
def postgres():
    if NO_POSTGRES is not None:
        pytest.skip(NO_POSTGRES)
    cluster = Cluster()
    yield cluster
    cluster.stop()


FORMS = {  # how the password is given → the URL (its database's host, port and name filled in)
    "user part": "postgresql://hil:Zq7xkWv9yq@{where}",
    "query": "postgresql://hil@{where}?password=Zq7xkWv9yq",
    "raw @": "postgresql://hil:Zq7xk@Wv9yq@{where}",
}


def _hil(*args: str, cwd, **extra: str) -> subprocess.CompletedProcess:
    return processes.run([sys.executable, "-m", "hil.cli.main", *args], cwd=cwd, timeout=300,
                         env=env("off", **extra))


def _no_secret(where: str, text: str) -> None:
    for half in (FIRST, SECOND):
        assert half not in text, f"the password ({half}) is shown in {where}: {text[-3000:]}"


# (the ?password= form, whose database also refuses connections, in the gate; the others, which the masking's
# unit cases hold too, in the matrix: the gate's time)
@pytest.mark.parametrize("form", [f if f == "query" else pytest.param(f, marks=pytest.mark.matrix)
                                  for f in sorted(FORMS)])
def test_the_password_is_in_no_lock_file_message_console_report_or_listing(tmp_path, monkeypatch, postgres, form):
    """A ``hil run --hil-history URL`` on a real target: while it holds the bench, its lock file and a second
    run's refusal; at its end its console and HTML report; then ``hil history list``.  The "query" store refuses
    connections: the run's warning and ``hil history list``'s one line name it, password hidden."""
    monkeypatch.setenv("HIL_LOCK_DIR", str(tmp_path / "locks"))
    database = postgres.new_database()
    url = FORMS[form].format(where=database.split("@", 1)[1])
    reachable = form != "query"
    if not reachable:
        postgres.refuse(database.rsplit("/", 1)[1])
    tests = write_tests(tmp_path / "t")
    go = tmp_path / "go"
    with hil_emulate(EMULATOR_BENCH, 1.0) as where:
        bench = tmp_path / "bench.toml"
        bench.write_text(bench_over_the_wire(EMULATOR_BENCH.read_text(), where, 1.0))
        run = processes.spawn([sys.executable, "-m", "hil.cli.main", "run", "--bench", str(bench), "--junitxml",
                               str(tmp_path / "r" / "junit.xml"), "--html", str(tmp_path / "r" / "report.html"),
                               "--", str(tests), "-k", "not quick", "--hil-history", url],
                              cwd=tmp_path, env=env("off", HIST_GO=str(go)), stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True)
        try:
            lock = BenchLock(f"fatek+tcp://{where['fatek-tcp']}")
            record = wait_for(lambda: lock.path.exists() and lock.path.read_text(), "the run's lock record")
            assert "--hil-history" in json.loads(record)["command"], record
            _no_secret("the lock file", record)
            second = _hil("run", "--bench", str(bench), "--", str(tests), "-k", "quick", "--hil-history", url,
                          cwd=tmp_path)
            assert second.returncode == 4 and "in use by" in second.stdout + second.stderr, second
            _no_secret("the second run's refusal", second.stdout + second.stderr)
        finally:
            go.touch()
        out, _ = run.communicate(timeout=300)
        processes.end(run, signal.SIGKILL, grace=0)
    assert run.returncode == 0, out[-3000:]
    _no_secret("the console", out)
    assert ("unreachable" in out) is not reachable, out[-2000:]
    report = (tmp_path / "r" / "report.html").read_text(encoding="utf-8")
    assert "history: postgresql" in report or "history: sqlite" in report
    _no_secret("the HTML report", report)
    listed = _hil("history", "list", "--url", url, cwd=tmp_path)
    _no_secret("hil history list", listed.stdout + listed.stderr)
    if reachable:
        assert listed.returncode == 0 and "runs in postgresql+psycopg://hil:***@" in listed.stdout, listed
        assert "PASSED" in listed.stdout, listed.stdout
    else:
        said = listed.stderr.strip().splitlines()
        assert listed.returncode == 4 and len(said) == 1 and "Traceback" not in listed.stderr, listed
        assert said[0].startswith("hil: error: history store postgresql+psycopg://hil@") and "unreachable" in said[0]
        assert "password=***" in said[0] and "check that its server runs" in said[0], said


@pytest.mark.parametrize("action", ["list", "sync"])
def test_an_unreachable_store_is_one_line_exit_4(tmp_path, action):
    """Nothing listens on the store's port: one line naming the store (password hidden) and what to check."""
    with socket.socket() as s:  # a port nothing listens on (bound, never listening)
        s.bind(("127.0.0.1", 0))
        url = f"postgresql://hil:Zq7xk@Wv9yq@127.0.0.1:{s.getsockname()[1]}/h"
        spool = tmp_path / "state" / "history-unsent.sqlite"  # sync has a spool to upload
        spool.parent.mkdir()
        sqlite3.connect(spool).close()
        done = _hil("history", action, "--url", url, cwd=REPO, HIL_STATE_DIR=str(tmp_path / "state"))
    said = done.stderr.strip().splitlines()
    assert done.returncode == 4 and len(said) == 1 and not done.stdout.strip(), done
    assert said[0].startswith("hil: error: history store postgresql+psycopg://hil:***@127.0.0.1:"), said
    assert "unreachable" in said[0] and "check that its server runs" in said[0], said
    _no_secret("hil history's error", done.stderr)


def test_a_usage_error_that_echoes_the_url_hides_its_password(tmp_path):
    """``--hil-history URL`` given before ``--`` (a pytest option): the hint repeats the command line."""
    done = _hil("run", "--hil-history", FORMS["raw @"].format(where="db/h"), cwd=tmp_path)
    assert done.returncode == 4 and "hil run -- --hil-history postgresql://hil:***@db/h" in done.stderr, done
    _no_secret("the usage error", done.stderr)


def test_a_holder_named_by_the_kernel_has_its_password_hidden():
    """A lock held with no record is named from /proc (hil.core.lock.describe_process): its command line too."""
    from hil.core.lock import describe_process
    holder = processes.spawn([sys.executable, "-c", "import sys; sys.stdin.read()", "--hil-history",
                              FORMS["user part"].format(where="db/h")], stdin=subprocess.PIPE)
    try:
        wait_for(lambda: Path(f"/proc/{holder.pid}/cmdline").read_bytes(), "the holder's command line (set by exec)")
        said = describe_process(holder.pid)
    finally:
        processes.end(holder, signal.SIGKILL, grace=0)
    assert "--hil-history postgresql://hil:***@db/h" in said, said
    _no_secret("the kernel's holder", said)
