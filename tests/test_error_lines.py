"""Every error line hil prints has one form, ``hil: error: <what was wrong> — <what to do next>``, whoever finds
the error: argparse, a command, or the pytest plugin under ``hil run`` (issue 42).  Provoked as a user would, by
running ``hil …`` (in this process where nothing but the command line is involved, as its own process where pytest
or a wire is); a mistyped command or option is answered with what it most likely meant."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from hil.cli.main import main
from hil.core.errors import error_line
from tests.test_cli_entry import EXIT_USAGE, REPO, hil
from tests.test_first_hour import _bench_for, _refused_port

#: the one form: the prefix, what was wrong, a dash, what to do next — on one line
ONE_FORM = re.compile(r"^hil: error: \S.* — \S.*$")


def hil_here(capsys: pytest.CaptureFixture[str], *argv: str) -> subprocess.CompletedProcess[str]:
    """``hil …`` run by its own ``main`` in this process, its output captured: the command line's parsing and its
    errors are the same code as in a process of their own, for a fraction of the start-up (the gate's time)."""
    try:
        code = main(list(argv))
    except SystemExit as exc:  # (argparse exits)
        code = exc.code if isinstance(exc.code, int) else 1
    out = capsys.readouterr()
    return subprocess.CompletedProcess(["hil", *argv], code, out.out, out.err)


def error_lines(done: subprocess.CompletedProcess) -> list[str]:
    """The lines of stderr that say an error (a usage line may stand above one: it shows what the command takes)."""
    return [line for line in done.stderr.splitlines() if "error" in line.lower()]


def the_error_line(done: subprocess.CompletedProcess) -> str:
    assert done.returncode == EXIT_USAGE, done.stdout + done.stderr
    lines = error_lines(done)
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert ONE_FORM.match(lines[0]), lines[0]
    return lines[0]


def test_the_form_is_what_then_what_to_do() -> None:
    assert error_line("no such file", "check the path") == "hil: error: no such file — check the path"
    assert error_line("hil: lane 2 does not start\n  (port busy)") == "hil: error: lane 2 does not start (port busy)"
    assert error_line(error_line("twice", "once")) == "hil: error: twice — once"  # said once, whoever adds it


@pytest.mark.parametrize("argv, says", [
    (["rnu"], "invalid choice: 'rnu' (choose from 'run', "),
    (["probe", "--bogus"], "unrecognized arguments: --bogus — see hil probe --help"),
    (["drift", "measure"], "the following arguments are required: --duration — see hil drift measure --help"),
    (["history", "list", "--limit", "many"], "invalid int value: 'many' — see hil history list --help"),
], ids=["unknown-command", "bad-option", "missing-argument", "bad-value"])
def test_argparse_errors_have_the_one_form_under_the_commands_usage(argv: list[str], says: str, capsys) -> None:
    done = hil_here(capsys, *argv)
    assert says in the_error_line(done)
    assert done.stderr.startswith("usage: hil"), done.stderr  # what the command takes, above the error


@pytest.mark.parametrize("argv, meant", [
    (["rnu"], "did you mean 'run'?"),
    (["run", "--bnech", "x"], "did you mean --bench?"),
    (["history", "lst"], "did you mean 'list'?"),
    (["history", "export", "--fromat", "json"], "did you mean --format?"),
    (["rtc", "raed"], "did you mean 'read'?"),
], ids=["command", "run-option", "history-action", "history-export-option", "rtc-action"])
def test_a_typo_is_answered_with_what_it_likely_meant(argv: list[str], meant: str, capsys) -> None:
    assert the_error_line(hil_here(capsys, *argv)).endswith(f" — {meant}")


def test_a_bad_target_url_says_which_forms_there_are(capsys) -> None:
    line = the_error_line(hil_here(capsys, "probe", "nonsense://x"))
    assert "unknown scheme 'nonsense' — write one of these forms: " in line and "fatek+tcp://HOST:500" in line


def test_an_unreachable_target_says_what_to_check(tmp_path: Path) -> None:
    line = the_error_line(hil("probe", f"fatek+tcp://127.0.0.1:{_refused_port()}", cwd=tmp_path))
    assert "check host and port" in line


def test_a_bad_profile_says_what_to_pass(tmp_path: Path) -> None:
    line = the_error_line(hil("run", "--bench", str(tmp_path / "none.toml"), cwd=tmp_path))
    assert "cannot read bench profile" in line and "pass --bench with an existing file" in line


def test_hil_runs_usage_error_inside_pytest_has_the_one_form(tmp_path: Path) -> None:
    """The bench is opened by the pytest plugin, inside pytest: its error is hil's line, not pytest's ``ERROR:``."""
    target = f"fatek+tcp://127.0.0.1:{_refused_port()}"
    done = hil("run", "--bench", _bench_for(target, tmp_path), cwd=tmp_path)
    line = the_error_line(done)
    assert "cannot open bench " in line and f"at {target}:" in line, line
    assert "ERROR:" not in done.stderr + done.stdout


def test_pytests_own_usage_error_under_hil_run_has_the_one_form(tmp_path: Path) -> None:
    line = the_error_line(hil("run", "--", "no_such_test.py", cwd=tmp_path))
    assert "file or directory not found: no_such_test.py — check the arguments after '--'" in line


def test_plain_pytest_says_hils_usage_error_in_the_one_form_too(tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "pytest", str(REPO / "suites" / "test_smoke.py"), "--target", "", "-p",
                           "no:cacheprovider"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert "--target is empty" in the_error_line(done)


def test_pytests_own_usage_errors_stay_pytests(tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "pytest", str(tmp_path / "no_such_test.py"), "-p", "no:cacheprovider"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == EXIT_USAGE and "ERROR: file or directory not found" in done.stderr, done.stderr
