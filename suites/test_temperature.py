"""Temperature modules (FBs manual ch. 20.1–20.4): the table and work block, readings, sensor break and the mask.

Every expectation is stated here, literally from the manual: the table marker A556H, execution codes 56H (every
point measured), FEH (module count 0 or > 8), FFH (more than 32 points) and the mismatch bits of TW+0's low byte,
the per-module entries from TW+4 on, each sensor's range in °C or °F, 0.1 ° resolution at the normal rate and 1 °
at the fast one (shown in 0.1 ° units either way), the accuracy ±(1 % + 1 °C) for thermocouples and ±1 % for
RTD/NTC, the break value 28767, R4010 for points 0–15 and R4011 for 16–31, TW+1/TW+2 for their break bits, a
masked point reading 0 with no break bit.  The bench profile's [temperature] section only says *where* the table,
readings and work block are, *which* modules are fitted and, optionally, which points a reference holds at a
known temperature; [faults.sensor_break] says how this bench opens a sensor.
"""

import pytest

# the table's module name codes are the harness's [our choice] (the manual gives none): the ones the
# bench's own table uses
from hil.families.fbs.temperature import MODULES

# Manual 20.1: points per module, and each sensor's measuring range in °C.
POINTS = {"2TC": 2, "6TC": 6, "16TC": 16, "6RTD": 6, "16RTD": 16, "6NTC": 6}
RANGE_C = {"J": (-200, 900), "K": (-190, 1300), "T": (-190, 380), "E": (-190, 1000), "N": (-200, 1000),
           "B": (350, 1800), "R": (0, 1800), "S": (0, 1700), "PT100": (-200, 850), "PT1000": (-200, 600)}
BREAK = 28767  # 20.3.3: a fitted point whose sensor is open reads 28767
#: 20.1: update time (fast, normal) in seconds — every point of the module measured once in it
UPDATE_S = {"2TC": (1, 2), "6TC": (2, 4), "16TC": (3, 6), "6RTD": (1, 2), "16RTD": (2, 4), "6NTC": (1, 2)}
#: bench seconds a PLC's scan may add to an update (the check is on the last poll that did not yet see the change,
#: so the wire's and the host's delays only make it more lenient, never flaky)
UPDATE_MARGIN_S = 0.5
FAMILY = {"2TC": "TC", "6TC": "TC", "16TC": "TC", "6RTD": "RTD", "16RTD": "RTD", "6NTC": "NTC"}
#: line="idle": most of these tests wait out the modules' update times; in a run with lanes on one line the main
#: lane runs them first, while the other lane sends (hil.plugin.order)
pytestmark = pytest.mark.lane("main", line="idle")
#: 20.3.2, high byte of TW+0
MEASURING, BAD_MODULE_COUNT, TOO_MANY_POINTS = 0x56, 0xFE, 0xFF
#: fewest readings a normal-rate (0.1 °) check needs before "every one a whole degree" means whole degrees
RESOLUTION_SAMPLES = 8


@pytest.fixture
def temp(temperature):
    """The shipped ``temperature`` fixture (hil.families.fbs.fixtures): skips without [temperature], waits for a
    first measurement of every point just after power-on."""
    return temperature


@pytest.fixture
def breaker(bench, temp):
    reason = bench.faults.unavailable("sensor_break")
    if reason:
        pytest.skip(reason)
    yield bench.faults.sensor_break
    # Close every circuit and restore the mask now, then let each point be measured healthy again, so the next
    # test starts from a PLC with no break bits (the bench's own end_test then finds nothing left to undo).  A
    # point the test left masked reads 0 with no break bit until the PLC measures it again: the wait is also for
    # every installed point to read something else (a test that failed midway may leave one).
    bench.end_test()
    temp.wait_until(lambda: _healthy_again(bench, temp))


def _healthy_again(bench, temp):
    """No break bit, no 28767, and no point installed in R4010/R4011 reading 0 (one masked a moment ago)."""
    readings = temp.readings()
    installed = [readings[p] for p in _installed(bench, range(len(readings)))]
    return temp.break_words() == (0, 0) and BREAK not in readings and 0 not in installed


def _words(points):
    """(TW+1, TW+2) — or (R4010, R4011) — with the bits of ``points`` (20.3.2/20.3.3: 0–15 in the first word,
    16–31 in the second)."""
    words = [0, 0]
    for p in points:
        words[p // 16] |= 1 << (p % 16)
    return tuple(words)


def _installed(bench, points):
    """Those of ``points`` whose bit in R4010 (0–15) or R4011 (16–31) is 1 (20.3.3)."""
    mask = bench.plc.io.read_words("R4010", 2)
    return [p for p in points if mask[p // 16] >> (p % 16) & 1]


def _bits(words):
    return " ".join(f"{w:016b}" for w in words)


def _need(bench, *names):
    reason = bench.cannot_reach(*names)
    if reason:
        pytest.skip(reason)


def _in_unit(celsius, unit):
    return celsius * 9 / 5 + 32 if unit == "F" else celsius


@pytest.mark.spec("TEMP-MOD-1", "TEMP-TBL-1", "TEMP-TBL-2", "TEMP-TBL-3", "TEMP-WORK-1", "TEMP-WORK-2",
                  "TEMP-WORK-4", "TEMP-WORK-6", "TEMP-WORK-7", "TEMP-IO-1")
def test_table_is_recognised_and_measuring(bench, temp):
    """SR+0 = A556H, TW+0 = 56H with no mismatch bit, TW+3 = total points / module count, and per module k
    (TW+4+4k …): its sensor kind as the table names it, its point count, its readings' start (module 1 at the
    table's SR+2, each next one after the points before it), its multiplexer index within its points, and its
    I/O: each module takes 1 input register and 8 digital outputs (20.4), so each module's DO number is at least 8
    and its AI number at least 1 past the one before."""
    modules = temp.config.modules
    table = temp.read_table()
    assert table.marker == 0xA556, f"SR+0 = {table.marker:04X}H, the table is valid only with A556H"
    assert table.module_count == len(modules)
    work = temp.read_work()
    assert work.execution_code == 0x56, f"execution code {work.execution_code:02X}H, expected 56H (measuring)"
    assert work.mismatch_bits == 0, f"TW+0 low byte {work.mismatch_bits:08b}: table ≠ modules fitted"
    assert work.module_count == len(modules)
    assert work.total_points == sum(POINTS[m.type.name] for m in modules)
    first = 0
    for k, module in enumerate(modules):
        kind_do, points_ai, start, mux = work.entry(k)
        name = f"module {k + 1} ({module.type.name}), TW+{4 + 4 * k}…"
        assert kind_do >> 8 == table.words[4 + k] >> 8, (
            f"{name}: sensor kind {kind_do >> 8:02X}H, the table's SR+{4 + k} names {table.words[4 + k] >> 8:02X}H")
        assert points_ai >> 8 == POINTS[module.type.name], (
            f"{name}: {points_ai >> 8} points, an FBs-{module.type.name} has {POINTS[module.type.name]}")
        assert start == (table.words[2] + first) & 0xFFFF, (
            f"{name}: readings start {start}, expected SR+2 ({table.words[2]}) + the {first} points before it")
        assert 0 <= mux < POINTS[module.type.name], f"{name}: multiplexer index {mux} outside its points"
        if k:
            do_before, ai_before = work.entry(k - 1)[0] & 0xFF, work.entry(k - 1)[1] & 0xFF
            assert (kind_do & 0xFF) >= do_before + 8, f"{name}: DO {kind_do & 0xFF}, the module before has {do_before}"
            assert (points_ai & 0xFF) >= ai_before + 1, f"{name}: AI {points_ai & 0xFF}, the one before has {ai_before}"
        first += POINTS[module.type.name]


def _accuracy_c(family, celsius):
    """20.1: ±(1 % + 1 °C) for thermocouples, ±1 % for RTD and NTC (1 % of the reading, in °C)."""
    return abs(celsius) / 100 + (1.0 if family == "TC" else 0.0)


def _reference_allowance(config, module, celsius):
    """How far, in the table's unit, a point a reference holds at ``celsius`` may read: the module's accuracy, the
    reference's own uncertainty and the reading's rounding (1 ° at the fast rate, 0.1 ° at the normal one)."""
    allowed = (_accuracy_c(FAMILY[module.type.name], celsius) + config.reference_tolerance)
    allowed *= 9 / 5 if config.unit == "F" else 1
    return allowed + (0.5 if config.rate == "fast" else 0.05)


@pytest.mark.spec("TEMP-SENS-1", "TEMP-SENS-2", "TEMP-SENS-3", "TEMP-UNIT-1", "TEMP-UNIT-2", "TEMP-RATE-1",
                  "TEMP-ACC-1", "TEMP-MASK-1", "TEMP-BREAK-2", "TEMP-WORK-5")
def test_readings_are_in_range_and_units(bench, temp, measure):
    """Every fitted point: 0 when masked off, else within its sensor's range in the table's unit (°C, or °F =
    °C × 9/5 + 32); at the fast rate whole degrees (1 °) in 0.1 ° units, at the normal rate 0.1 ° (not every reading
    a whole degree — taken over at least 8 readings, more updates on a bench with fewer points); and each point a
    reference holds at a known temperature ([temperature] reference) reads it, in the unit, within the module's
    accuracy — which is what tells °C from °F and the sensor kinds without a manual range (NTC)."""
    config = temp.config
    unit = config.unit
    samples = []
    for attempt in range(4):
        readings = temp.readings()
        mask = bench.plc.io.read_words("R4010", 2)
        live = []
        for point, value in enumerate(readings):
            installed = mask[point // 16] >> (point % 16) & 1
            if not installed:
                assert value == 0, f"point {point} is not installed (mask bit 0) yet reads {value}"
                continue
            assert value != BREAK, f"point {point} reads the break value 28767 with no fault injected"
            _, module = config.point_module(point)
            live.append(value)
            if module.sensor.name in RANGE_C:
                low, high = (_in_unit(c, unit) for c in RANGE_C[module.sensor.name])
                if attempt == 0:
                    measure(f"point{point}", value / 10, unit=f"°{unit}", low=low, high=high,
                            note=f"{module.sensor.name} sensor range (readings are in 0.1°)")
                assert low * 10 <= value <= high * 10, (
                    f"point {point} ({module.sensor.name}) reads {value / 10} °{unit}, outside "
                    f"{low}…{high} °{unit} (readings are in 0.1°)")
            if config.rate == "fast":
                assert value % 10 == 0, f"fast rate has 1° resolution, point {point} reads {value} (0.1° units)"
            if point in config.reference and attempt == 0:
                celsius = config.reference[point]
                allowed = _reference_allowance(config, module, celsius)
                want = _in_unit(celsius, unit)
                measure(f"point{point}_reference", value / 10, unit=f"°{unit}", low=want - allowed,
                        high=want + allowed, note=f"a reference holds it at {celsius} °C")
                assert abs(value / 10 - want) <= allowed + 1e-9, (
                    f"point {point} ({module.sensor.name}) is held at {celsius} °C = {want:.2f} °{unit}: it reads "
                    f"{value / 10} °{unit}, more than the module's accuracy ±{allowed:.2f} °{unit} off")
        samples += live
        if config.rate == "fast" or len(samples) >= RESOLUTION_SAMPLES:
            break
        temp.wait_for_update(1.0)  # few points: their next readings, one update later
    assert temp.break_words() == (0, 0), "break bits set with no fault injected"
    if config.rate == "normal":
        if len(samples) < RESOLUTION_SAMPLES:
            pytest.fail(f"inconclusive: {len(samples)} readings over 4 updates, fewer than {RESOLUTION_SAMPLES}, "
                        f"cannot tell 0.1 ° resolution from whole degrees")
        assert any(v % 10 for v in samples), (
            f"normal rate has 0.1 ° resolution, yet all {len(samples)} readings are whole degrees: {samples[:12]}")


def _head(work):
    """TW+0 and TW+3: the execution code, the mismatch bits, the point and module counts."""
    return work.words[0], work.words[3]


def _retable(bench, temp, items, condition):
    """Write table words (``items``: offset from SR → word) and wait, at most the update time (a PLC takes a new
    table at its own next cycle), for the work block the new table produces: ``condition`` holding on a TW+0/TW+3
    other than the one read before the write.  Each step of the tests is chosen so that ``condition`` is false
    before its write (``bench.expect`` says so, as a test error, where it is not), so a block still showing the
    previous table is never read as the answer (fresh evidence); a PLC whose block does not change fails here.
    Returns the work block as then read."""
    sr = temp.config.table
    written = ", ".join(f"SR+{k} = {v & 0xFFFF:04X}H" for k, v in items.items())
    seen, before = [], None

    def shows_it():
        seen[:] = [temp.read_work()]
        return _head(seen[0]) != before and condition(seen[0])

    awaited = bench.expect(f"the work block that {written} produces", shows_it)
    before = _head(seen[0])
    bench.plc.io.write_many({str(sr.offset(k)): v & 0xFFFF for k, v in items.items()})
    bench.settle()
    awaited.within(temp.update_period() * 1.5, every=temp.poll_interval)
    work = seen[0]
    assert _head(work) != before, (
        f"{written} written: TW+0 TW+3 still {before[0]:04X}H {before[1]:04X}H after the update time, the work "
        f"block never showed the new table")
    return work


@pytest.mark.spec("TEMP-MASK-2")
@pytest.mark.needs("power_on_state", reason="a bench's program may have changed R4010/R4011 since power-on")
def test_installed_mask_defaults_to_ffffh(bench, temp):
    r4010, r4011 = bench.plc.io.read_words("R4010", 2)
    assert (r4010, r4011) == (0xFFFF, 0xFFFF), f"R4010, R4011 = {r4010:04X}H, {r4011:04X}H: both default to FFFFH"


@pytest.mark.spec("TEMP-WORK-3", "TEMP-MAX-1", "TEMP-WORK-4", "TEMP-TBL-4", "TEMP-WORK-6", "TEMP-TBL-3")
def test_work_block_codes_for_a_table_that_does_not_fit(bench, temp):
    """20.3.2: the execution code is FEH for a module count (TW+3 low byte) of 0 or more than 8 (tried with 0, 9 and
    FFH: the byte's edges and the first count past 8), FFH for more than 32 points, and bit k of TW+0's low byte flags
    table module k + 1 not matching the module fitted — tried with every module, the even ones and then the odd ones
    (each bit seen set and clear), the entry's module name replaced by FFH (no module) and by another module kind (its
    code in the harness's code table, which the bench's own table uses).  The harness then puts the table back, and
    the code returns to 56H.  Needs the table (SR … SR+11) in [safety] writable; the guard restores it whatever
    happens."""
    config = temp.config
    sr = config.table
    _need(bench, f"{sr}-{sr.offset(4 + 8 - 1)}")
    table = temp.read_table().words
    n = len(config.modules)
    before = temp.readings()

    # The bad counts one after the other, from the valid table (56H) and back to it once: each wait is for FEH with
    # TW+3 counting the new count, which the block before did not show (a PLC that takes the table at its next cycle
    # still shows the last one's code and TW+3 until then) — three counts for the waits of two.
    for count in (0, 9, 0xFF):
        work = _retable(bench, temp, {1: count},
                        lambda w, c=count: w.execution_code == BAD_MODULE_COUNT and w.module_count == c)
        assert work.execution_code == BAD_MODULE_COUNT, (
            f"module count {count} in SR+1: execution code {work.execution_code:02X}H, expected FEH")
        assert work.module_count == count, f"module count {count}: TW+3 low byte {work.module_count}"
    _put_back_count(bench, temp, n)

    biggest = max(range(n), key=lambda k: POINTS[config.modules[k].type.name])
    size = POINTS[config.modules[biggest].type.name]
    many = 32 // size + 1  # modules of the biggest kind that make more than 32 points
    if many <= 8:
        items = {1: many, **{4 + k: table[4 + biggest] for k in range(many)}}
        work = _retable(bench, temp, items, lambda w: w.execution_code == TOO_MANY_POINTS)
        assert work.execution_code == TOO_MANY_POINTS, (
            f"{many} × {config.modules[biggest].type.name} = {many * size} points: execution code "
            f"{work.execution_code:02X}H, expected FFH (more than 32 points)")
        _put_back_count(bench, temp, n, {4 + k: table[4 + k] for k in range(many) if 4 + k < len(table)})

    # Bit k: table module k + 1 names no module (FFH) or another module than the one fitted (TEMP-WORK-4) — each
    # kind on the even and on the odd modules, each step flagging other modules than the one before (a bit seen set
    # while the others are clear, and a PLC that keeps the last step's bits fails); "another module" keeps the
    # total at most 32 points (else FFH), so a module with no such other kind is tried with FFH only.
    headroom = 32 - sum(POINTS[m.type.name] for m in config.modules)

    def no_module(k):
        return (table[4 + k] & 0xFF00) | 0xFF

    def another_module(k):
        other = _another_module(config.modules[k].type.name, headroom)
        return None if other is None else (table[4 + k] & 0xFF00) | MODULES[other].code

    even, odd = [k for k in range(n) if k % 2 == 0], [k for k in range(n) if k % 2 == 1]
    flagged: dict[int, int] = {}  # module → the word the table now names for it
    for modules, name_of in ((even, no_module), (odd, another_module), (even, another_module), (odd, no_module)):
        words = {k: name_of(k) for k in modules if name_of(k) is not None}
        if not words:
            continue
        want = sum(1 << k for k in words)
        if want == sum(1 << k for k in flagged):  # (the same bits as now: clear them first, so the step shows)
            _retable(bench, temp, {4 + k: table[4 + k] for k in flagged}, lambda w: w.mismatch_bits == 0)
            flagged = {}
        items = {**{4 + k: table[4 + k] for k in flagged}, **{4 + k: v for k, v in words.items()}}
        work = _retable(bench, temp, items, lambda w, want=want: w.mismatch_bits == want)
        what = ", ".join(f"{k + 1}: {'FFH (no module)' if v & 0xFF == 0xFF else _module_name(v)}"
                         for k, v in words.items())
        assert work.mismatch_bits == want, (
            f"table modules {what} do not match the modules fitted "
            f"({', '.join(m.type.name for m in config.modules)}): TW+0 low byte {work.mismatch_bits:08b}, "
            f"expected {want:08b}")
        flagged = words
    work = _retable(bench, temp, {4 + k: table[4 + k] for k in flagged},
                    lambda w: w.mismatch_bits == 0 and w.execution_code == MEASURING)
    assert work.mismatch_bits == 0 and work.execution_code == MEASURING, (
        f"the table put back: TW+0 = {work.words[0]:04X}H, expected 5600H")
    # Left as found: a module the PLC stopped measuring (or measured elsewhere) averages its way back over as many
    # updates as it averages samples; the next test must not see those readings.
    bench.plc.io.write_words(str(sr), table)
    temp.wait_until(lambda: all(_close(a, b) for a, b in zip(temp.readings(), before)),
                    periods=config.averaging + 1.5)


@pytest.mark.spec("TEMP-TBL-2")
def test_nothing_is_measured_while_sr0_is_not_a556h(bench, temp, breaker):
    """20.3.1: the table is valid only with SR+0 = A556H.  With any other marker — one above (A557H) and one below
    (56A5H, A556H byte-swapped), one update time and the margin each, after one more for the PLC to take the first
    — the PLC measures nothing: sensors opened meanwhile (every one the rig can open) show neither 28767 nor a
    break bit.  The sensors repaired, A556H is put back.  Needs SR+0 in [safety] writable; the guard restores it."""
    config = temp.config
    sr = config.table
    _need(bench, str(sr))
    points = breaker.openable(list(range(config.points)))
    if not points:
        pytest.skip("the sensor-break rig can open none of the fitted points")
    io = bench.plc.io
    update = max(UPDATE_S[m.type.name][0 if config.rate == "fast" else 1] for m in config.modules)
    # The marker first, and one update time for the PLC to take it (it may read the table at its next cycle, and an
    # idle PLC shows nothing that says it has): a valid table must not get to measure an open sensor.
    io.write(str(sr), 0xA557)
    bench.plc.time.wait(update + UPDATE_MARGIN_S)
    bench.settle()
    before, words_before = temp.readings(), temp.break_words()
    for p in points:
        breaker.open(p)
    for marker in (0xA557, 0x56A5):
        io.write(str(sr), marker)
        bench.plc.time.wait(update + UPDATE_MARGIN_S)  # every point measured in that time, were it measuring
        bench.settle()
        readings = temp.readings()
        shown = [p for p in points if readings[p] == BREAK != before[p]]
        assert not shown, (f"SR+0 = {marker:04X}H (not A556H: no table), yet the open sensors of points {shown} "
                           f"read 28767: the PLC measured")
        words = temp.break_words()
        assert words == words_before, (f"SR+0 = {marker:04X}H (no table), yet TW+1 TW+2 went from "
                                       f"{_bits(words_before)} to {_bits(words)}: the PLC measured")
    for p in points:  # (repaired before the table is valid again: no open sensor left to be measured and waited out)
        breaker.repair(p)
    io.write(str(sr), 0xA556)


def _put_back_count(bench, temp, n, entries=None):
    """The table's own module count (and ``entries``) back: measuring again, 56H (20.3.2)."""
    work = _retable(bench, temp, {1: n, **(entries or {})}, lambda w: w.execution_code == MEASURING)
    assert work.execution_code == MEASURING, (
        f"the table's module count {n} put back: execution code {work.execution_code:02X}H, expected 56H")


def _another_module(name, headroom):
    """A module kind other than ``name`` whose points fit ``headroom`` more than its own (the same count first)."""
    fits = [m for m in POINTS if m != name and POINTS[m] <= POINTS[name] + headroom]
    return min(fits, key=lambda m: (POINTS[m] != POINTS[name], -POINTS[m]), default=None)


def _module_name(word):
    return next((f"{name} ({word & 0xFF:02X}H)" for name, m in MODULES.items() if m.code == word & 0xFF),
                f"{word & 0xFF:02X}H")


def _close(after, before):
    """The same sensor a little later: within the module accuracy ±(1 % + 1 °C), doubled for drift."""
    return abs(after - before) <= 2 * (abs(before) / 100 + 10) + 10


@pytest.mark.spec("TEMP-BREAK-1", "TEMP-BREAK-2", "TEMP-BREAK-3", "TEMP-WORK-5", "TEMP-MASK-1", "TEMP-MASK-3",
                  "TEMP-RATE-2")
def test_sensors_broken_masked_unmasked_and_repaired(bench, temp, breaker, measure):
    """Every fitted point the rig can open goes through the manual's states, in four groups changing together (one
    module update shows each step whole): A masked off in R4010/R4011 and every sensor opened → A reads 0 with no
    break bit, B, C and D 28767 with exactly their break bits (TW+1 for 0–15, TW+2 for 16–31); A unmasked, B and D
    masked → A, still broken, reads 28767 with its bits, B and D (seen broken) 0 and no bit, C keeps 28767 and its
    bits; B repaired while masked, A, C and D repaired, and every fitted point masked in a checkerboard over
    R4010/R4011 (p masked, p ± 16 and p ± 1 not) → the masked read 0, the others their live readings (B's unmasked
    half among them), no break bit; all unmasked → every point its live reading, no break bit.  Points the rig
    cannot open keep their readings throughout (but for the checkerboard's mask)."""
    config = temp.config
    fitted = list(range(config.points))
    points = breaker.openable(fitted)
    if not points:
        pytest.skip("the sensor-break rig can open none of the fitted points")
    # groups alternate along the points, so that each half (R4010/TW+1, R4011/TW+2) has points of each
    group_a, group_b, group_c, group_d = points[0::4], points[1::4], points[2::4], points[3::4]
    io = bench.plc.io
    _need(bench, "R4010-R4011")
    mask = io.read_words("R4010", 2)
    everything = _words(fitted)
    if (mask[0] & everything[0], mask[1] & everything[1]) != everything:
        io.write_many({"R4010": mask[0] | everything[0], "R4011": mask[1] | everything[1]})
        temp.wait_until(lambda: 0 not in temp.readings())
    mask = io.read_words("R4010", 2)
    others = [p for p in fitted if p not in points]

    def healthy(readings):
        return all(readings[p] not in (0, BREAK) for p in points)

    temp.wait_until(lambda: healthy(temp.readings()))
    before = temp.readings()

    def check(state, broken, zero, live, extra=""):
        readings = temp.readings()
        words = temp.break_words()
        wrong = [p for p in broken if readings[p] != BREAK]
        assert not wrong, f"{state}: points {wrong} read {[readings[p] for p in wrong]}, expected 28767{extra}"
        stray = [p for p in live + others if readings[p] in (BREAK, 0)]
        assert not stray, f"{state}: points {stray} read {[readings[p] for p in stray]}, expected live readings"
        wrong = [p for p in zero if readings[p] != 0]
        assert not wrong, f"{state}: masked-off points {wrong} read {[readings[p] for p in wrong]}, expected 0"
        want = _words(broken)
        assert words == want, f"{state}: TW+1 TW+2 = {_bits(words)}, expected only points {broken}: {_bits(want)}"
        return readings

    # 20.1: each module measures every point once per update time, so a change shows within it (TEMP-RATE-2)
    update = max(UPDATE_S[m.type.name][0 if config.rate == "fast" else 1] for m in config.modules)
    clock = bench.plc.time

    def within_an_update(what, event):
        """Poll ``event`` until it holds (at most 1.5 updates and the margin); the latest bench time at which it was
        seen not to hold, from the start: the change came after it (a lower bound, whatever the wire's delays)."""
        started = clock.now()
        deadline = started + 1.5 * update + UPDATE_MARGIN_S
        missed = started
        while True:
            before = clock.now()
            if event():
                break
            missed = before
            if before >= deadline:
                break
            clock.wait(temp.poll_interval)
        took = missed - started
        measure(f"update_{what}", took, unit="s", low=0, high=update + UPDATE_MARGIN_S,
                note=f"{config.rate} rate: every point measured within {update} s (the last poll that did not yet "
                     f"see it)")
        bench.settle()
        return took

    def reading_all(want):
        """One read of the readings (a poll is one frame, however many points it looks at): ``want`` holds?"""
        readings = temp.readings()
        return all(ok(readings[p]) for p, ok in want)

    def mask_off(group):
        off = _words(group)
        io.write_many({"R4010": mask[0] & ~off[0], "R4011": mask[1] & ~off[1]})  # R4010: 0–15, R4011: 16–31

    def in_time(took, what):
        assert took <= update + UPDATE_MARGIN_S, (
            f"{what} {took:.1f} s after the change: each point is measured within the update time, {update} s")

    mask_off(group_a)  # (before the sensors open: A never gets measured open and unmasked)
    for p in points:
        breaker.open(p)
    shown = sorted(group_b + group_c + group_d)
    took = within_an_update("open", lambda: temp.break_words() == _words(shown) and
                            reading_all([(p, lambda v: v == BREAK) for p in shown] +
                                        [(p, lambda v: v == 0) for p in group_a]))
    check("every sensor open, A masked off as they opened", shown, group_a, [])
    in_time(took, "the open sensors (and A masked off) were not all showing")

    mask_off(group_b + group_d)  # A unmasked, still broken; B and D, seen broken, masked off
    shown = sorted(group_a + group_c)
    took = within_an_update("mask", lambda: temp.break_words() == _words(shown) and
                            reading_all([(p, lambda v: v == 0) for p in group_b + group_d] +
                                        [(p, lambda v: v == BREAK) for p in group_a]))
    check("A unmasked while still broken, B and D masked off, C still open", shown, group_b + group_d, [])
    in_time(took, "the masked points did not all read 0 (and A 28767 again)")

    # All repaired, and in the same update every fitted point masked in a checkerboard over R4010/R4011 — p masked
    # and p ± 16 not, neighbours opposite — so a PLC reading a point's bit from the other word or the next bit shows,
    # as does one that masks only open sensors (no sensor is open now: the masked read 0 with their sensors healthy,
    # those just repaired among them).  One update shows both: the repairs on the unmasked half, the healthy mask on
    # the other; unmasked again, every point must read live with no break bit.
    checker = [p for p in fitted if (p // 16 + p) % 2 == 0]
    for p in group_b + group_a + group_c + group_d:  # B first, while still masked off
        breaker.repair(p)
    mask_off(checker)
    took = within_an_update("mask_healthy", lambda: temp.break_words() == (0, 0) and reading_all(
        [(p, lambda v: v == 0) for p in checker] +
        [(p, lambda v: v not in (0, BREAK)) for p in points if p not in checker]))
    readings, words = temp.readings(), temp.break_words()
    wrong = [p for p in checker if readings[p] != 0]
    assert not wrong, (f"no sensor open, points {wrong} masked off in R4010/R4011 ({_bits(_words(checker))} cleared) "
                       f"read {[readings[p] for p in wrong]}, expected 0")
    stray = [p for p in fitted if p not in checker and readings[p] in (0, BREAK)]
    assert not stray, (f"points {stray}, repaired or never open and still fitted in R4010/R4011 (their neighbours "
                       f"and p ± 16 masked off), read {[readings[p] for p in stray]}, expected live readings: each "
                       f"point has its own bit")
    assert words == (0, 0), f"all repaired, points masked: TW+1 TW+2 = {_bits(words)}, expected no break bit"
    in_time(took, "the masked healthy points did not all read 0 (and the repaired ones their live value)")

    io.write_many({"R4010": mask[0], "R4011": mask[1]})
    temp.wait_until(lambda: temp.break_words() == (0, 0) and reading_all(
        [(p, lambda v: v not in (0, BREAK)) for p in points] + [(p, lambda v: v != 0) for p in checker]))
    bench.settle()
    after = check("all repaired, unmasked", [], [], points)
    for p in points:
        tolerance = 2 * (abs(before[p]) / 100 + 10) + 10
        measure(f"point{p}_repair_change", abs(after[p] - before[p]) / 10, unit=f"°{config.unit}", low=0,
                high=tolerance / 10, note=f"read {before[p] / 10} before the break, {after[p] / 10} after")
        assert _close(after[p], before[p]), (
            f"point {p} read {before[p]} before the break, {after[p]} after being repaired")


@pytest.mark.spec("TEMP-UNIT-1", "TEMP-UNIT-3", "TEMP-ACC-1")
def test_a_reading_below_zero_is_a_signed_word(bench, temp, measure):
    """20.1/20.3: a reading is one register in 0.1 °, and the ranges of most sensors go below 0 °C, so a reading
    below zero is the signed 16-bit value: −12.3 ° is the word FF85H, −123.  Each point a reference holds below 0 in
    the table's unit ([temperature] reference: an ice-salt bath, a calibrator) must read a word with the sign bit set
    whose signed value is the reference's temperature within the module's accuracy — not 0 (a PLC that clamps at
    zero), not the magnitude (one that drops the sign).  Skipped on a bench with no such reference."""
    config = temp.config
    installed = _installed(bench, range(config.points))
    # (held so far below zero that the module's whole accuracy band is: only there must a reading carry the sign)
    cold = {p: c for p, c in config.reference.items() if p in installed
            and _in_unit(c, config.unit) + _reference_allowance(config, config.point_module(p)[1], c) < 0}
    if not cold:
        pytest.skip(f"no point installed in R4010/R4011 is held below 0 °{config.unit} by more than its module's "
                    f"accuracy: name one in [temperature] reference (an ice-salt bath, a calibrator) to check "
                    f"readings below zero")
    for point, celsius in sorted(cold.items()):
        _, module = config.point_module(point)
        want = _in_unit(celsius, config.unit)
        allowed = _reference_allowance(config, module, celsius)
        word = bench.plc.io.read_words(config.readings.offset(point), 1)[0]  # the raw word, not the decoded value
        value = word - 0x10000 if word & 0x8000 else word
        measure(f"point{point}_below_zero", value / 10, unit=f"°{config.unit}", low=want - allowed,
                high=want + allowed, note=f"a reference holds it at {celsius} °C; word {word:04X}H")
        expected = round(want * 10)
        assert word & 0x8000, (
            f"point {point} ({module.sensor.name}) is held at {want:.1f} °{config.unit}: its reading word is "
            f"{word:04X}H = {word}, with no sign bit; below zero a reading is the signed 16-bit value "
            f"(about {expected & 0xFFFF:04X}H = {expected})")
        assert abs(value / 10 - want) <= allowed + 1e-9, (
            f"point {point} ({module.sensor.name}) is held at {want:.1f} °{config.unit}: its word {word:04X}H reads "
            f"{value / 10} °{config.unit} signed, more than the module's accuracy ±{allowed:.2f} °{config.unit} off")


@pytest.mark.spec("TEMP-RATE-2")
def test_each_module_shows_a_change_within_its_own_update_time(bench, temp, breaker, measure):
    """20.1: a module measures every one of its points once per *its own* update time (fast / normal: 2TC, 6RTD,
    6NTC 1/2 s, 6TC and 16RTD 2/4 s, 16TC 3/6 s), whatever other modules are fitted beside it.  Every point the
    rig can open is opened at once; each one's 28767 — news: none reads it before — must show within its own
    module's update time (and the scan margin), not only within the slowest module's.  Timed on the last poll that
    still saw the point's old reading, from the moment its open was done: a lower bound, whatever the wire's
    delays."""
    config = temp.config
    points = breaker.openable(_installed(bench, range(config.points)))  # (a masked point shows no break: 20.3.3)
    if not points:
        pytest.skip("the sensor-break rig can open none of the points installed in R4010/R4011")
    rate = 0 if config.rate == "fast" else 1
    before = temp.readings()
    already = [p for p in points if before[p] == BREAK]
    assert not already, f"points {already} read 28767 before any sensor was opened"
    clock = bench.plc.time
    opened = {}
    for p in points:
        breaker.open(p)
        opened[p] = clock.now()  # (the open is done by now: the time is taken late, the check only more lenient)
    missed = dict(opened)  # each point's last poll that did not see 28767
    waiting = set(points)
    deadline = clock.now() + 1.5 * temp.update_period() + UPDATE_MARGIN_S  # (a hang guard: the slowest module's)
    while waiting:
        polled = clock.now()
        readings = temp.readings()
        for p in list(waiting):
            if readings[p] == BREAK:
                waiting.discard(p)
            else:
                missed[p] = polled
        if not waiting or polled >= deadline:
            break
        clock.wait(temp.poll_interval)
    assert not waiting, f"points {sorted(waiting)} never read 28767 after their sensors were opened"
    for k, module in enumerate(config.modules):  # (measure fails the test at the first module out of its limit)
        mine = [p for p in points if config.point_module(p)[0] == k]
        if mine:
            limit = UPDATE_S[module.type.name][rate]
            measure(f"module{k + 1}_update", max(missed[p] - opened[p] for p in mine), unit="s", low=0,
                    high=limit + UPDATE_MARGIN_S,
                    note=f"module {k + 1}, an FBs-{module.type.name} at the {config.rate} rate, measures each of its "
                         f"points within its own update time, {limit} s (the last poll that still saw a point of it "
                         f"unbroken, from that point's open)")
