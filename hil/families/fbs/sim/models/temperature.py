"""FBs temperature modules in the emulator (manual ch. 20.1–20.4; spec/fbs-temperature.md).

What the model does every scan, as the FBs OS does:

* reads the temperature table at SR (the profile's ``table``); without A556H at SR+0 nothing is measured;
* checks it (module count 1–8 else FEH, at most 32 points else FFH), compares each table module with the module
  actually fitted (``fitted``; mismatch → bit k of TW+0's low byte, its points are not measured);
* measures the fitted modules' points one at a time (the modules multiplex), each module going round all its
  points once per update time; each measurement reads the point's installed bit (R4010/R4011) then writes its
  reading and its break bit (TW+1/TW+2);
* writes the execution code 56H once every point has been measured once.

In bench timing (hil.sim.timing) the model publishes as late as the manual allows: each module refreshes all its
points' readings and break bits at once, once per update time, at a seeded phase of its own; the table is read
once per cycle (the longest update time of the fitted modules), at a seeded phase, so a rewrite takes effect at
the next cycle and the work block (execution code, mismatch and break bits) changes only at those times.  The
same code measures and reports in both modes; only the schedule differs.

Each point's true temperature comes from a *source* (models/sensor_inputs.py: the simulated world, with the
faults a rig injects on a sensor).

The decisions a broken PLC could get wrong are small methods (``installed``, ``point_result``,
``break_position``, ``execution_code``) so the harness's tests can build broken variants as tiny subclasses.
Measurements are taken in batches — every measurement due at a scan at once, as arrays over (time, point)
columns (:meth:`TemperatureModel.take`) — so ``installed`` and ``point_result`` take and return arrays.
On a real PLC the ladder/WinProladder writes the table; here :meth:`power_on` plays that part.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from hil.families.fbs import registers as reg
from hil.families.fbs.address import Address

# (the simulated world the sensors see: no manual statement, so not here; the sources are re-exported for the
# profile builder and the tests)
from hil.families.fbs.sim.models.sensor_inputs import Fixed, Ramp, Source, source_from_spec
from hil.families.fbs.sim.models.temperature_readings import Readings
from hil.families.fbs.temperature import (
    BREAK_VALUE,
    EXEC_BAD_MODULE_COUNT,
    EXEC_IDLE,
    EXEC_MEASURING,
    EXEC_TOO_MANY_POINTS,
    MAX_MODULES,
    MAX_POINTS,
    MODULE_BY_CODE,
    TABLE_MARKER,
    ModuleType,
    TemperatureConfig,
    decode_start,
)
from hil.sim.columns import last_of_each
from hil.sim.model import Model
from hil.sim.timing import INSTANT, Timing

if TYPE_CHECKING:
    from hil.families.fbs.sim.memory import Memory
    from hil.families.fbs.sim.plc import Emulator


_MASK_LOW = int(reg.INSTALLED_LOW[1:])  # R4010


class TemperatureModel(Readings, Model["Emulator"]):
    name = "temperature"

    def __init__(self, config: TemperatureConfig, *, fitted: Sequence[ModuleType] | None = None,
                 write_table: bool = True, timing: Timing = INSTANT) -> None:
        self.config = config
        self.phases = timing
        #: bench timing: the table's words as read at the last table cycle (before the first: none), and when the
        #: next cycle reads it again
        self._table_read: list[int] = [0]
        self._table_due = 0.0
        #: The modules physically plugged in, in expansion order (default: those the profile names).
        self.fitted: list[ModuleType] = list(fitted if fitted is not None else (m.type for m in config.modules))
        self.write_table = write_table
        self.init_readings(config)
        self.state = "idle"
        self._measured: set[int] = set()
        self._next: list[float] = [0.0] * len(self.fitted)  # virtual time of each fitted module's next point
        #: the fitted modules the table had measured at the last full scan (a mismatched or unlisted module's
        #: schedule stands still: it must not look due)
        self._active: tuple[int, ...] = tuple(range(len(self.fitted)))
        self._mux: list[int] = [0] * len(self.fitted)  # the point (within the module) measured next
        self._breaks = 0  # 32 break bits as the model last wrote them
        self._break_key: int | None = None  # _breaks for which _break_value was computed
        self._break_value = (0, 0)
        self._plan_cache: dict[tuple, tuple] = {}
        #: the last scan's result while nothing can change it: (table words, next measurement due, bank, first
        #: index, block) — a scan with the same table before that time only rewrites the block (see scan)
        self._quiet: tuple | None = None
        self._installed: tuple = (None, None)  # (R4010/R4011, every point's installed bit)

    # -- the seams broken variants override (arrays over measurements) ----------------------------------------------
    def installed(self, mem: Memory, point: np.ndarray) -> np.ndarray:
        """Points' bits in R4010 (points 0–15) or R4011 (16–31)."""
        mask = np.array(mem.words["R"][_MASK_LOW:_MASK_LOW + 2])
        return (mask[point // 16] >> (point % 16) & 1).astype(bool)

    def point_result(self, point: np.ndarray, installed: np.ndarray, broken: np.ndarray,
                     live: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(reading, break bit) of each measurement."""
        return np.where(installed, np.where(broken, BREAK_VALUE, live), 0), installed & broken

    def break_position(self, point: int) -> tuple[int, int]:
        """(offset from TW, bit) of the point's break bit."""
        return 1 + point // 16, point % 16

    def execution_code(self, state: str, all_measured: bool) -> int:
        if state == "bad_module_count":
            return EXEC_BAD_MODULE_COUNT
        if state == "too_many_points":
            return EXEC_TOO_MANY_POINTS
        if state == "measuring" and all_measured:
            return EXEC_MEASURING
        return EXEC_IDLE

    # -- the engine ---------------------------------------------------------------------------------------------
    def power_on(self, emu: Emulator) -> None:
        if self.write_table:
            emu.memory.write(self.config.table, self.config.table_words())
        self._quiet = None
        for k, module in enumerate(self.fitted):
            first = self.phases.phase(f"temperature:module{k}", self._cycle(module)) if self.phases.bench else 0.0
            self._next[k] = emu.now + (first or self._step(module))
        # bench timing: the table the power-on left is read at once (the OS starts from it), a rewrite at the next
        # table cycle, the first of which comes at a seeded phase
        self._table_due = emu.now
        self._table_in_effect(emu.now, emu.memory)
        self._table_due = emu.now + self.phases.phase("temperature:table", self._table_cycle())

    def next_event(self, now: float) -> float:
        # Measurements are caught up at the next scan, each at its scheduled time (see _measure_module), so a
        # time jump loses nothing and the model never needs a scan of its own between requests — unless the table
        # may change between them (bench timing: at a table cycle), when measurements due before the cycle must be
        # taken under the table before it, as scanning every scan would
        if not self.phases.bench:
            return math.inf
        return min(self._table_due, self.next_measurement())

    def next_measurement(self) -> float:
        """Virtual time of the next scheduled measurement of any point (a PID acting on PV may need a scan then)."""
        return min((self._next[k] for k in self._active), default=math.inf)

    def _step(self, module: ModuleType) -> float:
        """The time between two measurements of the module: one point after the other, round its points once per
        update time (bench timing: all its points at once, once per update time)."""
        return self._cycle(module) / (1 if self.phases.bench else module.points)

    def _cycle(self, module: ModuleType) -> float:
        return module.update_s[self.config.rate]

    def _table_cycle(self) -> float:
        """Bench timing: how often the table is read — the longest update time of the fitted modules ([our
        choice] 1 s with none fitted)."""
        return max((self._cycle(m) for m in self.fitted), default=1.0)

    def _table_in_effect(self, now: float, mem: Memory) -> list[int]:
        """Bench timing: the table's words as the last table cycle at or before ``now`` read them."""
        if now + 1e-9 >= self._table_due:
            cycle = self._table_cycle()
            self._table_due += (math.floor((now + 1e-9 - self._table_due) / cycle) + 1) * cycle
            words, sr = mem.words[self.config.table.kind], self.config.table.index
            self._table_read = list(words[sr:sr + 4 + min(words[sr + 1], MAX_MODULES)])
        return self._table_read

    def _plan(self, codes: list[int], table_modules: list, readings_word: int) -> tuple:
        """(mismatch bits, points expected, TW entries with the mux words 0, [(k, first point, code)] measured),
        cached on the table and the fitted modules."""
        key = (tuple(codes), readings_word, tuple(id(m) for m in self.fitted))
        plan = self._plan_cache.get(key)
        if plan is None:
            mismatch, expected, entries, measured = 0, set[int](), list[int](), list[tuple[int, int, int]]()
            first = 0
            for k, (code, tm) in enumerate(zip(codes, table_modules)):
                points = tm.points if tm else 0
                matches = tm is not None and k < len(self.fitted) and self.fitted[k] is tm
                if not matches:
                    mismatch |= 1 << k
                else:
                    expected.update(range(first, first + points))
                    measured.append((k, first, code))
                entries += [(code & 0xFF00) | (8 * k & 0xFF), points << 8 | k, (readings_word + first) & 0xFFFF, 0]
                first += points
            if len(self._plan_cache) > 64:
                self._plan_cache.clear()
            plan = self._plan_cache[key] = (mismatch, frozenset(expected), tuple(entries), tuple(measured))
        return plan

    def scan(self, emu: Emulator) -> None:
        """One scan of the OS's temperature routine: read the table, check it, take the measurements due, write
        the work block (execution code, mismatch and break bits, the module entries)."""
        if self._still_quiet(emu.now):
            return
        mem = emu.memory
        words, sr = self._table_words(emu.now, mem)
        self._active = ()
        if words[sr] != TABLE_MARKER:  # without A556H at SR+0 nothing is measured
            self.state = "idle"
            return
        count = words[sr + 1]
        header = tuple(words[sr:sr + 4 + min(count, MAX_MODULES)])
        self._quiet = None
        state, readings, work, codes, table_modules, total = table_layout(header)
        if work is None:  # nowhere to report anything
            self.state = "idle"
            return
        self.state = state
        measuring = self.state == "measuring" and readings is not None
        mismatch, expected, entries = 0, frozenset[int](), list[int]()
        if measuring:
            mismatch, expected, entries = self._measure_table(emu, codes, table_modules, words[sr + 2], readings)
        all_measured = bool(expected) and expected <= self._measured
        head = self.execution_code(self.state, all_measured) << 8 | mismatch
        low, high = self._break_words()
        block = [head, low, high, (total if self.state != "bad_module_count" else 0) << 8 | count & 0xFF]
        self._write_work(mem, work, block + entries, (list(header), words, sr) if measuring else None)

    def _still_quiet(self, now: float) -> bool:
        """Same table, no measurement due since the last scan: the model's state (mux, breaks, measured points)
        cannot have changed, so neither has the work block — rewritten as it was (the host may have scribbled
        over it).  False (nothing done) when anything may have changed, or in bench timing (the table read may
        change any scan)."""
        quiet = None if self.phases.bench else self._quiet
        if quiet is None:
            return False
        header, due, bank, first, block, words, sr = quiet
        # (the table's words equal to the recorded header, marker and count included — equal count, equal
        # length — is the same test as the full path's header comparison)
        if now + 1e-9 >= due or words[sr:sr + len(header)] != header:
            return False
        bank[first:first + len(block)] = block
        return True

    def _table_words(self, now: float, mem: Memory) -> tuple[Sequence[int], int]:
        """The bank the table is read from and SR's index in it: the memory (instant timing), or the words the
        last table cycle read (bench timing)."""
        if self.phases.bench:
            return self._table_in_effect(now, mem), 0
        return mem.words[self.config.table.kind], self.config.table.index

    def _measure_table(self, emu: Emulator, codes: list[int], table_modules: list, readings_word: int,
                       readings: Address) -> tuple[int, frozenset[int], list[int]]:
        """A valid table's scan: the measurements due of the modules that match it, taken.  Returns its mismatch
        bits, the points it expects measured and the work block's module entries (each module's multiplexer
        index as it now is)."""
        mismatch, expected, entries, measured = self._plan(codes, table_modules, readings_word)
        self._active = tuple(k for k, _first, _code in measured)
        now = emu.now
        due = [(k, first, code >> 8) for k, first, code in measured if self._next[k] <= now + 1e-9]
        if due:
            self._measure(emu, due, readings)
        entries = list(entries)
        for k in range(min(len(codes), len(self._mux))):
            entries[4 * k + 3] = self._mux[k]
        return mismatch, expected, entries

    def _write_work(self, mem: Memory, work: Address, block: list[int], table: tuple | None) -> None:
        """The work block at TW; while a valid table (``table``: its header, bank and SR) is measured, recorded for
        :meth:`_still_quiet` until the next measurement is due."""
        bank = mem.words.get(work.kind)
        if bank is None:
            mem.write(work, block)
            return
        block = [v & 0xFFFF for v in block]
        bank[work.index:work.index + len(block)] = block
        if table is not None:
            header, words, sr = table
            due = min((self._next[k] for k in self._active), default=math.inf)
            self._quiet = (header, due, bank, work.index, block, words, sr)

    def _break_words(self) -> tuple[int, int]:
        """TW+1 and TW+2 from the break bits, each placed where :meth:`break_position` says."""
        if self._breaks == self._break_key:
            return self._break_value
        self._break_key, self._break_value = self._breaks, self._compute_break_words()
        return self._break_value

    def _compute_break_words(self) -> tuple[int, int]:
        words = {1: 0, 2: 0}
        for point in range(MAX_POINTS):
            if self._breaks >> point & 1:
                offset, bit = self.break_position(point)
                words[offset] = words.get(offset, 0) | 1 << bit
        return words[1] & 0xFFFF, words[2] & 0xFFFF

    def measure_module(self, now: float, k: int, first: int) -> tuple[np.ndarray, np.ndarray]:
        """(times, points) of module k's measurements due by ``now``, its schedule moved past them."""
        module = self.fitted[k]
        step = self._step(module)
        self._next[k] = resume_after_jump(self._next[k], now, self._cycle(module), self.config.averaging)
        times, self._next[k] = schedule(self._next[k], step, now + 1e-9)
        if self.phases.bench:  # every point of the module at each cycle (the multiplexer ends where it began)
            times = np.repeat(times, module.points)
        points = first + (self._mux[k] + np.arange(len(times))) % module.points
        self._mux[k] = (self._mux[k] + len(times)) % module.points
        return times, points

    def _measure(self, emu: Emulator, due: list[tuple[int, int, int]], readings: Address) -> None:
        """The measurements of modules ``due`` [(k, first point, sensor code)] up to now, in one batch."""
        batches = [(*self.measure_module(emu.now, k, first), code) for k, first, code in due]
        if len(batches) == 1:
            times, points, code = batches[0]
            codes = np.full(len(times), code)
        else:
            times = np.concatenate([b[0] for b in batches])
            points = np.concatenate([b[1] for b in batches])
            codes = np.concatenate([np.full(len(b[0]), b[2]) for b in batches])
        words, last = self.take(emu.memory, times, points, codes)
        out, base = emu.memory.words[readings.kind], readings.index
        for point, word in zip(points[last].tolist(), words[last].tolist()):
            out[base + point] = word

    def take(self, mem: Memory, times: np.ndarray, points: np.ndarray,
             codes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Measure ``points`` at ``times`` (each point's in time order) with the sensors of ``codes``: the reading
        words, the samples, break bits and measured points updated as one measurement after the other would.
        Returns the words and the index of each point's last measurement."""
        cls = type(self)
        # every point's installed bit, kept for these R4010/R4011 (a variant's seam may read more than them)
        if cls.installed is TemperatureModel.installed:
            mask = mem.words["R"][_MASK_LOW:_MASK_LOW + 2]
            if self._installed[0] != mask:
                self._installed = (mask, np.asarray(self.installed(mem, np.arange(MAX_POINTS)), dtype=bool))
            installed = self._installed[1][points]
        else:
            installed = np.asarray(self.installed(mem, points), dtype=bool)
        last = last_of_each(points)
        if not self.broken and np.count_nonzero(installed) == len(points):
            broken = good = None  # (every one good)
            live = self._live(times, points, codes, last)
        else:
            broken = np.isin(points, list(self.broken))
            good = installed & ~broken
            live = np.zeros(len(points))
            if np.count_nonzero(good):
                live[good] = self._live(times[good], points[good], codes[good])
            self.forget(points[~good])  # (a point is good or not for all its measurements of one scan)
        # (point_result of good measurements: the live readings, no break bit)
        if good is None and cls.point_result is TemperatureModel.point_result:
            reading, flagged = live, np.zeros(len(points), dtype=bool)
        else:
            if broken is None:
                broken = np.zeros(len(points), dtype=bool)
            reading, flagged = self.point_result(points, installed, broken, live)
            reading, flagged = np.asarray(reading), np.asarray(flagged, dtype=bool)
            if flagged.shape != points.shape:
                flagged = np.full(points.shape, bool(flagged))
        self._record_results(points[last].tolist(), flagged[last].tolist())
        words = (np.full(points.shape, reading) if reading.shape != points.shape else reading).astype(np.int64)
        return words & 0xFFFF, last

    def _record_results(self, points: Sequence[int], flagged: Sequence[bool]) -> None:
        """Break bits and measured points after the last measurement of each of ``points`` (``flagged``: its break
        bit)."""
        breaks = self._breaks
        for point, flag in zip(points, flagged):
            breaks = reg.with_bit(breaks, point, flag)
        self._breaks = breaks
        self._measured.update(points)

@functools.lru_cache(maxsize=64)
def table_layout(header: tuple[int, ...]) -> tuple:
    """The table's words decoded and checked (state, readings, work, codes, modules, total points): module count
    1–8 (else "bad_module_count": FEH), at most 32 points (else "too_many_points": FFH).  Cached on the words:
    the OS reads the table every scan, a ladder rewrites it seldom."""
    count = header[1]
    readings, work = decode_start(header[2]), decode_start(header[3])
    codes = list(header[4:])
    table_modules = [MODULE_BY_CODE.get(c & 0xFF) for c in codes]
    total = sum(m.points for m in table_modules if m)
    if count == 0 or count > MAX_MODULES:
        state = "bad_module_count"
    elif total > MAX_POINTS:
        state = "too_many_points"
    else:
        state = "measuring"
    return state, readings, work, codes, table_modules, total


def resume_after_jump(next_due: float, now: float, cycle: float, averaging: int) -> float:
    """Where a module's measurements resume when a scan catches up a long jump: a reading shows only the last
    ``averaging`` cycles' samples and each measurement rewrites its point's reading and break bit, so the whole
    cycles before the last ``averaging`` + 1 are not measured (the multiplexer ends each cycle where it began, so
    the schedule is unchanged).  Without it a virtual day of the default bench measures every point ≈ 14,000 times
    in one scan, and the in-process suites take 2–4 s longer."""
    keep = (averaging + 1) * cycle
    if now - next_due > keep:
        next_due += math.floor((now - next_due - keep) / cycle) * cycle
    return next_due


def schedule(at: float, step: float, limit: float) -> tuple[np.ndarray, float]:
    """The times at, at + step, … up to ``limit`` (each one step after the one before, added as a running clock
    adds them), and the first one after it."""
    if at > limit:
        return np.empty(0), at
    count = int((limit - at) / step) + 2
    if count <= 8:  # (a few: added in Python, the same additions without numpy's overhead)
        few = [at]
        while at + step <= limit:
            at += step
            few.append(at)
        return np.array(few), at + step
    times = np.add.accumulate(np.concatenate(([at], np.full(count, step))))
    n = int(np.searchsorted(times, limit, side="right"))
    return times[:n], float(times[n])


__all__ = ["Fixed", "Ramp", "Source", "TemperatureModel", "resume_after_jump", "schedule", "source_from_spec",
           "table_layout"]
