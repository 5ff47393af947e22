"""What a user meets first on the command line: which tests ``hil run`` runs, its options, exit codes, errors."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from hil.cli import drift
from hil.cli.main import main
from hil.cli.run import pytest_args, selects_tests
from tests import processes

REPO = Path(__file__).resolve().parent.parent
EXIT_USAGE, EXIT_INTERNAL = 4, 3


def hil(*argv: str, cwd: Path, timeout: float = 120, columns: int = 100) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST")}
    return subprocess.run([sys.executable, "-m", "hil", *argv], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout, env=env | {"COLUMNS": str(columns)})


def test_pytest_arguments_that_name_tests_replace_the_default_suites() -> None:
    assert selects_tests(["suites/test_rtc.py"]) and selects_tests(["-q", "suites/test_rtc.py::test_x[a]"])
    assert not selects_tests(["-k", "rtc", "-m", "slow", "-x", "--lf", "-o", "junit_family=xunit1"])
    assert not selects_tests(["--deselect", "suites/test_rtc.py::test_x"])
    assert pytest_args(None, None, "j.xml", ["suites/test_rtc.py"])[0].startswith("--")  # no suites dir added
    assert pytest_args(None, None, "j.xml", ["-k", "rtc"])[0].endswith("suites")


def test_hil_run_with_a_file_runs_only_that_file(tmp_path: Path) -> None:
    done = hil("run", "-q", "--junitxml", str(tmp_path / "junit.xml"), "--html", str(tmp_path / "r.html"), "--",
               str(REPO / "suites" / "test_smoke.py"), cwd=tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    files = {c.get("file") or c.get("classname") for c in ET.parse(tmp_path / "junit.xml").iter("testcase")}
    assert files and all("test_smoke" in f for f in files), files
    # no "module already imported" noise on every run (the command line imports some plugin modules first)
    assert "warning" not in done.stdout and "PytestAssertRewriteWarning" not in done.stdout + done.stderr, done.stdout


def test_plain_pytest_outside_the_checkout_warns_of_no_assert_rewriting(tmp_path: Path) -> None:
    # an editable install: pytest cannot list the package's files, so a plugin module imported before pytest marks
    # it warned "Module already imported so cannot be rewritten" (one per module, on every run)
    done = processes.run([sys.executable, "-m", "pytest", str(REPO / "suites" / "test_smoke.py"), "-q", "-p",
                          "no:cacheprovider", "-W", "error::pytest.PytestAssertRewriteWarning"], cwd=tmp_path,
                         timeout=120)
    assert done.returncode == 0 and "PytestAssertRewriteWarning" not in done.stdout + done.stderr, \
        done.stdout[-3000:] + done.stderr


def test_cache_provider_works_from_any_directory(tmp_path: Path) -> None:
    # --lf needs pytest's cache provider; its directory is the current one, never inside the package
    done = hil("run", "-q", "--junitxml", str(tmp_path / "j.xml"), "--html", str(tmp_path / "r.html"), "--",
               "--lf", "-k", "smoke", cwd=tmp_path)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "5 passed" in done.stdout
    assert (tmp_path / ".pytest_cache").is_dir()


def test_pytest_options_before_the_separator_get_a_hint(capsys) -> None:
    with pytest.raises(SystemExit) as info:
        main(["run", "-k", "rtc"])
    assert info.value.code == EXIT_USAGE
    err = capsys.readouterr().err
    assert "after '--'" in err and "hil run -- -k rtc" in err


def test_python_dash_m_hil(tmp_path: Path) -> None:
    done = hil("--version", cwd=tmp_path)
    assert done.returncode == 0 and done.stdout.startswith("hil ")


def test_debug_is_accepted_after_the_sub_command(capsys) -> None:
    assert main(["drift", "code", "fast", "--debug"]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert "Traceback" in err and "InvalidValue" in err  # --debug: the traceback of a user error too
    assert main(["drift", "code", "fast"]) == EXIT_USAGE
    assert "Traceback" not in capsys.readouterr().err


def test_exit_codes_are_pytests(capsys, tmp_path: Path) -> None:
    assert main(["run", "--bench", str(tmp_path / "none.toml")]) == EXIT_USAGE  # pytest: 4 = usage error
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "none.toml" in err


def test_a_bug_shows_its_traceback(capsys, monkeypatch) -> None:
    def broken(rate, console):
        raise ZeroDivisionError("a bug")
    monkeypatch.setattr(drift, "drift_code", broken)
    assert main(["drift", "code", "3.38"]) == EXIT_INTERNAL
    err = capsys.readouterr().err
    assert "Traceback" in err and "ZeroDivisionError: a bug" in err and "internal error" in err


@pytest.mark.parametrize("argv, says", [
    (["drift", "code", "1e308"], "+1e+308 s/day is outside"),
    (["drift", "code", "inf"], "as a number"),
    (["drift", "measure", "emulator", "--duration", "1e12"], "at most 31622400 s"),
    (["drift", "measure", "emulator", "--duration", "nan"], "more than 5 s"),
])
def test_absurd_numbers_are_one_short_line(capsys, argv: list[str], says: str) -> None:
    assert main(argv) == EXIT_USAGE
    out, err = capsys.readouterr()
    assert out == "" and says in err and len(err.strip().splitlines()) == 1 and len(err) < 300, err


def test_missing_serial_port_names_the_path_once(capsys) -> None:
    assert main(["probe", "fatek+serial:///dev/ttyHIL-none"]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert err.count("/dev/ttyHIL-none") == 1 and "plugged in" in err, err


@pytest.fixture(name="silent_listener")
def silent_listener_fixture():
    """A TCP port that accepts and never answers."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    yield server.getsockname()[1]
    server.close()


def test_modbus_listener_that_never_replies_is_one_line(silent_listener: int, tmp_path: Path) -> None:
    done = hil("probe", f"modbus+tcp://127.0.0.1:{silent_listener}?timeout=0.2&retries=1", cwd=tmp_path)
    assert done.returncode == EXIT_USAGE
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr  # pymodbus's own log lines are silenced
    assert "no valid reply" in lines[0] and "retries" not in lines[0]


@pytest.mark.e2e
def test_emulate_refuses_time_scale_zero_before_any_endpoint_line(tmp_path: Path) -> None:
    done = hil("emulate", "--fatek-tcp", "127.0.0.1:0", "--time-scale", "0", "--no-live", cwd=tmp_path)
    assert done.returncode == EXIT_USAGE and done.stdout == ""
    assert "--time-scale 0" in done.stderr


@pytest.mark.e2e
def test_emulate_clock_starts_at_host_time(tmp_path: Path) -> None:
    from hil.core.timebase import HostTimebase
    from hil.families.fbs.device.plc import FbsPlc
    from hil.families.fbs.transport.factory import open_transport
    proc = processes.spawn([sys.executable, "-m", "hil", "emulate", "--fatek-tcp", "127.0.0.1:0", "--no-live"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    try:
        kind, address = proc.stdout.readline().split()
        time.sleep(0.3)  # past the start-up: the clock runs on its own
        with open_transport(f"fatek+tcp://{address}") as transport:
            plc = FbsPlc(transport, HostTimebase())
            shown = plc.rtc.read().to_datetime()
            host = __import__("datetime").datetime.now()
        behind = (host - shown).total_seconds()
        assert -0.5 < behind < 1.2, behind  # whole seconds on the PLC; was 1.5–2 s behind
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def test_fatek_listener_that_never_replies_is_one_line_that_blames_nothing_earlier(silent_listener: int,
                                                                                  tmp_path: Path) -> None:
    done = hil("probe", f"fatek+tcp://127.0.0.1:{silent_listener}?timeout=0.2&retries=1", cwd=tmp_path)
    assert done.returncode == EXIT_USAGE
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert "earlier fault" not in lines[0] and "check the station number" in lines[0]
