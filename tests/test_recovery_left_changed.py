"""Recovery that overwrites nothing it cannot prove the run's and forgets no journal it can read (issue 40, items 6,
8 and 10, and ``hil restore --show``), against ``hil emulate`` as a separate process, reached only over its wires.

Each test makes a journal the way a run does — a run SIGKILLed in a child process, or a bench that dies without
restoring — then does what an operator or a host would do after the crash, and runs ``hil restore`` (or the next
session) as a user would.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import pwd
import re
import signal
from pathlib import Path

import pytest

from hil.bench.profile import load_profile
from hil.bench.recovery import Outcome
from hil.core.journal import Journal, journal_path
from hil.core.lock import lock_key
from hil.families.fbs.bench import Bench
from hil.families.fbs.device.plc import FbsPlc
from hil.families.fbs.rtc_time import RtcTime
from tests.conftest import EMULATOR_BENCH
from tests.external import hil_emulate
from tests.test_clock_and_forced_bits import _a_run_that_sets_the_clock
from tests.test_kill_recovery import READINGS, differences, snapshot
from tests.test_recovery_trust import KILL, _plc, _profile, _restore, _session, _url

pytestmark = pytest.mark.e2e  # hil emulate in real time
WORK_BLOCK = {f"R{n}" for n in range(3060, 3100)}  # the emulator profile's temperature work block (its [temperature])


@pytest.fixture(scope="module")
def plc():
    """One ``hil emulate`` (FATEK/TCP, the rig) for this module's tests; each leaves it as found."""
    with hil_emulate(EMULATOR_BENCH, 1.0) as where:
        yield where


def _died_writing(profile: Path, writes: dict[str, int], lane: str | None = None) -> Journal:
    """A run (or one lane of a run with lanes) that wrote ``writes`` and died before its restore: its journal is
    left on disk, the PLC changed."""
    bench = Bench(load_profile(profile), lane=lane)
    try:
        bench.begin_test("suites/test_x.py::test_died")
        bench.plc.io.write_many(writes)
        return bench.journal
    finally:
        bench.close()  # died: nothing restored


# -- item 6: command 42 journaled with what it set; a bit changed since is left ------------------------------------
def test_a_bit_an_operator_forced_after_a_killed_runs_command_42_is_left_and_reported(plc, tmp_path, capsys):
    url, profile = _url(plc), _profile(tmp_path, plc)
    with _plc(plc) as t:
        assert (t.read_disabled("M1001", 1), t.read_bits("M1001", 1)) == ([0], [0]), "as found: enabled, 0"
    run = _session(tmp_path, profile, f"bench.plc.io.bit_action('M1001', 1)\n{KILL}")  # disables it, then dies
    assert run.returncode == -signal.SIGKILL, run.stdout + run.stderr
    entry = Journal(lock_key(url)).data["enable"]["M1001"]
    assert (entry["disabled"], entry["wrote"]) == (False, True), "the state command 42 set is journaled"
    assert Journal(lock_key(url)).data["elements"]["M1001"]["wrote"] == 0, "and the value it left, not null"
    try:
        with _plc(plc) as t:  # the operator, after the crash: forces M1001 at 1 (un-force, set, force)
            t.bit_action("M1001", 2)
            t.write_bits("M1001", [1])
            t.bit_action("M1001", 1)
        code, lines = _restore(capsys, url, "--bench", str(profile))
        text = " ".join(lines)
        assert code == 1 and "changed since — left" in text, lines
        assert "M1001 is disabled with value 1, the run left it disabled, value 0 (original enabled)" in text, text
        assert "M1001 reads 1, the run wrote 0 (original 0)" in text, text
        with _plc(plc) as t:
            assert (t.read_disabled("M1001", 1), t.read_bits("M1001", 1)) == ([1], [1]), "the operator's force stays"
        assert set(Journal(lock_key(url)).data["enable"]) == {"M1001"}, "kept for a look by hand"
    finally:
        with _plc(plc) as t:
            t.bit_action("M1001", 2)
            t.write_bits("M1001", [0])
        journal_path(lock_key(url)).unlink(missing_ok=True)


def test_a_bit_left_as_the_killed_run_set_it_is_put_back(plc, tmp_path, capsys):
    url, profile = _url(plc), _profile(tmp_path, plc)
    run = _session(tmp_path, profile, f"bench.plc.io.bit_action('M1002', 1)\nbench.plc.io.bit_action('M1002', 3)\n"
                                      f"{KILL}")  # forced at 1, then dies
    assert run.returncode == -signal.SIGKILL, run.stdout + run.stderr
    code, lines = _restore(capsys, url, "--bench", str(profile))
    assert code == 0 and "M1002 enabled (read back, command 43)" in lines[0] and "M1002 = 0" in lines[0], lines
    with _plc(plc) as t:
        assert (t.read_disabled("M1002", 1), t.read_bits("M1002", 1)) == ([0], [0])
    assert not journal_path(lock_key(url)).exists()


# -- item 8: a damaged lane journal stops no other ----------------------------------------------------------------
@pytest.mark.parametrize("by", ["hil restore", "the next run"])
def test_a_damaged_lane_journal_is_named_and_the_good_ones_beside_it_restored(plc, tmp_path, capsys, by):
    url, profile = _url(plc), _profile(tmp_path, plc)
    with _plc(plc) as t:
        found = t.read_words("R1000", 2)
    _died_writing(profile, {"R1000": found[0] ^ 0x55})
    _died_writing(profile, {"R1001": found[1] ^ 0x66}, lane="gw0")
    damaged = _died_writing(profile, {"R1002": 1}, lane="gw1").path  # then a power cut truncates its file
    with _plc(plc) as t:
        t.write("R1002", 0)  # (what it wrote is not the point here)
    raw = damaged.read_bytes()[:40]
    damaged.write_bytes(raw)
    try:
        if by == "hil restore":
            code, lines = _restore(capsys, url, "--bench", str(profile))
            text = " ".join(lines)
        else:
            run = _session(tmp_path, profile, "pass")
            code, text = run.returncode, run.stdout
        assert code != 0 and str(damaged) in text and "damaged" in text, text
        assert f"R1000 = {found[0]}" in text and f"R1001 = {found[1]}" in text, text
        with _plc(plc) as t:
            assert t.read_words("R1000", 2) == found, "both good journals replayed"
        assert not journal_path(lock_key(url)).exists() and not journal_path(lock_key(url), lane="gw0").exists()
        assert damaged.read_bytes() == raw, "the damaged one kept as it is"
    finally:
        damaged.unlink()


def test_a_damaged_run_journal_is_named_and_its_lanes_restored(plc, tmp_path, capsys):
    url, profile = _url(plc), _profile(tmp_path, plc)
    with _plc(plc) as t:
        found = t.read("R1001")
    damaged = _died_writing(profile, {"R1000": 1}).path
    with _plc(plc) as t:
        t.write("R1000", 0)
    _died_writing(profile, {"R1001": found ^ 0x66}, lane="gw0")
    damaged.write_bytes(b'{"version": 2')
    try:
        code, lines = _restore(capsys, url, "--bench", str(profile))
        text = " ".join(lines)
        assert code != 0 and str(damaged) in text and "damaged" in text and f"R1001 = {found}" in text, text
        with _plc(plc) as t:
            assert t.read("R1001") == found, "the lane's journal replayed"
        run = _session(tmp_path, profile, "bench.plc.io.write('R1002', 5)")  # nothing goes out over a damaged one
        assert run.returncode != 0 and str(damaged) in run.stdout, run.stdout
        with _plc(plc) as t:
            assert t.read("R1002") == 0
        assert damaged.read_bytes() == b'{"version": 2', "kept as it is"
    finally:
        damaged.unlink()


# -- item 10: a host clock step carried on the boot clock; another boot ---------------------------------------
def _killed_with_the_clock_set(profile: Path, **change: float | str) -> Path:
    """A run that set the RTC and was killed; its journal's clock entry then changed as the host's clocks would
    have moved (``change``: fields added to it)."""
    dead = _a_run_that_sets_the_clock(load_profile(profile), dies=True)
    path = dead.journal.path
    data = json.loads(path.read_text())
    for name, value in change.items():
        data["clock"][name] = data["clock"][name] + value if isinstance(value, float) else value
    path.write_text(json.dumps(data))
    return path


def _year(plc) -> int:
    with _plc(plc) as t:
        return t.read("R4133")


def _clock_back(profile: Path) -> None:
    """The emulator's clock put back by hand (as an operator would) and the journal's clock entry removed."""
    bench = Bench(load_profile(profile))
    try:
        bench.journal.drop_clock()
        FbsPlc(bench.raw, bench.time).rtc.sync_to_host()
    finally:
        bench.close()


def test_a_host_clock_step_is_carried_on_the_boot_clock_and_reported_with_the_figures(plc, tmp_path, capsys):
    """23.9 h on the boot clock, 42.6 s more on the wall clock (issue 40: accepted as within 500 ppm before, carried
    by the wall clock): the origin is carried by the boot clock, the step said with its figure."""
    url, profile = _url(plc), _profile(tmp_path, plc)
    _killed_with_the_clock_set(profile, host=-(86040.0 + 42.6), since_boot=-86040.0)
    try:
        code, lines = _restore(capsys, url, "--bench", str(profile))
        text = " ".join(lines)
        assert code == 0 and "wall clock was stepped by +42.600 s" in text, lines
        with _plc(plc) as t:
            shown = RtcTime.from_registers(t.read_words("R4128", 7)).to_datetime()
        ahead = (shown - dt.datetime.now(dt.UTC).replace(tzinfo=None)).total_seconds()
        # the emulator's clock ran on host time before the run: the boot clock's 23.9 h on, not the wall's 42.6 s more
        assert abs(ahead - 86040.0) <= 3.0, f"the clock was put back {ahead:+.1f} s from host time, not +86040 s"
    finally:
        _clock_back(profile)


@pytest.mark.matrix  # the gate holds the clock check's step (above); this half in the matrix: the gate's time
def test_a_clock_origin_from_another_boot_needs_accept_host_clock(plc, tmp_path, capsys):
    url, profile = _url(plc), _profile(tmp_path, plc)
    _killed_with_the_clock_set(profile, boot="another-boot-of-this-host")
    try:
        code, lines = _restore(capsys, url, "--bench", str(profile))
        text = " ".join(lines)
        assert code == 1 and "another boot of this host" in text and "--accept-host-clock" in text, lines
        assert _year(plc) == 99, "set from a host clock nothing can check"
        code, lines = _restore(capsys, url, "--bench", str(profile), "--accept-host-clock")
        assert code == 0 and "clock = " in lines[0], lines
        assert _year(plc) == dt.datetime.now().year % 100
    finally:
        _clock_back(profile)


# -- hil restore --show: every journal, whose, which bench, what a restore would do; nothing written ----------------
def test_show_lists_every_journal_and_what_a_restore_would_do_writing_nothing(plc, tmp_path, capsys):
    url, profile = _url(plc), _profile(tmp_path, plc)
    with _plc(plc) as t:
        found = t.read_words("R1000", 2)
    _died_writing(profile, {"R1000": found[0] ^ 0x55})
    _died_writing(profile, {"R1001": found[1] ^ 0x66}, lane="gw0")
    damaged = _died_writing(profile, {"R1002": 1}, lane="gw1").path
    with _plc(plc) as t:
        t.write("R1001", 4321)  # an operator, after the crash
        t.write("R1002", 0)
    damaged.write_bytes(b"{")
    files = {p: p.read_bytes() for p in journal_path(lock_key(url)).parent.glob("journal-*.json")}
    assert len(files) == 3
    rig = plc["rig-modbus-tcp"]
    before = snapshot(url, rig, time_scale=1.0)
    # what the PLC changes on its own: the temperature readings and work block (execution code, break bits: set at
    # each measurement, the first one a few seconds after hil emulate starts), and whatever else moves meanwhile
    moving = {k for k, v in snapshot(url, rig, 1.0).items() if before[k] != v} | READINGS | WORK_BLOCK
    try:
        code, lines = _restore(capsys, "--show", "--bench", str(profile))
        after = snapshot(url, rig, time_scale=1.0)
        assert not differences(before, after, moving, time_scale=1.0), "--show wrote to the PLC"
        assert {p: p.read_bytes() for p in files} == files, "--show changed a journal"
        text = "\n".join(lines)
        user, pid = pwd.getpwuid(os.getuid()).pw_name, os.getpid()
        headers = [line for line in lines if "pending restore" in line]
        assert len(headers) == 2 and all(f"left by user {user}, pid {pid}" in h for h in headers), text
        assert any("lane gw0" in h for h in headers), text
        assert f"would restore: R1000 to {found[0]} (reads {found[0] ^ 0x55}, as the run left it)" in text, text
        assert (f"changed since — left: R1001 reads 4321, the run wrote {found[1] ^ 0x66} (original {found[1]})"
                in text), text
        assert any(line.startswith("refused") and str(damaged) in line for line in lines), text
        assert code == 0
    finally:
        with _plc(plc) as t:
            t.write_many({"R1000": found[0], "R1001": found[1]})
        for path in files:
            path.unlink(missing_ok=True)


# -- issue 41: one verdict per entry, whoever replays the journal --------------------------------------------------
def _verdicts(text: str) -> dict[str, Outcome]:
    """Element → what became of it, read from a recovery's summary (the run's line, ``hil restore``'s) or from
    ``hil restore --show``'s lines: each entry's line follows its outcome's label."""
    labels = sorted({label for o in Outcome for label in (o.done, o.shown)}, key=len, reverse=True)
    pieces = re.split(f"({'|'.join(map(re.escape, labels))}): ", text)
    found: dict[str, Outcome] = {}
    for label, lines in zip(pieces[1::2], pieces[2::2]):
        for line in lines.split("\n")[0].removesuffix(" — ").split("; "):
            name = re.match(r"[RM]\d+", line)
            if name:
                found[name.group()] = Outcome.labelled(label)
    return found


def test_a_journal_gets_the_same_verdicts_from_the_next_run_and_from_hil_restore(plc, tmp_path, capsys):
    url, wide = _url(plc), _profile(tmp_path, plc)
    narrow = tmp_path / "narrow.toml"  # R1002 no longer writable: refused, by both
    narrow.write_text(wide.read_text().replace('"R1000-R1099"', '"R1000-R1001", "R1003-R1099"'))
    with _plc(plc) as t:
        found = t.read_words("R1000", 4)
    ran = [found[0] ^ 0x55, found[1] ^ 0x66, found[2] ^ 0x77, found[3] ^ 0x11]
    journal = _died_writing(wide, dict(zip(("R1000", "R1001", "R1002", "R1003"), ran))).path
    left = [ran[0], 4321, ran[2], found[3]]  # an operator, after the crash: R1001 changed, R1003 put back
    with _plc(plc) as t:
        t.write_words("R1000", left)
    kept = journal.read_bytes()
    expected = {"R1000": Outcome.RESTORED, "R1001": Outcome.CHANGED, "R1002": Outcome.REFUSED,
                "R1003": Outcome.BACK}
    try:
        _, lines = _restore(capsys, "--show", "--bench", str(narrow))
        shown = _verdicts("\n".join(lines))
        assert shown == {**expected, "R1000": Outcome.PLANNED}, lines
        run = _session(tmp_path, narrow, "pass")
        by_run = _verdicts(next(line for line in run.stdout.splitlines() if "hil bench recovery" in line))
        assert by_run == expected, run.stdout
        with _plc(plc) as t:  # the same PLC and the same journal again, for hil restore
            assert t.read_words("R1000", 4) == [found[0], *left[1:]]
            t.write_words("R1000", left)
        journal.write_bytes(kept)
        code, lines = _restore(capsys, url, "--bench", str(narrow))
        assert code == 1 and _verdicts(" ".join(lines)) == by_run, lines
    finally:
        with _plc(plc) as t:
            t.write_words("R1000", found)
        journal.unlink(missing_ok=True)
