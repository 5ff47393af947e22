"""What the guard journals and restores of FUN86's own rewrites.  The FATEK guard's restore of side effects:
what the test wrote goes back first, then what the PLC rewrote only because of it is read, and written back only
where it differs — a block that still holds its originals costs one read instead of a write and a read-back (on
port 0 both cost alike).  And a box that takes Sn/Zn from registers rewrites only the points they give (none for an
invalid Sn/Zn), any of its 32 once Sn/Zn are written while EN is on."""

import pytest

from hil.bench.profile import load_profile
from hil.core.journal import Journal
from hil.families.fbs.address import parse
from hil.families.fbs.bench import Bench
from hil.families.fbs.transport.guard import GuardedTransport
from hil.families.fbs.transport.local import LocalTransport
from hil.sim.model import Model
from tests.conftest import EMULATOR_BENCH


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
    guarded.write("R200", 7)  # a write of the test: put back in the first write, whatever the PLC did after it
    writes = _writes_during(guarded, guarded.restore)
    assert writes == ["M0", "R200"]
    assert emulator.memory.read("R200", 1) == [5]


def test_a_run_the_test_wrote_back_to_its_originals_is_read_and_written_only_where_the_plc_changed_it(emulator):
    """Ki = 0 over Ki = 0: what reads its original after the restore's first write is as found (that read is its
    verification); what the PLC changed since the test's last write is written back and read back."""
    guarded = GuardedTransport(LocalTransport(emulator), writable=["M0", "R100-R109"])
    emulator.memory.write("R100", [0] * 10)
    guarded.begin()
    guarded.write("M0", 1)
    guarded.write_words("R100", [0] * 10)
    writes = _writes_during(guarded, guarded.restore)
    assert writes == ["M0"], "the block still holds its originals: read, not written"
    guarded.begin()
    guarded.write_words("R100", [3] * 10)
    guarded.write_words("R100", [0] * 10)
    emulator.memory.write("R104", [9])  # the PLC changed one word after the test's last write
    writes = _writes_during(guarded, guarded.restore)
    assert writes == ["R104"]
    assert emulator.memory.read("R100", 10) == [0] * 10 and guarded.journal == {}
    guarded.begin()
    guarded.write_words("R100", [0, 0, 0, 4, 0, 0, 0, 0, 0, 0])  # one word of the run changed: the run is written
    writes = _writes_during(guarded, guarded.restore)
    assert writes == [f"R{100 + i}" for i in range(10)]


# -- what FUN86 rewrites: a box that takes Sn/Zn from registers reaches the points they give --------------------------
@pytest.fixture
def err_box():
    """The emulator bench's box with Sn/Zn registers, every point's gains tuned away from FUN86's defaults:
    (bench, box, the tuned PR/IR/DR)."""
    bench = Bench(load_profile(EMULATOR_BENCH), target="emulator")
    box = next(i for i in bench.plc.pid.config.instances if i.settable)
    tuned = {str(getattr(box, k).offset(i)): v for i in range(32) for k, v in (("pr", 250), ("ir", 20), ("dr", 40))}
    bench.raw.write_many(tuned)
    yield bench, box, tuned
    bench.close()


def _journaled(bench):
    return {str(e) for e in bench.io.journal}


def _switch_on(bench, box, sn, zn):
    """A test starts, gives the box Sn/Zn (EN off), then switches EN on (heating)."""
    bench.begin_test(f"test_switches_the_box_on_at_sn_{sn}_zn_{zn}")
    bench.plc.pid.set_sn_zn(box, sn, zn)
    bench.plc.pid.enable(box, True, heating=True)


def test_en_on_a_box_of_registered_sn_zn_journals_every_point_whatever_the_registers_hold(err_box):
    """The side effects are decided from the names written, not from what the PLC holds: recovery asks the same of
    the whole allow-list after a crash, when the registers may read anything."""
    bench, box, tuned = err_box
    _switch_on(bench, box, 8, 4)
    bench.wait(5)
    assert bench.raw.read_words(str(box.pr), 5) == [110] * 4 + [250], \
        "precondition: FUN86's first execution loaded its defaults into the 4 points' PR only"
    assert {str(box.pr.offset(i)) for i in range(32)} <= _journaled(bench)
    assert set(map(str, bench.plc.pid.side_effects([box.en]))) == \
        set(map(str, bench.plc.pid.side_effects([box.sn_register])))
    bench.end_test()
    assert bench.raw.read_many(list(tuned)) == list(tuned.values())


def test_an_invalid_sn_zn_then_a_valid_one_while_en_is_on_leaves_every_point_as_found(err_box):
    bench, box, tuned = err_box
    _switch_on(bench, box, 0, 33)
    bench.settle()
    assert bench.plc.pid.err(box), "precondition: Zn 33 is refused with ERR"
    bench.plc.pid.set_sn_zn(box, 0, 32)  # while EN is on: FUN86 may now act on any point
    bench.wait(5)
    assert bench.raw.read_words(str(box.pr), 32) == [110] * 32, \
        "precondition: FUN86 executed for the first time once Sn/Zn were valid: every point's defaults"
    bench.end_test()
    assert bench.raw.read_many(list(tuned)) == list(tuned.values()), "every point's tuned gains are back"


def test_a_cause_of_side_effects_written_back_to_its_original_by_the_test_is_still_written_back_first(emulator):
    """EN 1 then 0 (its original): still written back before its side effects are read — after a write of unknown
    outcome it may hold 1, and what it makes the PLC rewrite is stable only once it is undone."""
    guarded = _guarded(emulator)
    guarded.begin()
    guarded.write("M0", 1)
    guarded.write("M0", 0)
    writes = _writes_during(guarded, guarded.restore)
    assert writes == ["M0"]


# -- recovery after a kill: the causes first, then what the PLC rewrites --------------------------------------------
class _RewritesAtItsNextInterval(Model):
    """As FUN86 at its next PID interval: while M1010 is on, its second scan writes R1050–R1057 (the outputs the
    test's settings give) — a rewrite that may land between a recovery's read and the write that stops it."""

    def __init__(self) -> None:
        self.scans_on = 0

    def scan(self, emu) -> None:
        self.scans_on = self.scans_on + 1 if emu.memory.get("M1010") else 0
        if self.scans_on == 2:
            emu.memory.write("R1050", [7] * 8)


def test_recovery_reads_what_the_plc_rewrites_only_once_its_cause_is_undone(emulator, tmp_path):
    """A run dies with EN on while the outputs it makes the PLC rewrite happen to hold their originals; the PLC
    rewrites them a scan later.  Recovery puts EN back first and only then reads the outputs: the rewrite is
    found and undone (read before EN, they would have been taken as back and the rewrite left)."""
    emulator.add_model(_RewritesAtItsNextInterval())
    outputs = [parse(f"R{1050 + i}") for i in range(8)]

    def guard():
        g = GuardedTransport(LocalTransport(emulator), writable=["M1010", "R1000-R1009"])
        g.side_effects = lambda written: outputs if parse("M1010") in set(written) else []
        g.durable = Journal("plc", tmp_path)
        g.identity_vouched = True
        return g

    dead = guard()
    dead.begin("test_killed")
    dead.write_words("R1000", [3, 4])
    dead.write("M1010", 1)
    emulator.memory.write("R1050", [0] * 8)  # the outputs at their originals at the moment of the kill…
    emulator.models[-1].scans_on = 0  # …and the PLC's next rewrite of them two scans away
    report = guard().recover()
    assert report is not None and report.ok, report.summary()
    assert emulator.memory.get("M1010") == 0
    assert emulator.memory.read("R1050", 8) == [0] * 8, "the PLC's rewrite after the kill was put back"
    assert emulator.memory.read("R1000", 2) == [0, 0]
    assert not Journal("plc", tmp_path).pending
