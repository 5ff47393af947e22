"""The journal's format (issue 25, items 2 and 8): version 2, a registry of entry kinds each with its validator,
and save before mutate.  Fast: no PLC, the file only."""

from __future__ import annotations

import json

import pytest

from hil.core import journal as jmod
from hil.core.journal import ELEMENTS, KINDS, EntryKind, Journal, JournalError, JournalRefused, register_kind


def test_every_section_has_a_kind_with_a_validator():
    assert set(KINDS) == {"elements", "coils", "clock", "run", "disabled", "enable"}
    assert ELEMENTS.check({"original": 1, "wrote": 2, "test": "t", "pid": 1, "at": "2026-01-01T00:00:00+00:00"}) \
        is None
    for bad, why in (({"original": True, "wrote": 2}, "original"), ({"original": 1, "wrote": "2"}, "wrote"),
                     ({"original": 1, "wrote": 2, "at": "yesterday"}, "time stamp"),
                     ({"original": 1, "wrote": None, "at": "2999-01-01T00:00:00+00:00"}, "in the future"),
                     ([1], "not an object")):
        assert why in ELEMENTS.check(bad), bad


def test_an_unknown_section_refuses_the_file_until_its_kind_is_registered(tmp_path):
    journal = Journal("tcp://127.0.0.1:500", tmp_path)
    journal.add_elements({"R1": 0}, {"R1": 1})
    data = json.loads(journal.path.read_text())
    data["forced"] = {"M1": {"disabled": True}}
    journal.path.write_text(json.dumps(data))
    refused = Journal("tcp://127.0.0.1:500", tmp_path)  # kept as it is, named, and nothing added to it
    assert "unknown section" in refused.refused and refused.pending
    with pytest.raises(JournalRefused, match="unknown section"):
        refused.load()
    with pytest.raises(JournalRefused, match="unknown section.*refusing every write"):
        refused.add_elements({"R2": 0}, {"R2": 1})
    kind = register_kind(EntryKind("forced", True, lambda e: None, lambda n, e: f"{n} forced", {}))
    try:
        assert any("M1 forced" in line for line in Journal("tcp://127.0.0.1:500", tmp_path).describe())
    finally:
        del KINDS[kind.section]


def test_a_failed_save_changes_nothing_and_refuses_every_later_entry(tmp_path, monkeypatch):
    journal = Journal("tcp://127.0.0.1:500", tmp_path)
    journal.add_elements({"R1": 0}, {"R1": 1})
    on_disk = journal.path.read_bytes()

    def full(self, data):
        raise JournalError("disk full")
    monkeypatch.setattr(Journal, "_save", full)
    with pytest.raises(JournalError):
        journal.add_elements({"R2": 0}, {"R2": 5})
    assert "R2" not in journal.data["elements"] and journal.failed
    monkeypatch.undo()
    with pytest.raises(JournalError, match="could not be written earlier"):
        journal.add_elements({"R3": 0}, {"R3": 5})
    with pytest.raises(JournalError, match="could not be written earlier"):
        journal.set_clock(__import__("datetime").datetime(2026, 1, 1), 1.0, 1.0)
    assert journal.path.read_bytes() == on_disk
    journal.drop_elements(["R1"])  # putting back is never refused
    assert not journal.path.exists()


def test_a_written_value_is_recorded_before_each_write_and_the_first_original_kept(tmp_path):
    journal = Journal("tcp://127.0.0.1:500", tmp_path, endpoint="tcp://127.0.0.1:500", plc={"serial": "01"})
    journal.add_elements({"R1": 7}, {"R1": 8})
    journal.add_elements({"R1": 9}, {"R1": 10})
    data = json.loads(journal.path.read_text())
    assert data["version"] == jmod.VERSION == 2 and data["plc"] == {"serial": "01"}
    assert data["elements"]["R1"]["original"] == 7 and data["elements"]["R1"]["wrote"] == 10
    # a run killed after journaling 10 but before sending it leaves 8 on the PLC: kept as what the run may have left
    assert data["elements"]["R1"]["earlier"] == 8 and jmod.run_left(data["elements"]["R1"]) == [10, 8]
    journal.add_coil("rig", "modbus+tcp://127.0.0.1:5020", 3, 1, False, True)
    journal.add_coil("rig", "modbus+tcp://127.0.0.1:5020", 3, 1, True, False)
    assert jmod.run_left(journal.coils()["rig"]) == [False, True]


def test_enable_states_keep_the_first_and_leave_only_when_dropped(tmp_path):
    journal = Journal("tcp://127.0.0.1:500", tmp_path)
    journal.add_enable_states({"M1001": True}, {"M1001": False})
    journal.add_enable_states({"M1001": False, "M1002": False}, {"M1001": True, "M1002": True})
    assert Journal("tcp://127.0.0.1:500", tmp_path).enable_states() == {"M1001": True, "M1002": False}
    # what command 42 set, as for a written value: the last, and the one before it (issue 40, item 6)
    assert jmod.run_left(journal.data["enable"]["M1001"]) == [True, False]
    journal.drop_enable_states(["M1001", "M1002"])
    assert not journal.path.exists()
