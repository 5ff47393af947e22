"""Temperature modules (FBs manual ch. 20.1–20.4): the table and work block, readings, sensor break and the mask.

Every expectation is stated here, literally from the manual: the table marker A556H, execution code 56H, the
break value 28767, R4010 for points 0–15 and R4011 for 16–31, TW+1/TW+2 for their break bits, a masked point
reading 0 with no break bit.  The bench profile's [temperature] section only says *where* the table, readings
and work block are and *which* modules are fitted; [faults.sensor_break] says how this bench opens a sensor.
"""

import pytest

# Manual 20.1: points per module, and each sensor's measuring range in °C.
POINTS = {"2TC": 2, "6TC": 6, "16TC": 16, "6RTD": 6, "16RTD": 16, "6NTC": 6}
RANGE_C = {"J": (-200, 900), "K": (-190, 1300), "T": (-190, 380), "E": (-190, 1000), "N": (-200, 1000),
           "B": (350, 1800), "R": (0, 1800), "S": (0, 1700), "PT100": (-200, 850), "PT1000": (-200, 600)}
BREAK = 28767  # 20.3.3: a fitted point whose sensor is open reads 28767
# both ends of R4010/TW+1 (points 0–15) and of R4011/TW+2 (16–31): the first and last fitted point of each half
BREAK_POINTS = ["first-low", "last-low", "first-high", "last-high"]


@pytest.fixture
def temp(bench):
    temperature = bench.plc.temperature
    if not temperature.configured:
        pytest.skip("the bench profile has no [temperature] section")
    if temperature.read_work().execution_code != 0x56:
        temperature.wait_for_update()  # just powered on: let every point be measured once
    return temperature


@pytest.fixture
def breaker(bench, temp):
    reason = bench.faults.unavailable("sensor_break")
    if reason:
        pytest.skip(reason)
    yield bench.faults.sensor_break
    # Close every circuit and restore the mask now, then let each point be measured healthy again, so the next
    # test starts from a PLC with no break bits (the bench's own end_test then finds nothing left to undo).
    bench.end_test()
    temp.wait_until(lambda: temp.read_work().break_words == (0, 0) and BREAK not in temp.readings())


def _point(temp, role):
    """The fitted point a role names, from the profile's modules (e.g. 30 points: 0, 15, 16, 29)."""
    fitted = temp.config.points
    half = range(0, min(16, fitted)) if role.endswith("low") else range(16, fitted)
    if not half:
        pytest.skip(f"no fitted point among {'0–15' if role.endswith('low') else '16–31'} (the profile's modules "
                    f"give {fitted} points)")
    return half[0] if role.startswith("first") else half[-1]


def _mask_register(point):
    return "R4010" if point < 16 else "R4011"  # 20.3.3


def _expected_break_words(point):
    """(TW+1, TW+2) with only ``point``'s bit set (20.3.2: TW+1 = sensors 0–15, TW+2 = sensors 16–31)."""
    return (1 << point, 0) if point < 16 else (0, 1 << (point - 16))


def _set_mask_bit(bench, point, on):
    name = _mask_register(point)
    reason = bench.cannot_reach(name)
    if reason:
        pytest.skip(f"cannot change the installed mask: {reason}")
    word = bench.plc.io.read(name)
    bit = 1 << (point % 16)
    bench.plc.io.write(name, word | bit if on else word & ~bit)


def _ensure_installed(bench, point):
    if not bench.plc.io.read(_mask_register(point)) >> (point % 16) & 1:
        _set_mask_bit(bench, point, True)


@pytest.mark.spec("TEMP-MOD-1", "TEMP-TBL-1", "TEMP-TBL-2", "TEMP-TBL-3", "TEMP-WORK-1", "TEMP-WORK-2",
                  "TEMP-WORK-4", "TEMP-WORK-6")
def test_table_is_recognised_and_measuring(bench, temp):
    modules = temp.config.modules
    table = temp.read_table()
    assert table.marker == 0xA556, f"SR+0 = {table.marker:04X}H, the table is valid only with A556H"
    assert table.module_count == len(modules)
    work = temp.read_work()
    assert work.execution_code == 0x56, f"execution code {work.execution_code:02X}H, expected 56H (measuring)"
    assert work.mismatch_bits == 0, f"TW+0 low byte {work.mismatch_bits:08b}: table ≠ modules fitted"
    assert work.module_count == len(modules)
    assert work.total_points == sum(POINTS[m.type.name] for m in modules)


@pytest.mark.spec("TEMP-SENS-1", "TEMP-SENS-2", "TEMP-UNIT-1", "TEMP-UNIT-2", "TEMP-RATE-1", "TEMP-MASK-1",
                  "TEMP-BREAK-2", "TEMP-WORK-5")
def test_readings_are_in_range_and_units(bench, temp, measure):
    config = temp.config
    readings = temp.readings()
    mask = bench.plc.io.read_words("R4010", 2)
    for point, value in enumerate(readings):
        installed = mask[point // 16] >> (point % 16) & 1
        if not installed:
            assert value == 0, f"point {point} is not installed (mask bit 0) yet reads {value}"
            continue
        assert value != BREAK, f"point {point} reads the break value 28767 with no fault injected"
        _, module = config.point_module(point)
        if module.sensor.name in RANGE_C:
            low, high = RANGE_C[module.sensor.name]
            if config.unit == "F":
                low, high = low * 9 / 5 + 32, high * 9 / 5 + 32
            measure(f"point{point}", value / 10, unit=f"°{config.unit}", low=low, high=high,
                    note=f"{module.sensor.name} sensor range (readings are in 0.1°)")
            assert low * 10 <= value <= high * 10, (
                f"point {point} ({module.sensor.name}) reads {value / 10} °{config.unit}, outside "
                f"{low}…{high} °{config.unit} (readings are in 0.1°)")
        if config.rate == "fast":
            assert value % 10 == 0, f"fast rate has 1° resolution, point {point} reads {value} (0.1° units)"
    assert temp.read_work().break_words == (0, 0), "break bits set with no fault injected"


#: the manual's two ways back from a masked broken sensor (20.3.3): unmasked while still broken → 28767, or
#: repaired while masked and then unmasked → its live reading; each register gets both, at different ends
UNMASKED_STILL_BROKEN = {"first-low", "last-high"}


@pytest.mark.spec("TEMP-BREAK-1", "TEMP-BREAK-2", "TEMP-BREAK-3", "TEMP-WORK-5", "TEMP-MASK-1", "TEMP-MASK-3")
@pytest.mark.parametrize("point", BREAK_POINTS)
def test_a_sensor_broken_masked_unmasked_and_repaired(bench, temp, breaker, point, measure):
    """One sensor through the manual's states, each checked as the PLC shows it: open → 28767 with only its
    break bit (TW+1 for 0–15, TW+2 for 16–31); masked off in R4010/R4011 → 0 and no break bit; then restoring the
    bit brings back 28767 when the sensor is still broken (and the live reading once it is repaired), or — at the
    other end of each half — the live reading when it was repaired while masked.

    One test walks them all because each state shows only at the point's next update (up to the module's update
    time, 6 s on a 16TC at 0.1 °): separate tests would each pay for the way in and the way back out."""
    role = point
    point = _point(temp, role)
    _ensure_installed(bench, point)
    temp.wait_until(lambda: temp.reading(point) not in (0, BREAK))
    before = temp.reading(point)

    breaker.open(point)
    temp.wait_until(lambda: temp.reading(point) == BREAK)
    bench.settle()
    readings = temp.readings()
    assert readings[point] == 28767, f"broken point {point} reads {readings[point]}, expected 28767"
    others = [p for p, v in enumerate(readings) if v == 28767 and p != point]
    assert not others, f"points {others} read 28767 though only point {point} is broken"
    tw1, tw2 = temp.read_work().break_words
    want1, want2 = _expected_break_words(point)
    assert (tw1, tw2) == (want1, want2), (
        f"break bits TW+1={tw1:016b} TW+2={tw2:016b}; expected only point {point}: "
        f"TW+1={want1:016b} TW+2={want2:016b}")

    _set_mask_bit(bench, point, False)  # R4010 for 0–15, R4011 for 16–31
    temp.wait_until(lambda: temp.reading(point) == 0 and temp.read_work().break_words == (0, 0))
    assert temp.reading(point) == 0, f"point {point} masked off in {_mask_register(point)} must read 0"
    assert temp.read_work().break_words == (0, 0), f"masked point {point} must have no break bit"

    if role in UNMASKED_STILL_BROKEN:
        _set_mask_bit(bench, point, True)
        temp.wait_until(lambda: temp.reading(point) == BREAK)
        bench.settle()
        assert temp.reading(point) == 28767, f"point {point} unmasked, still broken: expected 28767"
        assert temp.read_work().break_words == _expected_break_words(point), f"point {point} unmasked: its bit again"
        breaker.repair(point)
        how = "repaired"
    else:
        breaker.repair(point)
        _set_mask_bit(bench, point, True)
        how = "repaired while masked, then unmasked"
    temp.wait_until(lambda: temp.reading(point) not in (0, BREAK) and temp.read_work().break_words == (0, 0))
    bench.settle()
    after = temp.reading(point)
    assert after != 28767, f"point {point} {how} but still reads 28767"
    # The same sensor some seconds later: within the module accuracy ±(1 % + 1 °C), doubled for drift.
    tolerance = 2 * (abs(before) / 100 + 10) + 10
    measure(f"point{point}_repair_change", abs(after - before) / 10, unit=f"°{temp.config.unit}", low=0,
            high=tolerance / 10, note=f"read {before / 10} before the break, {after / 10} after: {how}")
    assert abs(after - before) <= tolerance, f"point {point} read {before} before the break, {after} after: {how}"
    assert temp.read_work().break_words == (0, 0), f"point {point} {how} but its break bit is still set"
