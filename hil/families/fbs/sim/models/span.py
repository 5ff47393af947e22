"""Request-free stretches of the temperature modules, FUN86 and the thermal plant, run in batches.

Between two requests nothing outside the models touches memory.  When the only scans the engine would run there are
FUN86's PID steps — the plant integrating the PWM between them (no dead time), no reading able to reach the
pre-alarm limit, no heater-loop deadline due, no other model needing a scan — :class:`Span` runs those scans
together, the state of every point in arrays:

1. the scans' times are planned on the engine's clock (the PID steps, landed as the engine lands them);
2. block after block of scans: the block's measurements are scheduled at once (the temperature model's schedule)
   and whatever does not depend on the loop's state — their noise, the decays, the PWM cycles' starts — is computed
   for all of them; then scan after scan only what does: the plant through the last interval's waveforms (its closed
   form for every measurement and every point's anchor, :func:`~hil.families.fbs.sim.models.plant_solution.cycles_temperature`),
   the readings (the temperature model's ``in_unit``, ``average``, ``resolution``), the PID step of the instances
   due (:meth:`Fun86Model.control`) and the new waveforms; then the rest of the block at once: the readings
   replayed for the heater-loop timer, each scan's normal and warning words and ALM (:meth:`Fun86Model.track`,
   ``in_band``, ``bit_words``, ``alarm``);
3. at the end, what the last scan left: outputs, readings and samples, the plant's anchors where its waveforms last
   changed.  A heater-loop deadline the engine would have scanned at between two of the scans shows in a block's
   alarms: the batch is planned again, up to it.

(Blocks keep the arrays small: memory reused from block to block rather than fresh for every batch, which costs a
page fault every 4 KiB.)

These are the functions the models' own scans call, on more rows at once; scan observers (``Engine.observers``)
still see every scan's outputs.  Anything else — a broken variant's overridden seam, dead time, a reading that could
reach R4008, memory the models share with one another or with another model — leaves the scans to the engine.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from hil.families.fbs import registers as reg
from hil.families.fbs.address import Address
from hil.families.fbs.pid import OUTPUT_FULL, PidInstance
from hil.families.fbs.address import parse
from hil.families.fbs.sim.models.fun86 import Fun86Model, InstanceState, Law
from hil.families.fbs.sim.models.plant import ThermalPlant
from hil.families.fbs.sim.models.plant_solution import cycle_terms, cycles_temperature
from hil.families.fbs.sim.models.temperature import SENSOR_HIGH, SENSOR_LOW, MeasuringTable, TemperatureModel
from hil.families.fbs.temperature import MAX_POINTS
from hil.sim.columns import last_of_each, signed16
from hil.sim.model import scan_grid, seen_at_skipped_scans

if TYPE_CHECKING:
    from hil.sim.engine import Engine
    from hil.families.fbs.sim.memory import Memory

_INDEX = {name: parse(name).index for name in (reg.PREALARM_LIMIT, reg.HEATER_LOOP_SECONDS, reg.PID_SOURCE_KEY,
                                                reg.INSTALLED_LOW, reg.PID_ENABLE_HIGH)}

#: scans per batch at most (the batch's arrays are scans × columns)
CHUNK = 2048
#: scans whose plant columns (scans × cycles × columns) are made at once: few enough for arrays that fit in
#: reused memory (fresh memory for each batch costs a page fault per 4 KiB)
BLOCK = 256



@dataclass
class _Loop:
    """A running FUN86 instance, as constant as it is between requests."""

    inst: PidInstance
    st: InstanceState
    enabled: np.ndarray  # per point b
    idx: np.ndarray  # the enabled b
    off: np.ndarray  # the disabled b
    points: np.ndarray  # Sn + b
    law: Law  # of the enabled points
    sv: np.ndarray
    os: np.ndarray
    output: np.ndarray  # OR (per b), as before the batch (until it is committed)
    driven: np.ndarray  # the b whose output heats a plant slot …
    slots: np.ndarray  # … and those slots
    y_on: np.ndarray  # per b
    y_off: np.ndarray
    lit: np.ndarray  # the heater of each slot with its output on …
    dark: np.ndarray  # … and off (the plant's faults)


@dataclass
class _Ready:
    """What a batch needs, as it holds between two requests (:meth:`Span._ready`)."""

    tm: TemperatureModel
    plant: ThermalPlant
    table: MeasuringTable
    loops: list[_Loop]
    limit: int  # R4008
    loop_seconds: int  # R4007
    high_at: float  # the output (of OUTPUT_FULL) from which a heater-loop timer runs: R4006


@dataclass
class _Measured:
    """A block's measurements (:meth:`_Batch._measurements`): per measurement, in the order the scans take them."""

    times: np.ndarray
    points: np.ndarray
    codes: np.ndarray  # its sensor's code
    scan: np.ndarray  # the block's scan it lands in …
    col: np.ndarray  # … its column in that scan's row
    rank: np.ndarray  # the how-many-th reading of its point at that scan
    per_scan: np.ndarray  # measurements per scan
    width: int  # the widest scan's
    cell: np.ndarray  # scans × width: the measurement in each cell (−1: none)
    slot: np.ndarray  # the plant slot heating its point (−1: none)
    good: np.ndarray  # installed and not broken
    heated: np.ndarray
    bad_reading: np.ndarray | None = None  # (only when some are not good) what those read …
    bad_flag: np.ndarray | None = None  # … and their break bits
    pre: np.ndarray | None = None  # (only when some good points have sources of their own) their values

    def rows(self, flat: np.ndarray, fill: Any) -> np.ndarray:  # noqa: ANN401
        """A value per measurement as the block's rows (``fill`` where a scan has fewer)."""
        return np.where(self.cell >= 0, flat[self.cell], fill)


@dataclass
class _Columns:
    """The plant's columns of a block's scans (:meth:`_Batch._columns`): what of their solution does not depend on
    the loop, scans × cycles × columns."""

    c_slot: np.ndarray  # each column's slot
    raw: np.ndarray  # each cycle's start, off the scan grid
    s3: np.ndarray
    t3: np.ndarray  # each column's time
    r3: np.ndarray  # each column's rate
    c_lift: np.ndarray
    decay: np.ndarray
    base: np.ndarray


@dataclass
class _Stepped:
    """What the scans of a block computed (:meth:`_Batch._steps`)."""

    values: np.ndarray  # scans × width: each measurement's value
    temps_at: np.ndarray  # scans × slots: T of each slot at each scan
    outputs_at: list[np.ndarray]  # per instance, scans × points: OR
    updates: np.ndarray  # scans × points: the column of each point's last reading at the scan (−1: none)
    readings: np.ndarray  # scans × width: each measurement's reading word


@dataclass
class _Seen:
    """A block's readings as the scans' PVs saw them (:meth:`_Batch._readings`)."""

    flat: np.ndarray  # per measurement, its reading
    pv_at: np.ndarray  # scans × points: each point's PV register at each scan


class _Step:
    """A running instance's PID state through a batch (its points' arrays: the enabled ones)."""

    def __init__(self, loop: _Loop, n_pv: int, n_slots: int) -> None:
        st, idx = loop.st, loop.idx
        self.at = loop.points[idx]
        self.every_pv = len(self.at) == n_pv and bool((self.at == np.arange(n_pv)).all())  # PVs: all, in order
        self.every_point = len(loop.off) == 0
        self.every_slot = (self.every_point and len(loop.slots) == n_slots
                           and bool((loop.slots == np.arange(n_slots)).all())
                           and bool((loop.driven == np.arange(st.zn)).all()))
        self.integral, self.prev = st.integral[idx], st.pv_prev[idx]
        self.has: np.ndarray | bool = True if st.has_prev[idx].all() else st.has_prev[idx]
        self.sv = loop.sv[idx].astype(float)  # (as the PVs: one type, no cast at each step)
        self.output = loop.output.astype(float)


class Span:
    """Runs a FUN86 model's scans in batches (see the module docstring): its :attr:`Fun86Model.batcher`."""

    def __init__(self) -> None:
        self.fun86: Fun86Model | None = None
        self._shared_key: object = None
        self._shared = True

    def run(self, fun86: Fun86Model, engine: "Engine", target: float) -> bool:
        self.fun86 = fun86
        ready = self._ready(engine)
        if ready is None:
            return False
        bound = math.inf
        saved = self._save(engine, ready)
        while True:
            start = engine.now
            times, due = self._plan(engine, target, ready.loops, bound)
            if not times:
                return False
            batch = _Batch(self.fun86, engine, ready, np.array([start, *times]), due)
            deadline = batch.run()
            if deadline is None:
                batch.commit()
                return True
            # a heater-loop deadline the engine would have scanned at, inside: again, up to it
            self._restore(engine, ready, saved)
            bound = deadline

    # -- what may be batched ---------------------------------------------------------------------------------
    def _ready(self, engine: "Engine") -> _Ready | None:
        """Everything a batch needs, or None when the coming scans are not FUN86's PID steps alone."""
        fun86 = self.fun86
        tm = fun86.temperature_model
        if not fun86.batchable or not fun86.pwm_exact or tm is None or not tm.batchable or tm.log is None:
            return None
        states = fun86.states
        if any(st.waiting for st in states) or not any(st.running for st in states):
            return None
        models = engine.models
        plant = next((m for m in models if isinstance(m, ThermalPlant) and m.batchable), None)
        if plant is None or not plant.waved or plant.driver is not fun86:
            return None
        at = [next((i for i, m in enumerate(models) if m is model), -1) for model in (tm, fun86, plant)]
        if not 0 <= at[0] < at[1] < at[2]:
            return None
        now = engine.now
        others = [m for m in models if m is not tm and m is not fun86 and m is not plant]
        if any(m.next_event(now) != math.inf for m in others):
            return None
        mem = engine.memory
        table = tm.measuring_table(mem)
        if table is None:
            return None
        start = fun86.readings_start(mem)
        if start is None or (start.kind, start.index) != (table.readings.kind, table.readings.index):
            return None
        if not self._unshared(engine, mem, table, others):
            return None
        words = mem.words
        r = words["R"]
        limit, loop_seconds = r[_INDEX[reg.PREALARM_LIMIT]], r[_INDEX[reg.HEATER_LOOP_SECONDS]]
        loops = []
        for inst, st in zip(fun86.config.instances, states):
            if not st.running:
                continue
            if (st.interval <= 2 * engine.scan_time or fun86.prealarm_possible(mem, st)
                    or fun86.counting(st)):
                return None
            b = np.arange(st.zn)
            points = st.sn + b
            enabled = np.asarray(fun86.enabled(mem, points), dtype=bool)
            pv = signed16(words[start.kind][start.index + st.sn:start.index + st.sn + st.zn])
            if (pv[enabled] >= limit).any():  # (readings cannot reach R4008: PVs now could)
                return None
            loops.append(self._loop(mem, inst, st, enabled, plant))
        # the next scan is a PID step's (not a heater-loop deadline's: those later are checked after the batch)
        if fun86.next_event(now) < fun86.scan_for(min(loop.st.next_pid for loop in loops), now):
            return None
        return _Ready(tm, plant, table, loops, limit, loop_seconds, fun86.loop_threshold(mem) * OUTPUT_FULL)

    def _loop(self, mem: "Memory", inst: PidInstance, st: InstanceState, enabled: np.ndarray,
              plant: ThermalPlant) -> _Loop:
        words = mem.words
        zn = st.zn
        idx, off = np.flatnonzero(enabled), np.flatnonzero(~enabled)
        gains = [np.array(words[a.kind][a.index:a.index + zn], dtype=np.int64)[idx] for a in (inst.pr, inst.ir, inst.dr)]
        heating = bool(mem.bits[inst.hc.kind][inst.hc.index])
        heaters = {(a.kind, a.index): plant.slot[p] for p, a in plant.heaters.items()}
        driven = [(b, heaters[(inst.yn.kind, inst.yn.index + b)]) for b in range(zn)
                  if (inst.yn.kind, inst.yn.index + b) in heaters]
        _on, y_on, y_off = self.fun86.waves(st, enabled, np.zeros(zn))
        heater = plant.order
        lit = np.array([plant.power(heater[s], bool(y_on[b])) for b, s in driven], dtype=np.int64)
        dark = np.array([plant.power(heater[s], bool(y_off[b])) for b, s in driven], dtype=np.int64)
        return _Loop(inst, st, enabled, idx, off, st.sn + np.arange(zn), self.fun86.law(inst, *gains, heating, st.interval),
                     signed16(words[inst.sv.kind][inst.sv.index:inst.sv.index + zn]),
                     signed16(words[inst.os.kind][inst.os.index:inst.os.index + zn]),
                     np.array(words[inst.or_.kind][inst.or_.index:inst.or_.index + zn], dtype=np.int64),
                     np.array([d[0] for d in driven], dtype=np.intp), np.array([d[1] for d in driven], dtype=np.intp),
                     np.array(y_on), np.array(y_off), lit, dark)

    def _unshared(self, engine: "Engine", mem: "Memory", table: MeasuringTable, others: list) -> bool:
        """No element the batch writes is read or written by anything else between its scans: not by the
        models' reads (table, R4003–R4013, the instances' operands), not by another part of the batch, not by
        another model nor the scan counter.  (A scan would see such an element change between two others.)"""
        fun86 = self.fun86
        key = (id(mem), table.header, tuple((st.running, st.sn, st.zn) for st in fun86.states),
               tuple(id(m) for m in others), getattr(engine, "scan_counter", None))
        if key == self._shared_key:
            return self._shared
        self._shared_key, self._shared = key, False

        def run(a: Address, n: int) -> set[tuple[str, int]]:
            return {(a.kind, a.index + i) for i in range(n)}

        writes = [run(table.readings, table.total), run(table.work, 4 + 4 * table.count)]
        reads = run(fun86.temperature_model.config.table, len(table.header))
        reads |= {("R", i) for i in range(_INDEX[reg.PID_SOURCE_KEY], _INDEX[reg.PREALARM_LIMIT] + 1)}
        reads |= {("R", i) for i in range(_INDEX[reg.INSTALLED_LOW], _INDEX[reg.PID_ENABLE_HIGH] + 1)}
        for inst, st in zip(fun86.config.instances, fun86.states):
            reads |= run(inst.en, 1)
            if inst.settable:
                reads |= run(inst.sn_register, 1) | run(inst.zn_register, 1)
            mine = run(inst.err, 1) | run(inst.alm, 1) | run(inst.yn, st.zn)
            if st.running:
                mine |= run(inst.or_, st.zn) | run(inst.wr, 4)
                reads |= run(inst.hc, 1)
                for a in (inst.sv, inst.os, inst.pr, inst.ir, inst.dr):
                    reads |= run(a, st.zn)
            writes.append(mine)
        foreign: set[tuple[str, int]] = set()
        for model in others:
            footprint = model.footprint()
            if footprint is None:
                return False
            foreign |= footprint
        counter = getattr(engine, "scan_counter", None)
        if counter is not None:
            foreign |= run(counter, 1)
        seen: set[tuple[str, int]] = set()
        for part in writes:
            if part & seen:
                return False
            seen |= part
        self._shared = not (seen & (reads | foreign))
        return self._shared

    # -- the batch ----------------------------------------------------------------------------------------------
    def _plan(self, engine: "Engine", target: float, loops: list[_Loop], bound: float) -> tuple[list, list]:
        """Tick the engine's clock through the coming PID scans (each landed as the engine lands it), short of any
        heater-loop deadline (``bound``) and leaving the last scan before ``target`` to the engine; for each
        instance, whether its PID step is due at each."""
        fun86 = self.fun86
        times: list[float] = []
        due: list[list[bool]] = [[] for _ in loops]
        while len(times) < CHUNK:
            event = fun86.next_pid_scan(engine.now)
            landing = engine.landing(event, target)
            if landing >= bound or not engine.leaves_a_scan(landing, target):
                break
            engine.land(event, target)
            engine.tick()
            times.append(engine.now)
            for loop, flags in zip(loops, due):
                flags.append(fun86.pid_due(loop.st, engine.now))
        return times, due

    @staticmethod
    def _save(engine: "Engine", ready: _Ready) -> tuple:
        """What planning and computing a batch change before it is committed (to try a shorter one instead)."""
        return ((engine.now, engine.scans, engine.skipped_time), [(loop.st.next_pid, loop.st.loop_since.copy())
                                                                   for loop in ready.loops],
                ready.tm.schedule_state())

    @staticmethod
    def _restore(engine: "Engine", ready: _Ready, saved: tuple) -> None:
        clock, loops, temperature = saved
        engine.now, engine.scans, engine.skipped_time = clock
        for loop, (next_pid, loop_since) in zip(ready.loops, loops):
            loop.st.next_pid, loop.st.loop_since = next_pid, loop_since.copy()
        ready.tm.restore_schedule(temperature)


class _Batch:
    """A batch's scans, computed block after block of scans (see the module docstring), and what they leave."""

    def __init__(self, fun86: Fun86Model, engine: "Engine", ready: _Ready, scans: np.ndarray,
                 due: list[list[bool]]) -> None:
        self.fun86, self.engine, self.ready = fun86, engine, ready
        self.tm, self.plant, self.table, self.loops = ready.tm, ready.plant, ready.table, ready.loops
        self.scans, self.due = scans, due
        self.st_time = engine.scan_time
        self.n_scans = n_scans = len(scans) - 1
        mem, tm, plant = engine.memory, self.tm, self.plant
        # per point, what holds through the batch: the seams' verdicts, the source
        every = np.arange(MAX_POINTS)
        self.installed = np.asarray(tm.installed(mem, every), dtype=bool)
        self.broken = np.isin(every, list(tm.broken))
        self.slot_of = tm.plant_slots(plant)
        codes = np.array([code >> 8 for _k, _first, code in self.table.measured], dtype=np.intp)
        self.clamps = not self._within(SENSOR_LOW[codes], SENSOR_HIGH[codes])
        self.wraps = not (np.isfinite(SENSOR_LOW[codes]).all() and np.isfinite(SENSOR_HIGH[codes]).all())
        self._waves()
        bank, base = mem.words[self.table.readings.kind], self.table.readings.index
        self.pv_register = signed16(bank[base:base + min(MAX_POINTS, len(bank) - base)])  # (as the PVs read)
        # carried from block to block
        n_slots = len(plant.order)
        self.temps = plant.temperatures(np.arange(n_slots), np.full(n_slots, scans[0]))
        self.pv = self.pv_register.astype(float)
        self.runs = [_Step(loop, len(self.pv), n_slots) for loop in self.loops]
        self.outputs = [loop.output for loop in self.loops]  # each instance's OR at the scan before the block
        self.last_word = np.full(MAX_POINTS, -1, dtype=np.int64)  # each point's last reading in the batch …
        self.last_value = np.zeros(MAX_POINTS)  # … its value (the sample averaged) …
        self.last_flag = np.zeros(MAX_POINTS, dtype=bool)  # … and its break bit
        # each instance's per-scan words and ALM; each of its heated slots' waveform key and last change
        self.words = [np.zeros((n_scans, 4), dtype=np.int64) for _ in self.loops]
        self.alm = [np.zeros(n_scans, dtype=bool) for _ in self.loops]
        self.keys = [self._initial_key(loop) for loop in self.loops]
        self.changed = [np.full(len(loop.slots), -1) for loop in self.loops]  # scan index, −1: none
        self.changed_temp = [np.zeros(len(loop.slots)) for loop in self.loops]
        self.kept: list | None = [] if engine.observers else None  # (each scan's, for the observers)

    # -- what holds through the batch ---------------------------------------------------------------------------
    def _within(self, low: np.ndarray, high: np.ndarray) -> bool:
        """No measurement can leave its sensor's range (the plant's bounds within it): no clamping to do."""
        plant = self.plant
        if (self.slot_of[: self.table.total] < 0).any():
            return False
        top = max(plant.upper(s) for s in range(len(plant.order)))
        bottom = plant.lower()
        return bool(top <= high.min() and bottom >= low.max())

    def _waves(self) -> None:
        """Each plant slot's waveform through the batch: the instance driving its heater (or constant: the
        plant's wave as it is)."""
        plant = self.plant
        n_slots = len(plant.order)
        self.started, self.period = np.zeros(n_slots), np.full(n_slots, 1e9)
        u_on, u_off = plant.w_uoff.copy(), plant.w_uoff.copy()
        self.on = np.zeros(n_slots)
        for loop in self.loops:
            if len(loop.slots):
                self.started[loop.slots], self.period[loop.slots] = loop.st.started, loop.st.pwm
                u_on[loop.slots], u_off[loop.slots] = loop.lit, loop.dark
                self.on[loop.slots] = np.minimum(Fun86Model.on_times(loop.st, loop.output[loop.driven]), loop.st.pwm)
        every = np.arange(n_slots)
        self.t_off = plant.settles_at(every, u_off)
        self.lift = plant.settles_at(every, u_on) - self.t_off
        self.rate = 1.0 / plant.tau
        waves, self.wave_of = np.unique(np.stack((self.started, self.period)), axis=1, return_inverse=True)
        self.wave_started, self.wave_period = waves

    def _key(self, loop: _Loop, outputs: np.ndarray) -> tuple[np.ndarray, ...]:
        """The plant's waveform of each slot an instance heats, for its outputs (scans × points): a key equal
        for equal waveforms (ON seconds of a PWM, or −1 − u for a constant u), and (steady, level, ON seconds)."""
        on = self.fun86.on_times(loop.st, outputs[..., loop.driven])
        pulsed, level = ThermalPlant.classify(on, loop.st.pwm, loop.lit, loop.dark)
        steady = ~pulsed
        return np.where(steady, -1.0 - level, on), steady, level, on

    def _initial_key(self, loop: _Loop) -> np.ndarray:
        """The key of the slots' waveforms as the plant has them now."""
        plant, slots, st = self.plant, loop.slots, loop.st
        same = (plant.w_started[slots] == st.started) & (plant.w_period[slots] == st.pwm) & (
            plant.w_uon[slots] == loop.lit) & (plant.w_uoff[slots] == loop.dark)
        return np.where(plant.w_pwm[slots], np.where(same, plant.w_on[slots], math.nan), -1.0 - plant.w_uoff[slots])

    # -- block after block -----------------------------------------------------------------------------------------
    def run(self) -> float | None:
        """Compute the batch's scans; None, or the first heater-loop deadline the engine would have scanned at
        between two of them (the batch is then to be planned again, up to it)."""
        for b0 in range(0, self.n_scans, BLOCK):
            b1 = min(b0 + BLOCK, self.n_scans)
            measured = self._measurements(b0, b1)
            stepped = self._steps(measured, self._columns(measured, b0, b1), b0, b1)
            seen = self._readings(measured, stepped, b0, b1)
            deadline = self._alarms(measured, stepped, seen, b0, b1)
            if deadline is not None:
                return deadline
            self._anchors(stepped, b0, b1)
        return None

    def _measurements(self, b0: int, b1: int) -> _Measured:
        """The measurements of scans b0…b1 − 1: each module's in time order (its points in turn), module after
        module (as each scan takes them), each with its column in its scan's row; and what each needs but the
        plant."""
        tm, scans, n = self.tm, self.scans, b1 - b0
        parts = []
        filled = np.zeros(n, dtype=np.int64)  # columns placed in each scan's row so far
        ends = scans[b0 + 1:b1 + 1] + 1e-9
        for k, first, code in self.table.measured:
            t, p = tm.measure_module(float(scans[b1]), k, first)
            scan = np.searchsorted(ends, t, side="left")
            within = np.arange(len(t)) - np.searchsorted(scan, np.arange(n))[scan]
            parts.append((t, p, np.full(len(t), code >> 8), scan, filled[scan] + within,
                          within // tm.fitted[k].points))  # (the how-many-th reading of its point at that scan)
            filled += np.bincount(scan, minlength=n)
        times, points, codes, scan, col, rank = (np.concatenate(x) for x in zip(*parts))
        width = int(filled.max()) if len(times) else 0
        cell = np.full((n, width), -1, dtype=np.intp)
        cell[scan, col] = np.arange(len(times))
        slot = self.slot_of[points]
        good = self.installed[points] & ~self.broken[points]
        block = _Measured(times, points, codes, scan, col, rank, filled, width, cell, slot, good, slot >= 0)
        if not good.all():
            reading, flag = tm.point_result(points, self.installed[points], self.broken[points],
                                            np.zeros(len(points), dtype=np.int64))
            block.bad_reading = np.broadcast_to(np.asarray(reading, dtype=np.int64), points.shape)
            block.bad_flag = np.broadcast_to(np.asarray(flag, dtype=bool), points.shape)
        if not (block.heated | ~good).all():  # sources of their own: their values known beforehand
            other = good & ~block.heated
            block.pre = np.zeros(len(points))
            block.pre[other] = tm.values(times[other], points[other])
        return block

    def _columns(self, block: _Measured, b0: int, b1: int) -> _Columns:
        """The plant's columns of the block's scans — the measurements, then every slot at the scan — and what of
        their solution does not depend on the loop: the cycles of the PWM each scan's interval meets, the decays and
        the heater-off part (:func:`cycle_terms`)."""
        plant, st_time, width = self.plant, self.st_time, block.width
        scans = self.scans[b0:b1 + 1]
        n, n_slots = b1 - b0, len(plant.order)
        cell = block.cell
        a = scans[:-1, None]
        m_slot = block.rows(np.where(block.heated, block.slot, 0), 0)
        m_time = np.where(cell >= 0, block.times[cell], a)  # (padding: nothing elapsed)
        c_slot = np.hstack((m_slot, np.broadcast_to(np.arange(n_slots), (n, n_slots))))
        c_time = np.hstack((m_time, np.broadcast_to(scans[1:, None], (n, n_slots))))
        started, period = self.wave_started, self.wave_period  # (each distinct waveform's)

        def cycle(x: np.ndarray, before: bool) -> np.ndarray:
            """Per waveform, the cycle whose start (on the grid) is the last at or before x (``before``: before x)."""
            k = np.floor((x - started) / period)
            start, end = (scan_grid(started + j * period, st_time) for j in (k, k + 1))
            k = np.where(start >= x if before else start > x, k - 1, k)
            return np.where(end < x if before else end <= x, k + 1, k)

        # from the cycle each scan's interval starts in to the last starting before the scan: scans × cycles × slots
        first = cycle(a, False)
        n_cycles = max(1, int((cycle(scans[1:, None], True) - first).max()) + 1)
        raw = started + (first[:, None] + np.arange(n_cycles)[:, None]) * period  # scans × cycles × waveforms
        shape = (n, n_cycles, c_slot.shape[1])
        # each column's (with one waveform, every column's is its one), whole rows for the steps, which take a
        # scan's row at a time: numpy broadcasts an operand at a cost per operation several times a row's
        s3 = np.ascontiguousarray(np.broadcast_to(c_slot[:, None], shape))
        if len(started) > 1:
            raw = np.take_along_axis(raw[..., self.wave_of], s3, axis=2)
            starts = scan_grid(raw, st_time)
        else:
            starts = scan_grid(raw, st_time)
            raw = np.ascontiguousarray(np.broadcast_to(raw, shape))
        t3 = np.ascontiguousarray(np.broadcast_to(c_time[:, None], shape))
        r3 = np.ascontiguousarray(np.broadcast_to(self.rate[c_slot][:, None], shape))
        c_lift = self.lift[c_slot]
        decay, base = cycle_terms(a, t3.transpose(1, 0, 2), starts.transpose(1, 0, 2), self.t_off[c_slot], c_lift,
                                  r3.transpose(1, 0, 2))
        if plant.normals is not None:  # (a measurement is T plus its noise: here, the columns come out measured)
            heated = block.heated
            noise = plant.measurement_noise(np.where(heated, block.slot, 0), block.points, block.times)
            base[:, :width] += block.rows(np.where(heated, noise, 0.0), 0.0)
        return _Columns(c_slot, raw, s3, t3, r3, c_lift, decay, base)

    def _steps(self, block: _Measured, columns: _Columns, b0: int, b1: int) -> _Stepped:
        """Scan after scan: the plant through the last interval's waveforms, the readings, the PID steps due."""
        fun86, tm, loops, due, st_time = self.fun86, self.tm, self.loops, self.due, self.st_time
        n, width, n_slots = b1 - b0, block.width, len(self.plant.order)
        averaging = tm.config.averaging
        mixed, bad = block.pre is not None, block.bad_reading is not None
        plain = not (mixed or self.clamps or tm.config.unit != "C" or averaging > 1 or bad or self.wraps)
        solved = np.zeros((n, width + n_slots))  # each scan's plant columns: measured values, then T of each slot
        values, temps_at = solved[:, :width], solved[:, width:]
        readings = np.zeros((n, width)) if averaging > 1 or bad else None  # (else: from the values, afterwards)
        outputs_at = [np.zeros((n, loop.st.zn), dtype=np.int64) for loop in loops]
        runs = self.runs
        alone = len(runs) == 1 and runs[0].every_slot  # (then a PID step's on-times are the slots' whole)
        control, in_unit, resolution, on_times = fun86.control, tm.in_unit, tm.resolution, fun86.on_times
        # the column of each point's last reading at each scan (its PV register's new value; −1: none)
        updates = np.full((n, len(self.pv)), -1, dtype=np.intp)
        last = last_of_each(block.scan * 64 + block.points)
        updates[block.scan[last], block.points[last]] = block.col[last]
        whole = (updates >= 0).all(axis=1).tolist()  # every PV read anew at the scan
        if block.pre is not None:
            heated, pre = block.rows(block.heated | ~block.good, True), block.rows(block.pre, 0.0)
        if self.clamps:
            low, high = block.rows(SENSOR_LOW[block.codes], -math.inf), block.rows(SENSOR_HIGH[block.codes], math.inf)
        if block.bad_reading is not None:
            good, bad_reading = block.rows(block.good, True), block.rows(block.bad_reading, 0)
        if averaging > 1:
            cell_points = block.rows(block.points, 0)
        pv, temps, on = self.pv, self.temps, self.on
        starts = self.scans[b0:b1].tolist()
        c_slot, raw, s3, t3, r3, c_lift = columns.c_slot, columns.raw, columns.s3, columns.t3, columns.r3, columns.c_lift
        decay, base = columns.decay, columns.base
        for j in range(n):
            i = b0 + j
            slots = c_slot[j]
            offs = scan_grid(raw[j] + on[s3[j]], st_time)
            temp = cycles_temperature(temps[slots], starts[j], t3[j], offs, c_lift[j], r3[j], (decay[j], base[j]),
                                      out=solved[j])
            temps = temp[width:]
            value = temp[:width]
            if plain:
                reading = None
            else:
                if mixed:
                    value = np.where(heated[j], value, pre[j])
                value = values[j] = in_unit(value, *((low[j], high[j]) if self.clamps else (None, None)))
                if averaging > 1:
                    count = block.per_scan[j]
                    mean = value.copy()
                    mean[:count] = tm.average(cell_points[j, :count], value[:count])
                else:
                    mean = value
                reading = resolution(mean)
                if bad:
                    reading = np.where(good[j], reading, bad_reading[j])
                if readings is not None:
                    readings[j] = reading
            if whole[j]:
                pv = resolution(value[updates[j]]) if reading is None else reading[updates[j]]
            else:
                pv = pv.copy()
                fresh = updates[j] >= 0
                pv[fresh] = resolution(value[updates[j][fresh]]) if reading is None else reading[updates[j][fresh]]
            if self.wraps:
                pv = signed16(pv.astype(np.int64) & 0xFFFF).astype(float)
            for loop, flags, outs, run in zip(loops, due, outputs_at, runs):
                if flags[i]:
                    now_pv = pv if run.every_pv else pv[run.at]
                    out, run.integral = control(loop.law, run.integral, run.prev, run.has, run.sv, now_pv)
                    run.prev, run.has = now_pv, True
                    if run.every_point:
                        run.output = out
                    else:
                        run.output = run.output.copy()
                        run.output[loop.idx], run.output[loop.off] = out, 0
                    if alone:
                        on = on_times(loop.st, run.output)
                    elif len(loop.slots):
                        on = on.copy()
                        on[loop.slots] = on_times(loop.st, run.output[loop.driven])
                outs[j] = run.output
        self.pv, self.temps, self.on = pv, temps, on
        return _Stepped(values, temps_at, outputs_at, updates,
                        (resolution(values) if readings is None else readings).astype(np.int64))

    def _readings(self, block: _Measured, stepped: _Stepped, b0: int, b1: int) -> _Seen:
        """The block's readings as each scan's PVs saw them, and each point's last reading so far."""
        readings, updates, width = stepped.readings, stepped.updates, block.width
        scan, col, points = block.scan, block.col, block.points
        flat = readings[scan, col]
        # each scan's PVs: each point's last reading so far (the register's value before the block until one)
        cell = np.where(updates >= 0, np.arange(b1 - b0)[:, None] * width + updates, -1)
        cell = np.maximum.accumulate(cell, axis=0)
        fresh = signed16(readings.ravel()[np.maximum(cell, 0)] & 0xFFFF) if readings.size else 0
        pv_at = np.where(cell >= 0, fresh, self.pv_register)
        self.pv_register = pv_at[-1]
        last = last_of_each(points)
        pts = points[last]
        self.last_word[pts] = flat[last] & 0xFFFF
        self.last_value[pts] = stepped.values[scan, col][last]
        self.last_flag[pts] = block.bad_flag[last] & ~block.good[last] if block.bad_flag is not None else False
        if self.kept is not None:
            for j in range(b1 - b0):
                fresh = np.flatnonzero(updates[j] >= 0)
                self.kept.append([fresh, readings[j][updates[j][fresh]] & 0xFFFF])
        return _Seen(flat, pv_at)

    def _alarms(self, block: _Measured, stepped: _Stepped, seen: _Seen, b0: int, b1: int) -> float | None:
        """Each instance's heater-loop starts through the block, and each scan's normal and warning words and ALM;
        the first heater-loop deadline the engine would have scanned at between two scans, if any."""
        fun86, ready, scans, st_time = self.fun86, self.ready, self.scans, self.st_time
        high_at, n = ready.high_at, b1 - b0
        first, limit = math.inf, None
        for k, (loop, outputs) in enumerate(zip(self.loops, stepped.outputs_at)):
            st = loop.st
            n_on = len(loop.idx)
            column = np.full(st.zn, -1)
            column[loop.idx] = np.arange(n_on)
            b = block.points - st.sn
            mine = (b >= 0) & (b < st.zn)
            mine[mine] = loop.enabled[b[mine]]
            mine = np.flatnonzero(mine)
            # (a reading landed at its very scan is that scan's PV)
            landed, skipped = seen_at_skipped_scans(block.times[mine], scans[b0:b1][block.scan[mine]],
                                                    scans[b0 + 1:b1 + 1][block.scan[mine]], st_time)
            mine, landed = mine[skipped], landed[skipped]
            rep_scan, rep_col, rep_row = block.scan[mine], column[b[mine]], block.rank[mine]
            per = int(rep_row.max()) + 2 if len(rep_row) else 1  # rows per scan: its readings replayed, then it
            # every row of a scan starts as the scan itself (a reading seen twice changes nothing), then the replays
            pv_at = seen.pv_at
            pv = np.repeat(pv_at[:, loop.points[loop.idx]], per, axis=0)
            at = np.repeat(np.broadcast_to(scans[b0 + 1:b1 + 1, None], (n, n_on)), per, axis=0)
            high = np.repeat(outputs[:, loop.idx] * 100 >= high_at, per, axis=0)
            where = rep_scan * per + rep_row
            pv[where, rep_col] = signed16(seen.flat[mine] & 0xFFFF)
            at[where, rep_col] = landed
            before = np.vstack((self.outputs[k][None], outputs[:-1]))  # the outputs each scan's replays saw
            high[where, rep_col] = before[rep_scan, loop.idx[rep_col]] * 100 >= high_at
            since = fun86.track(st, loop.idx, pv, at, high, None, loop.sv[loop.idx], loop.os[loop.idx],
                                ready.limit, count=False)[per - 1::per]
            loop_open = np.asarray(fun86.loop_elapsed(since, scans[b0 + 1:b1 + 1, None]) >= ready.loop_seconds,
                                   dtype=bool)
            normal = loop.enabled & np.asarray(fun86.in_band(pv_at[:, loop.points], loop.sv, loop.os), dtype=bool)
            warning = np.zeros((n, st.zn), dtype=bool)
            warning[:, loop.idx] = loop_open
            words = self.words[k][b0:b1]
            words[:, 0], words[:, 1] = fun86.bit_words(st, normal)
            words[:, 2], words[:, 3] = fun86.bit_words(st, warning)
            self.alm[k][b0:b1] = np.asarray(fun86.alarm(np.count_nonzero(loop.enabled & ~normal, axis=1) > 0,
                                                       np.count_nonzero(warning, axis=1) > 0), dtype=bool)
            # a deadline pending after a scan and due before the next one (scan i is at scans[i + 1])
            pairs = min(b1, self.n_scans - 1) - b0
            if pairs > 0:
                deadlines = since[:pairs] + ready.loop_seconds
                after, until = scans[b0 + 1:b0 + 1 + pairs, None], scans[b0 + 2:b0 + 2 + pairs, None]
                ahead = (deadlines > after + 1e-9) & (scan_grid(deadlines, st_time) < until - st_time / 2)
                hit = np.flatnonzero(np.count_nonzero(ahead, axis=1))
                if len(hit):
                    at_scan, soonest = b0 + int(hit[0]), float(deadlines[hit[0]][ahead[hit[0]]].min())
                    if at_scan < first or (at_scan == first and soonest < limit):
                        first, limit = at_scan, soonest
            self.outputs[k] = outputs[-1]
        return limit

    def _anchors(self, stepped: _Stepped, b0: int, b1: int) -> None:
        """Each heated slot's last waveform change so far (the plant re-anchors there: the time, and T then)."""
        for k, (loop, outputs) in enumerate(zip(self.loops, stepped.outputs_at)):
            if not len(loop.slots):
                continue
            key = self._key(loop, outputs)[0]
            changed = key != np.vstack((self.keys[k][None], key[:-1]))
            moved = changed.any(axis=0)
            if moved.any():
                last = len(key) - 1 - np.argmax(changed[::-1], axis=0)
                self.changed[k][moved] = b0 + last[moved]
                self.changed_temp[k][moved] = stepped.temps_at[last[moved], loop.slots[moved]]
            self.keys[k] = key[-1]
        if self.kept is not None:
            for j in range(b1 - b0):
                self.kept[b0 + j].append([out[j] for out in stepped.outputs_at])

    # -- the end ---------------------------------------------------------------------------------------------------
    def commit(self) -> None:
        """Memory and every model's state as after the batch's scans (observers called after each of them)."""
        fun86, engine, mem, tm, plant = self.fun86, self.engine, self.engine.memory, self.tm, self.plant
        scans = self.scans
        for loop, run in zip(self.loops, self.runs):
            loop.st.integral[loop.idx], loop.st.pv_prev[loop.idx], loop.st.has_prev[loop.idx] = (run.integral,
                                                                                                run.prev, run.has)
            loop.st.prealarm[:] = 0  # (no reading could reach R4008: every count was reset at the first scan)
            loop.output = run.output.astype(np.int64)
        for k, loop in enumerate(self.loops):  # the plant re-anchored where each slot's waveform last changed
            moved = self.changed[k] >= 0
            if not moved.any():
                continue
            s = loop.slots[moved]
            _key, steady, level, on = self._key(loop, loop.output)
            plant.t0[s] = scans[1:][self.changed[k][moved]]
            plant.temp0[s] = self.changed_temp[k][moved]
            plant.w_pwm[s] = ~steady[moved]
            plant.w_started[s], plant.w_period[s], plant.w_on[s] = loop.st.started, loop.st.pwm, on[moved]
            plant.w_uon[s], plant.w_uoff[s] = loop.lit[moved], level[moved]
        plant.waveforms_replaced()
        if self.kept is not None:
            self._observe()
        self._temperature()
        for k, loop in enumerate(self.loops):
            inst, st = loop.inst, loop.st
            mem.words[inst.or_.kind][inst.or_.index:inst.or_.index + st.zn] = loop.output.tolist()
            mem.words[inst.wr.kind][inst.wr.index:inst.wr.index + 4] = self.words[k][-1].tolist()
            mem.bits[inst.alm.kind][inst.alm.index] = 1 if self.alm[k][-1] else 0
            st.view = None  # (its registers changed)
            fun86.drive_outputs(mem, inst, st, float(scans[-1]), loop.enabled, loop.output)
        tm.log = []
        fun86.readings_replayed(float(scans[-1]))
        engine.now = float(scans[-1])

    def _temperature(self) -> None:
        """The readings registers, samples, break bits and measured points as after the batch's measurements."""
        tm, mem = self.tm, self.engine.memory
        points = np.flatnonzero(self.last_word >= 0)
        bank, base = mem.words[self.table.readings.kind], self.table.readings.index
        for point, word in zip(points.tolist(), self.last_word[points].tolist()):
            bank[base + point] = word
        tm.batch_measured(points, self.installed[points] & ~self.broken[points], self.last_value[points],
                          self.last_flag[points])

    def _observe(self) -> None:
        """Each scan's outputs and readings in memory, and the observers called, as after each of those scans."""
        fun86, engine, mem = self.fun86, self.engine, self.engine.memory
        bank, base = mem.words[self.table.readings.kind], self.table.readings.index
        for i, (fresh, words, outputs) in enumerate(self.kept):
            for point, word in zip(fresh.tolist(), words.tolist()):
                bank[base + point] = word
            now = float(self.scans[i + 1])
            for k, (loop, out) in enumerate(zip(self.loops, outputs)):
                inst, st = loop.inst, loop.st
                mem.words[inst.or_.kind][inst.or_.index:inst.or_.index + st.zn] = out.tolist()
                mem.words[inst.wr.kind][inst.wr.index:inst.wr.index + 4] = self.words[k][i].tolist()
                mem.bits[inst.alm.kind][inst.alm.index] = 1 if self.alm[k][i] else 0
                mem.bits[inst.yn.kind][inst.yn.index:inst.yn.index + st.zn] = fun86.outputs_at(
                    st, now, fun86.on_times(st, out), loop.y_on, loop.y_off)
            engine.now = now
            for observer in engine.observers:
                observer(engine)
