"""The write guard: refusal before any request, the journal, restore and verification."""

import pytest

from hil.core.errors import RestoreError, WriteRefused
from hil.families.fbs.transport.guard import GuardedTransport
from hil.families.fbs.transport.local import LocalTransport


@pytest.fixture
def guarded(emulator):
    inner = LocalTransport(emulator)
    return GuardedTransport(inner, writable=["R100-R109", "M10-M25"], volatile=["R4128-R4135"])


def test_refused_write_sends_nothing(guarded, emulator):
    before = emulator.memory.snapshot()
    requests = emulator.stats["requests"]
    with pytest.raises(WriteRefused, match="R110 not in the bench's \\[safety\\] writable"):
        guarded.write_words("R108", [1, 2, 3])  # R110 is outside
    with pytest.raises(WriteRefused, match="M26"):
        guarded.write_words("WM16", [0xFFFF])  # WM16 covers M16–M31
    with pytest.raises(WriteRefused):
        guarded.write_many({"R100": 1, "D4054": 0x56E5})
    assert emulator.stats["requests"] == requests
    assert emulator.memory.snapshot() == before


def test_journal_keeps_first_original_and_restore_verifies(guarded, emulator):
    emulator.memory.write("R100", [7, 8])
    emulator.memory.set("M10", 1)
    guarded.write_words("R100", [1, 2])
    guarded.write_words("R100", [3, 4])  # second write: original stays 7, 8
    guarded.write_bits("M10", [0, 1])
    assert guarded.journal == dict(zip(_names("R100", "R101", "M10", "M11"), [7, 8, 1, 0]))
    restored = guarded.restore()
    assert len(restored) == 4
    assert emulator.memory.read("R100", 2) == [7, 8]
    assert emulator.memory.read("M10", 2) == [1, 0]
    assert guarded.journal == {}


def test_volatile_elements_are_allowed_but_not_journaled(emulator):
    guarded = GuardedTransport(LocalTransport(emulator), writable=["R4128-R4134"], volatile=["R4128-R4135"])
    guarded.write_words("R4128", [1, 2, 3])
    assert guarded.journal == {}
    assert set(map(str, guarded.touched)) == {"R4128", "R4129", "R4130"}


def test_restore_reports_what_it_could_not_put_back(guarded, emulator):
    class Stuck:  # a model that forces R100 to 99 every scan: the PLC will not take the old value back
        def power_on(self, emu): pass
        def next_event(self, now): return float("inf")
        def scan(self, emu): emu.memory.words["R"][100] = 99
    guarded.write_words("R100", [5])
    emulator.add_model(Stuck())
    with pytest.raises(RestoreError, match=r"R100 \(original 0\): reads 99 after restore"):
        guarded.restore()


def _names(*names):
    from hil.families.fbs.address import parse
    return [parse(n) for n in names]
