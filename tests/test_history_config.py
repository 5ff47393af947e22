"""Where the history goes (``--hil-history``, ``$HIL_HISTORY_URL``, the profile's ``[history] url``, the default),
and a store that cannot be opened at all: one line, the run and its verdict as without it."""

from __future__ import annotations

import pytest

# imported before any in-process session (pytester) can import them first: pytester drops what a session imported,
# and numpy's and SQLAlchemy's compiled parts cannot be loaded twice in one process
import hil.families.fbs.sim
import hil.history.store  # noqa: F401
from hil.bench.profile import profile_from_dict
from hil.core.errors import InvalidValue, ProfileError
from hil.core.redact import hide_password
from hil.history import config
from tests.conftest import EMULATOR_BENCH


def test_the_command_line_then_the_environment_then_the_profile_then_sqlite_in_the_state_dir(monkeypatch, tmp_path):
    monkeypatch.setenv("HIL_STATE_DIR", str(tmp_path))
    monkeypatch.delenv("HIL_HISTORY_URL")
    assert config.resolve() == f"sqlite:///{tmp_path / 'history.sqlite'}"
    assert config.resolve(None, "postgresql://hil@db.lab/hil") == "postgresql+psycopg://hil@db.lab/hil"
    monkeypatch.setenv("HIL_HISTORY_URL", "sqlite:////srv/h.sqlite")
    assert config.resolve(None, "postgresql://hil@db.lab/hil") == "sqlite:////srv/h.sqlite"
    assert config.resolve("off", "postgresql://hil@db.lab/hil") is None
    assert config.resolve(str(tmp_path / "x.sqlite")) == f"sqlite:///{tmp_path / 'x.sqlite'}"
    with pytest.raises(InvalidValue, match="history URL is empty"):
        config.resolve(" ")
    assert hide_password("postgresql+psycopg://hil:secret@db.lab/hil") == "postgresql+psycopg://hil:***@db.lab/hil"


def _profile(history: dict) -> dict:
    return {"bench": {"name": "b"}, "history": history}


def test_the_profile_s_history_section():
    assert profile_from_dict(_profile({"url": "postgresql://hil@db/hil"})).history_url == "postgresql://hil@db/hil"
    assert profile_from_dict({"bench": {"name": "b"}}).history_url is None
    with pytest.raises(ProfileError, match=r"unknown key\(s\) in \[history\]: uri"):
        profile_from_dict(_profile({"uri": "x"}))
    with pytest.raises(ProfileError, match=r"\[history\] url"):
        profile_from_dict(_profile({"url": ""}))


def test_a_store_that_cannot_be_opened_is_said_once_and_the_run_goes_on(pytester, monkeypatch, tmp_path):
    monkeypatch.setenv("HIL_HISTORY_URL", "nosuchdb://somewhere/x")
    pytester.makepyfile(test_b="def test_one(bench):\n    pass\ndef test_two(bench):\n    pass\n")
    result = pytester.runpytest_inprocess("--bench", str(EMULATOR_BENCH), "-p", "no:cacheprovider")
    result.assert_outcomes(passed=2)
    said = [line for line in result.outlines if "history store" in line]
    assert len(said) == 1 and "nosuchdb://somewhere/x unreachable" in said[0], result.outlines
    from hil.history.store import Store
    spool = Store(config.spool_url())  # the state directory's spool kept the run
    try:
        run = spool.runs()[0]
        assert run["finished"] and run["verdict"] == "PASSED" and run["counts"] == {"passed": 2}
    finally:
        spool.close()
