"""The FATEK guard's restore of side effects (FUN86's outputs after an EN write): what the test wrote goes back
first, then what the PLC rewrote only because of it is read, and written back only where it differs — a block that
still holds its originals costs one read instead of a write and a read-back (on port 0 both cost alike)."""

from hil.families.fbs.address import parse
from hil.families.fbs.transport.guard import GuardedTransport
from hil.families.fbs.transport.local import LocalTransport


def _guarded(emulator):
    guarded = GuardedTransport(LocalTransport(emulator), writable=["M0", "R100-R109"])
    effects = [parse(f"R{200 + i}") for i in range(8)]  # as FUN86's OR block rewritten on an EN edge
    guarded.side_effects = lambda written: effects if parse("M0") in set(written) else []
    return guarded


def _writes_during(guarded, action):
    """The elements each write-back of ``action`` sent, in order."""
    writes, write_back = [], guarded.write_back
    guarded.write_back = lambda items: (writes.extend(str(a) for a, _ in items), write_back(items))
    action()
    return writes


def test_side_effects_still_at_their_originals_are_read_not_written(emulator):
    guarded = _guarded(emulator)
    emulator.memory.write("R200", [5] * 8)
    guarded.begin()
    guarded.write("M0", 1)
    writes = _writes_during(guarded, guarded.restore)
    assert writes == ["M0"], "only what the test wrote is written back"
    assert emulator.memory.get("M0") == 0 and emulator.memory.read("R200", 8) == [5] * 8
    assert guarded.journal == {}


def test_side_effects_the_plc_changed_are_written_back_after_their_cause_and_verified(emulator):
    guarded = _guarded(emulator)
    emulator.memory.write("R200", [5] * 8)
    guarded.begin()
    guarded.write("M0", 1)
    emulator.memory.write("R203", [9])  # the PLC's own rewrite while EN was on
    writes = _writes_during(guarded, guarded.restore)
    assert writes == ["M0", "R203"], "the cause first, then only the changed word"
    assert emulator.memory.read("R200", 8) == [5] * 8
    assert guarded.journal == {}


def test_a_side_effect_the_test_wrote_itself_is_written_back_like_any_write(emulator):
    guarded = GuardedTransport(LocalTransport(emulator), writable=["M0", "R200-R207"])
    guarded.side_effects = lambda written: [parse("R200")] if parse("M0") in set(written) else []
    emulator.memory.write("R200", [5])
    guarded.begin()
    guarded.write("M0", 1)
    guarded.write("R200", 5)  # the same value: still a write of the test, put back whatever it reads
    writes = _writes_during(guarded, guarded.restore)
    assert writes == ["M0", "R200"]
