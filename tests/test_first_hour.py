"""A new user's first hour (issue 24): a bench that cannot be opened, usage errors, the defaults — each one line
and exit 4 where it is the user's to fix, through the real command line (``python -m hil``, plain pytest)."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import pytest

from tests.test_cli_entry import EXIT_USAGE, REPO, hil, silent_listener_fixture  # noqa: F401 - the silent_listener fixture


def _refused_port() -> int:
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _bench_for(target: str, where: Path) -> str:
    """A newcomer's profile for the PLC at ``target``: the example copied, its target set (README "Wiring a real
    bench"); a PLC only ever runs with a profile that names it."""
    text = (REPO / "fixtures" / "benches" / "example-bench.toml").read_text()
    path = where / "my-bench.toml"
    path.write_text(text.replace('# target = "fatek+tcp://PLC-IP:500"', f'target = "{target}"', 1))
    return str(path)


def _one_line(done: subprocess.CompletedProcess) -> str:
    lines = [line for line in (done.stdout + done.stderr).splitlines() if line.strip()]
    assert len(lines) == 1, done.stdout + done.stderr
    assert "Traceback" not in lines[0]
    return lines[0]


@pytest.mark.parametrize("target, says", [
    ("fatek+tcp://127.0.0.1:{refused}", "nothing accepted the connection — check host and port"),
    ("modbus+tcp://127.0.0.1:{refused}", "is the PLC powered and reachable at 127.0.0.1:"),
    ("fatek+tcp://nosuchhost.invalid:500", "the host name 'nosuchhost.invalid' does not resolve"),
    ("fatek+tcp://127.0.0.1:{silent}?timeout=0.2&retries=0", "check the station number, the wiring or address"),
    ("modbus+tcp://127.0.0.1:{silent}?timeout=0.2&retries=0", "check the unit id"),
], ids=["fatek-refused", "modbus-refused", "unknown-host", "fatek-silent", "modbus-silent"])
def test_a_bench_that_cannot_be_opened_is_one_line_before_anything_is_collected(
        target: str, says: str, silent_listener: int, tmp_path: Path) -> None:
    target = target.format(refused=_refused_port(), silent=silent_listener)
    # a PLC's profile: the bundled default is the emulator's, refused for a PLC before the wire is tried
    done = hil("run", "--bench", _bench_for(target, tmp_path), "--target", target, cwd=tmp_path)
    assert done.returncode == EXIT_USAGE, done.stdout + done.stderr
    line = _one_line(done)  # nothing collected, skipped or passed before it: it is the only line
    assert f"at {target}:" in line and says in line, line
    assert "socket://" not in line  # the user's target, never the form pyserial is handed
    assert not (tmp_path / "reports" / "junit.xml").exists()  # no report claiming a verdict


@pytest.mark.e2e
def test_probe_names_the_users_target_not_pyserials_socket_url(tmp_path: Path) -> None:
    refused = hil("probe", f"fatek+tcp://127.0.0.1:{_refused_port()}", cwd=tmp_path)
    assert refused.returncode == EXIT_USAGE and "cannot open fatek+tcp://127.0.0.1:" in refused.stderr + refused.stdout
    assert "socket://" not in refused.stderr + refused.stdout
    from tests.external import emulate_process
    with emulate_process(REPO / "fixtures" / "benches" / "emulator.toml", 1.0, {"fatek-tcp": "--fatek-tcp"}) as where:
        done = hil("probe", f"fatek+tcp://{where['fatek-tcp']}", cwd=tmp_path)
        long_url = f"fatek+tcp://{where['fatek-tcp']}?station=1&timeout=3.5&retries=2&fence=reads"
        narrow = hil("probe", long_url, cwd=tmp_path, columns=80)
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"FATEK station 1 on fatek+tcp://{where['fatek-tcp']}" in done.stdout and "socket://" not in done.stdout
    # a long target in 80 columns: whole (wrapped in its row), never cut like a panel title
    assert narrow.returncode == 0, narrow.stdout + narrow.stderr
    shown = "".join(line.strip("│╭╮╰╯─ ").split("target", 1)[-1].strip() for line in narrow.stdout.splitlines()[:4])
    assert long_url.replace(" ", "") in shown.replace(" ", ""), narrow.stdout


def test_plain_pytest_stops_the_same_way(tmp_path: Path) -> None:
    target = f"fatek+tcp://127.0.0.1:{_refused_port()}"
    done = subprocess.run([sys.executable, "-m", "pytest", str(REPO / "suites"), "--target", target,
                           "--bench", _bench_for(target, tmp_path), "-p",
                           "no:cacheprovider"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == EXIT_USAGE
    assert f"at {target}:" in _one_line(done)


def test_probe_says_a_host_name_does_not_resolve(tmp_path: Path) -> None:
    done = hil("probe", "fatek+tcp://nosuchhost.invalid:500", cwd=tmp_path)
    assert done.returncode == EXIT_USAGE
    line = _one_line(done)
    assert "does not resolve" in line and "nothing accepted" not in line, line


def test_an_s7_target_on_an_fbs_profile_names_the_s7_profile(tmp_path: Path) -> None:
    done = hil("run", "--target", "emulator+s7-tcp", cwd=tmp_path)
    assert done.returncode == EXIT_USAGE
    assert "--bench s7-200smart" in _one_line(done)


@pytest.mark.parametrize("argv, says", [
    (["emulate", "--fatek-tcp", "127.0.0.1:99999", "--no-live"], "port 99999 is not a TCP port"),
    (["emulate", "--fatek-tcp", "nosuchhost.invalid:0", "--no-live"], "cannot listen on nosuchhost.invalid:0"),
    (["probe", "fatek+tcp://[::1"], "an IPv6 host goes in brackets"),
    (["run", "--target", ""], "--target is empty"),
    (["probe", ""], "the target URL is empty"),
])
def test_usage_errors_are_one_line_and_exit_4(argv: list[str], says: str, tmp_path: Path) -> None:
    done = hil(*argv, cwd=tmp_path)
    assert done.returncode == EXIT_USAGE, done.stdout + done.stderr
    assert says in _one_line(done)


def test_plain_pytest_refuses_an_empty_target(tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "pytest", str(REPO / "suites" / "test_smoke.py"), "--target", "",
                           "-p", "no:cacheprovider"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == EXIT_USAGE and "--target is empty" in _one_line(done)


def test_probe_and_rtc_read_default_as_hil_run_does(tmp_path: Path) -> None:
    probed = hil("probe", cwd=tmp_path)
    assert probed.returncode == 0, probed.stderr
    assert "emulator (in-process)" in probed.stdout
    profile = tmp_path / "wire.toml"
    profile.write_text((REPO / "fixtures" / "benches" / "emulator.toml").read_text()
                       .replace('target = "emulator"', 'target = "emulator+fatek-tcp"'))
    read = hil("rtc", "read", "--bench", str(profile), cwd=tmp_path)  # the profile's target, no URL
    assert read.returncode == 0, read.stderr
    assert "RTC of emulator+fatek-tcp" in read.stdout and "S-35390A" in read.stdout, read.stdout
    assert hil("rtc", "read", "--bench", "emulator", cwd=tmp_path).returncode == 0  # a profile by its short name


@pytest.mark.parametrize("duration", ["10", "12", "20"])
def test_drift_measure_measures_what_was_asked(duration: str, tmp_path: Path) -> None:
    done = hil("drift", "measure", "emulator", "--duration", duration, cwd=tmp_path)  # virtual time: instant
    assert done.returncode == 0, done.stderr
    assert f"{float(duration):.1f} s bench time" in done.stdout, done.stdout  # was 5.0, 5.0 and 13.0 s


def test_probe_shows_the_clock_as_a_date(tmp_path: Path) -> None:
    import re
    done = hil("probe", "emulator", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    row = next(line for line in done.stdout.splitlines() if "R4128–R4134" in line)
    assert re.search(r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d [A-Z][a-z]+day", row), row


def test_offsets_and_host_times_read_as_durations_and_dates() -> None:
    import datetime as dt

    from hil.cli.rtc import _vs_host
    from hil.core.journal import Journal
    host = dt.datetime(2026, 12, 1, 20, 0, 0)
    far = _vs_host(host - dt.timedelta(days=1005, hours=18, minutes=7, seconds=3), host)
    assert far.startswith("PLC 1005 d 18 h 07 min behind host time") and "-86897223.0 s" in far, far
    assert _vs_host(host + dt.timedelta(seconds=5), host).startswith("PLC 5.0 s ahead of host time")
    journal = Journal("tcp://127.0.0.1:1")
    journal.set_clock(host, host.timestamp() + 0.77, 1.0)
    line = next(line for line in journal.describe() if line.startswith("clock"))
    assert "at host time 2026-12-01 20:00:00.770" in line, line


def test_restore_show_says_what_is_gone(tmp_path: Path) -> None:
    port = _refused_port()  # an emulator's port, closed since
    writer = subprocess.run([sys.executable, "-c", "from hil.core.journal import Journal\n"
                             f"j = Journal('tcp://127.0.0.1:{port}'); j.test = 'suites/test_x.py::t'\n"
                             "j.add_elements({'R100': 7})"], capture_output=True, text=True, timeout=60)
    assert writer.returncode == 0, writer.stderr
    done = hil("restore", "--show", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    text = " ".join(done.stdout.split())
    assert "R100 = 7" in text
    assert "are no longer running" in text and f"nothing listens on 127.0.0.1:{port} now" in text, text


def test_hil_list_names_the_bundled_profiles_and_suites(tmp_path: Path) -> None:
    done = hil("list", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    names = {line.split()[0] for line in done.stdout.splitlines() if line.startswith("  ")}
    assert {"emulator", "s7-200smart", "example-bench", "rtc", "rtc_validity", "smoke", "s7smart"} <= names
    assert "list" in hil("--help", cwd=tmp_path).stdout


def test_a_default_profile_that_cannot_be_opened_stops_at_collection(tmp_path: Path) -> None:
    """No --bench nor --target: the profile found in ./fixtures/benches is opened once a bench test is collected."""
    benches = tmp_path / "fixtures" / "benches"
    benches.mkdir(parents=True)
    target = f"fatek+tcp://127.0.0.1:{_refused_port()}"
    benches.joinpath("emulator.toml").write_text(f'[bench]\nname = "mine"\ntarget = "{target}"\n')
    done = subprocess.run([sys.executable, "-m", "pytest", str(REPO / "suites" / "test_smoke.py"), "-p",
                           "no:cacheprovider", "-q"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == EXIT_USAGE, done.stdout + done.stderr
    assert f"cannot open bench 'mine' at {target}:" in done.stderr
    assert "passed" not in done.stdout and "skipped" not in done.stdout and "error" not in done.stdout.lower()


def test_a_closed_loop_on_an_emulator_without_a_plant_says_so(tmp_path):
    """[pid] without [plant]: the emulator heats nothing, and the closed loop's failure says that, not only that
    PV never reached the band."""
    import re as _re
    text = (REPO / "fixtures" / "benches" / "emulator.toml").read_text()
    profile = tmp_path / "no-plant.toml"
    profile.write_text(_re.sub(r"(?ms)^\[plant\].*?(?=^\[|\Z)", "", text))
    assert "\n[plant]" not in profile.read_text() and "[pid" in profile.read_text()
    done = hil("run", "--bench", str(profile), "--", str(REPO / "suites" / "test_pid_control.py"), "-k",
               "closed_loop", "--hil-run-slow", cwd=tmp_path)
    assert done.returncode == 1, done.stdout[-3000:]
    assert "this profile has no [plant], so the emulator heats nothing" in done.stdout, done.stdout[-3000:]


@pytest.mark.parametrize("argv, usage, says", [
    (["rnu"], "usage: hil [", "invalid choice: 'rnu'"),
    (["run", "--bnech", "x"], "usage: hil run [", "--bnech — did you mean --bench?"),
    (["probe", "--bogus"], "usage: hil probe [", "hil: error: unrecognized arguments: --bogus — see hil probe --help"),
    (["history", "trend", "x", "--bnech", "y"], "usage: hil history trend [", "— did you mean --bench?"),
], ids=["command", "run-option", "probe-option", "history-option"])
def test_a_mistyped_command_or_option_is_answered_by_its_own_command(argv, usage, says, tmp_path: Path) -> None:
    done = hil(*argv, cwd=tmp_path)
    assert done.returncode == EXIT_USAGE and done.stderr.startswith(usage) and says in done.stderr, done.stderr
    if argv == ["rnu"]:
        assert "did you mean 'run'?" in done.stderr


def test_hil_history_alone_lists_the_runs(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("HIL_HISTORY_URL", f"sqlite:///{tmp_path / 'history.sqlite'}")
    done = hil("history", cwd=tmp_path)
    assert done.returncode == 0 and done.stdout.startswith("# runs in sqlite:///"), done.stdout + done.stderr


@pytest.mark.parametrize("argv", [["list"], ["spec"], ["history", "yield"], ["history", "list"]])
def test_a_reader_that_leaves_early_is_not_a_failure(argv, tmp_path: Path, monkeypatch) -> None:
    """hil … | head: the reader has closed the pipe; hil ends quietly with 0 (1 would say "tests failed", 4 a usage
    error), no traceback, no "Broken pipe".  (The read end is closed before hil writes, so every write meets it.)"""
    monkeypatch.setenv("HIL_HISTORY_URL", f"sqlite:///{tmp_path / 'history.sqlite'}")
    env = {k: v for k, v in __import__("os").environ.items() if not k.startswith("PYTEST")}
    proc = subprocess.Popen([sys.executable, "-m", "hil", *argv], cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=env)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 0 and "Traceback" not in err and "Broken pipe" not in err, err


def test_hil_run_help_names_the_slow_and_destructive_options(tmp_path: Path) -> None:
    done = hil("run", "--help", cwd=tmp_path)
    assert "-- --hil-run-slow" in done.stdout and "-- --hil-allow-destructive" in done.stdout


@pytest.mark.e2e
def test_hil_emulate_prints_the_target_to_paste_and_the_lines_pace(tmp_path: Path) -> None:
    """hil emulate --fatek-serial: beside the pty's path (stdout, for scripts) a line for people with the target
    URL — the line's settings and station in it — and the pace; pasted into hil probe, it reaches the emulator."""
    import re as _re
    import signal as _signal

    from tests import processes
    proc = processes.spawn([sys.executable, "-m", "hil", "emulate", "--no-live", "--fatek-serial", "--line",
                            "9600 7E1"], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        said = []
        for line in proc.stderr:  # hang guard: the test's own timeout
            said.append(line)
            if "seed" in line:
                break
        text = "".join(said)
        found = _re.search(r"--target '(fatek\+serial://[^']+)' \(paced at 9600 7E1: 1\.04 ms a character\)", text)
        assert found, text
        assert "baudrate=9600&bytesize=7&parity=E&stopbits=1&station=1" in found.group(1)
        done = hil("probe", found.group(1), cwd=tmp_path, timeout=120)
        assert done.returncode == 0 and "state" in done.stdout, done.stdout + done.stderr
    finally:
        processes.end(proc, _signal.SIGINT, grace=30)


def test_a_command_cut_short_by_a_closed_pipe_never_says_it_succeeded(tmp_path: Path) -> None:
    """Not a listing: hil probe whose reader has gone could not show what it found — it exits 2 (interrupted),
    never 0, and quietly."""
    env = {k: v for k, v in __import__("os").environ.items() if not k.startswith("PYTEST")}
    proc = subprocess.Popen([sys.executable, "-m", "hil", "probe"], cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=env)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 2 and "Traceback" not in err, err
