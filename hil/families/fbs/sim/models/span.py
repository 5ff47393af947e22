"""Request-free stretches of the temperature modules, FUN86 and the thermal plant, run in batches.

Between two requests nothing outside the models touches memory.  When the only scans the engine would run there are
FUN86's PID steps — the plant integrating the PWM between them (no dead time), no reading able to reach the
pre-alarm limit, no heater-loop deadline due, no other model needing a scan — :class:`Span` runs those scans
together, the state of every point in arrays:

1. the measurements of the whole batch are scheduled at once (the temperature model's schedule), and whatever does
   not depend on the loop's state — their noise, the decays, the PWM cycles' starts — is computed for all of them;
2. then scan after scan only what does: the plant through the last interval's waveforms (its closed form for every
   measurement and every point's anchor, :func:`~hil.families.fbs.sim.models.plant.cycles_temperature`), the
   readings (the temperature model's ``in_unit``, ``average``, ``resolution``), the PID step of the instances due
   (:meth:`Fun86Model.control`) and the new waveforms;
3. then the rest for the whole batch at once: the readings replayed for the heater-loop timer, each scan's normal
   and warning words and ALM (:meth:`Fun86Model.track`, ``in_band``, ``bit_words``, ``alarm``), the last scan's
   outputs, the readings and samples, and the plant's anchors where its waveforms changed.

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
from hil.families.fbs.sim.models.fun86 import _R, PREALARM_SCANS, Fun86Model, InstanceState, Law
from hil.families.fbs.sim.models.plant import (NOISE_CLIP, PlantSource, ThermalPlant, cycle_terms, cycles_temperature,
                                                noise_index)
from hil.families.fbs.sim.models.temperature import SENSOR_HIGH, SENSOR_LOW, TemperatureModel
from hil.families.fbs.temperature import MAX_MODULES, MAX_POINTS, TABLE_MARKER
from hil.sim.columns import last_of_each, occurrence, signed16
from hil.sim.model import scan_grid

if TYPE_CHECKING:
    from hil.sim.engine import Engine
    from hil.families.fbs.sim.memory import Memory

#: scans per batch at most (the batch's arrays are scans × columns)
CHUNK = 2048



@dataclass
class _Table:
    """The temperature table as the temperature model reads it (measuring, every point measured once)."""

    readings: Address
    work: Address
    measured: tuple  # (module k, first point, table code) of the modules measured
    header: tuple[int, ...]
    count: int  # modules in the table
    total: int  # points in the table


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
    output: np.ndarray  # OR (per b), as now
    before: np.ndarray  # OR as before the batch
    driven: np.ndarray  # the b whose output heats a plant slot …
    slots: np.ndarray  # … and those slots
    y_on: np.ndarray  # per b
    y_off: np.ndarray
    lit: np.ndarray  # the heater of each slot with its output on …
    dark: np.ndarray  # … and off (the plant's faults)


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
        self.sv = loop.sv[idx]
        self.output = loop.output.astype(float)


class Span:
    """Runs FUN86's scans in batches (see the module docstring); :meth:`Fun86Model.span` asks it."""

    def __init__(self, fun86: Fun86Model) -> None:
        self.fun86 = fun86
        self._shared_key: object = None
        self._shared = True

    def run(self, engine: "Engine", target: float) -> bool:
        ready = self._ready(engine)
        if ready is None:
            return False
        bound = math.inf
        saved = self._save(engine, ready)
        while True:
            start = engine.now
            times, due = self._plan(engine, target, ready["loops"], bound)
            if not times:
                return False
            scans = np.array([start, *times])
            batch = self._compute(engine, ready, scans, due)
            deadline = self._deadline(ready, batch, scans, engine.scan_time)
            if deadline is None:
                self._commit(engine, ready, batch, scans)
                return True
            # a heater-loop deadline the engine would have scanned at, inside: again, up to it
            self._restore(engine, ready, saved)
            bound = deadline

    # -- what may be batched ---------------------------------------------------------------------------------
    def _ready(self, engine: "Engine") -> dict[str, Any] | None:
        """Everything a batch needs, or None when the coming scans are not FUN86's PID steps alone."""
        fun86 = self.fun86
        tm = fun86.temperature_model
        if (type(fun86) is not Fun86Model or not fun86.pwm_exact or type(tm) is not TemperatureModel
                or tm.log is None):
            return None
        states = fun86.states
        if any(st.waiting for st in states) or not any(st.running for st in states):
            return None
        models = engine.models
        plant = next((m for m in models if type(m) is ThermalPlant), None)
        if plant is None or not plant.waved or plant._fun86 is not fun86:
            return None
        at = [next((i for i, m in enumerate(models) if m is model), -1) for model in (tm, fun86, plant)]
        if not 0 <= at[0] < at[1] < at[2]:
            return None
        now = engine.now
        others = [m for m in models if m is not tm and m is not fun86 and m is not plant]
        if any(m.next_event(now) != math.inf for m in others):
            return None
        mem = engine.memory
        table = self._table(tm, mem)
        if table is None:
            return None
        start = fun86.readings_start(mem)
        if start is None or (start.kind, start.index) != (table.readings.kind, table.readings.index):
            return None
        if not self._unshared(engine, mem, table, others):
            return None
        words = mem.words
        r = words["R"]
        limit, loop_seconds = r[_R[reg.PREALARM_LIMIT]], r[_R[reg.HEATER_LOOP_SECONDS]]
        loops = []
        for inst, st in zip(fun86.config.instances, states):
            if not st.running:
                continue
            if (st.interval <= 2 * engine.scan_time or fun86._prealarm_possible(mem, st)
                    or ((st.prealarm > 0) & (st.prealarm < 4 * PREALARM_SCANS)).any()):
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
        return {"tm": tm, "plant": plant, "table": table, "loops": loops, "limit": limit,
                "loop_seconds": loop_seconds, "high_at": fun86.loop_threshold(mem) * OUTPUT_FULL}

    @staticmethod
    def _table(tm: TemperatureModel, mem: "Memory") -> _Table | None:
        """The table as the temperature model's scan reads it, if it is measuring and every point was measured."""
        words = mem.words[tm.config.table.kind]
        sr = tm.config.table.index
        if words[sr] != TABLE_MARKER:
            return None
        count = words[sr + 1]
        header = tuple(words[sr:sr + 4 + min(count, MAX_MODULES)])
        state, readings, work, codes, table_modules, total = tm._layout(header)
        if state != "measuring" or readings is None or work is None or work.kind not in mem.words:
            return None
        _mismatch, expected, _entries, measured = tm._plan(codes, table_modules, words[sr + 2])
        if not expected or not expected <= tm._measured:
            return None
        return _Table(readings, work, measured, header, min(count, MAX_MODULES), total)

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
                     np.array(words[inst.or_.kind][inst.or_.index:inst.or_.index + zn], dtype=np.int64),
                     np.array([d[0] for d in driven], dtype=np.intp), np.array([d[1] for d in driven], dtype=np.intp),
                     np.array(y_on), np.array(y_off), lit, dark)

    def _unshared(self, engine: "Engine", mem: "Memory", table: _Table, others: list) -> bool:
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
        reads |= {("R", _R[reg.PID_SOURCE_KEY] + i) for i in range(6)} | {("R", _R[reg.PID_ENABLE_LOW] - 2 + i)
                                                                         for i in range(4)}
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
            event = fun86.scan_for(min(loop.st.next_pid for loop in loops), engine.now)
            landing = engine.landing(event, target)
            if landing >= bound or landing + engine.scan_time > target + 1e-9:
                break
            engine.land(event, target)
            engine.tick()
            times.append(engine.now)
            for loop, flags in zip(loops, due):
                flags.append(fun86.pid_due(loop.st, engine.now))
        return times, due

    @staticmethod
    def _save(engine: "Engine", ready: dict[str, Any]) -> tuple:
        """What planning and computing a batch change before it is committed (to try a shorter one instead)."""
        tm = ready["tm"]
        return ((engine.now, engine.scans, engine.skipped_time), [(loop.st.next_pid, loop.st.loop_since.copy())
                                                                   for loop in ready["loops"]],
                (list(tm._next), list(tm._mux), tm._ring.copy(), tm._count.copy(), tm._top.copy()))

    @staticmethod
    def _restore(engine: "Engine", ready: dict[str, Any], saved: tuple) -> None:
        clock, loops, temperature = saved
        engine.now, engine.scans, engine.skipped_time = clock
        for loop, (next_pid, loop_since) in zip(ready["loops"], loops):
            loop.st.next_pid, loop.st.loop_since = next_pid, loop_since.copy()
            loop.output = loop.before.copy()
        tm = ready["tm"]
        tm._next, tm._mux = list(temperature[0]), list(temperature[1])
        tm._ring, tm._count, tm._top = temperature[2].copy(), temperature[3].copy(), temperature[4].copy()

    def _compute(self, engine: "Engine", ready: dict[str, Any], scans: np.ndarray,
                 due: list[list[bool]]) -> "_Batch":
        """The scans at ``scans[1:]`` (``scans[0]``: the one before; the clock already at the last), computed:
        everything but memory and the models' committed state."""
        batch = _Batch(engine, ready, scans)
        batch.steps(self.fun86, ready["loops"], due)
        batch.alarms = [self._alarms(ready, loop, outs, batch) for loop, outs in zip(ready["loops"], batch.outputs_at)]
        return batch

    def _deadline(self, ready: dict[str, Any], batch: "_Batch", scans: np.ndarray, st_time: float) -> float | None:
        """The first heater-loop deadline the engine would have scanned at between two of the batch's scans —
        pending after one, due before the next — or None."""
        first, limit = math.inf, None
        for _normal, _warning, _alm, since in batch.alarms:
            deadlines = since[:-1] + ready["loop_seconds"]
            ahead = (deadlines > scans[1:-1, None] + 1e-9) & (scan_grid(deadlines, st_time) < scans[2:, None]
                                                                - st_time / 2)
            hit = np.flatnonzero(ahead.any(axis=1))
            if len(hit) and hit[0] <= first:
                soonest = float(deadlines[hit[0]][ahead[hit[0]]].min())
                limit = soonest if hit[0] < first or limit is None else min(limit, soonest)
                first = int(hit[0])
        return limit

    def _commit(self, engine: "Engine", ready: dict[str, Any], batch: "_Batch", scans: np.ndarray) -> None:
        """Memory and every model's state as after the batch's scans (observers called after each of them)."""
        fun86, mem = self.fun86, engine.memory
        tm, plant, table, loops = ready["tm"], ready["plant"], ready["table"], ready["loops"]
        for loop, run in zip(loops, batch.runs):
            loop.st.integral[loop.idx], loop.st.pv_prev[loop.idx], loop.st.has_prev[loop.idx] = (run.integral,
                                                                                                run.prev, run.has)
            loop.st.prealarm[:] = 0  # (no reading could reach R4008: every count was reset at the first scan)
        self._plant(plant, loops, batch.outputs_at, scans, batch.temps_at)
        if engine.observers:
            self._observe(engine, loops, batch, table)
        self._temperature(tm, mem, table, batch)
        for loop, outs, (normal, warning, alm, _since) in zip(loops, batch.outputs_at, batch.alarms):
            inst = loop.inst
            mem.words[inst.or_.kind][inst.or_.index:inst.or_.index + loop.st.zn] = outs[-1].tolist()
            mem.words[inst.wr.kind][inst.wr.index:inst.wr.index + 4] = [int(w[-1]) for w in (*normal, *warning)]
            mem.bits[inst.alm.kind][inst.alm.index] = 1 if alm[-1] else 0
            loop.st.view = None  # (its registers changed)
            fun86._drive(mem, inst, loop.st, float(scans[-1]), loop.enabled, outs[-1])
        tm.log = []
        fun86._log = None

    @staticmethod
    def _temperature(tm: TemperatureModel, mem: "Memory", table: _Table, batch: "_Batch") -> None:
        """The readings registers, samples, break bits and measured points as after the batch's measurements."""
        points, good = batch.points, batch.good
        last = last_of_each(points)
        bank, base = mem.words[table.readings.kind], table.readings.index
        for point, word in zip(points[last].tolist(), (batch.flat_readings[last] & 0xFFFF).tolist()):
            bank[base + point] = word
        if tm.config.averaging == 1:
            kept = last[good[last]]
            tm.average(points[kept], batch.values[kept])
        if batch.some_bad:
            tm._forget(points[~good])
        breaks = tm._breaks
        for point, flag in zip(points[last].tolist(), (batch.bad_flag[last] & ~good[last]).tolist()):
            breaks = breaks | 1 << point if flag else breaks & ~(1 << point)
        tm._breaks = breaks
        tm._measured.update(points[last].tolist())
        tm._quiet = None

    def _alarms(self, ready: dict[str, Any], loop: _Loop, outputs: np.ndarray, batch: "_Batch") -> tuple:
        """An instance's heater-loop starts over the batch, and each scan's (normal words, warning words, ALM,
        heater-loop starts)."""
        fun86, st = self.fun86, loop.st
        high_at, scans, st_time = ready["high_at"], batch.scans, batch.st_time
        n_scans, n = batch.n_scans, len(loop.idx)
        column = np.full(st.zn, -1)
        column[loop.idx] = np.arange(n)
        b = batch.points - st.sn
        mine = (b >= 0) & (b < st.zn)
        mine[mine] = loop.enabled[b[mine]]
        mine = np.flatnonzero(mine)
        landed = scan_grid(batch.times[mine], st_time)
        skipped = landed < scans[1:][batch.scan_of[mine]] - st_time / 2  # (else read at that very scan: its PV)
        mine, landed = mine[skipped], landed[skipped]
        rep_scan, rep_col, rep_row = batch.scan_of[mine], column[b[mine]], batch.rank[mine]
        per = int(rep_row.max()) + 2 if len(rep_row) else 1  # rows per scan: its readings replayed, then the scan
        # every row of a scan starts as the scan itself (a reading seen twice changes nothing), then the replays
        pv = np.repeat(batch.pv_at[:, loop.points[loop.idx]], per, axis=0)
        at = np.repeat(np.broadcast_to(scans[1:, None], (n_scans, n)), per, axis=0)
        high = np.repeat(outputs[:, loop.idx] * 100 >= high_at, per, axis=0)
        where = rep_scan * per + rep_row
        pv[where, rep_col] = signed16(batch.flat_readings[mine] & 0xFFFF)
        at[where, rep_col] = landed
        before = np.vstack((loop.before[None], outputs[:-1]))  # the outputs each scan's readings were replayed at
        high[where, rep_col] = before[rep_scan, loop.idx[rep_col]] * 100 >= high_at
        since = fun86.track(st, loop.idx, pv, at, high, None, loop.sv[loop.idx], loop.os[loop.idx], ready["limit"],
                            count=False)[per - 1::per]
        loop_open = np.asarray(fun86.loop_elapsed(since, scans[1:, None]) >= ready["loop_seconds"], dtype=bool)
        normal = loop.enabled & np.asarray(fun86.in_band(batch.pv_at[:, loop.points], loop.sv, loop.os), dtype=bool)
        warning = np.zeros((n_scans, st.zn), dtype=bool)
        warning[:, loop.idx] = loop_open
        alm = np.asarray(fun86.alarm((loop.enabled & ~normal).any(axis=1), warning.any(axis=1)), dtype=bool)
        return fun86.bit_words(st, normal), fun86.bit_words(st, warning), np.broadcast_to(alm, (n_scans,)), since

    def _plant(self, plant: ThermalPlant, loops: list[_Loop], outputs_at: list[np.ndarray], scans: np.ndarray,
               temps_at: np.ndarray) -> None:
        """The plant's anchors and waveforms as its scans would have left them: each slot re-anchored at the last
        scan that changed its waveform."""
        fun86 = self.fun86
        for loop, outs in zip(loops, outputs_at):
            if not len(loop.slots):
                continue
            slots, st, lit, dark = loop.slots, loop.st, loop.lit, loop.dark
            on = fun86.on_times(st, outs[:, loop.driven])
            steady = (lit == dark) | (on <= 0) | (on >= st.pwm)
            level = np.where((lit != dark) & (on > 0) & (on >= st.pwm), lit, dark)
            key = np.where(steady, -1.0 - level, on)
            same_wave = (plant.w_started[slots] == st.started) & (plant.w_period[slots] == st.pwm) & (
                plant.w_uon[slots] == lit) & (plant.w_uoff[slots] == dark)
            initial = np.where(plant.w_pwm[slots], np.where(same_wave, plant.w_on[slots], math.nan),
                               -1.0 - plant.w_uoff[slots])
            changed = key != np.vstack((initial[None], key[:-1]))
            moved = changed.any(axis=0)
            if not moved.any():
                continue
            last = len(key) - 1 - np.argmax(changed[::-1], axis=0)
            s, at = slots[moved], last[moved]
            plant.t0[s] = scans[1:][at]
            plant.temp0[s] = temps_at[at, s]
            plant.w_pwm[s] = ~steady[-1, moved]
            plant.w_started[s], plant.w_period[s], plant.w_on[s] = st.started, st.pwm, on[-1, moved]
            plant.w_uon[s], plant.w_uoff[s] = lit[moved], level[-1, moved]
        plant._last_outputs = None

    def _observe(self, engine: "Engine", loops: list[_Loop], batch: "_Batch", table: _Table) -> None:
        """Each scan's outputs and readings in memory, and the observers called, as after each of those scans."""
        fun86, mem = self.fun86, engine.memory
        bank, base = mem.words[table.readings.kind], table.readings.index
        end = engine.now
        for i in range(batch.n_scans):
            fresh = np.flatnonzero(batch.updates[i] >= 0)
            for point, word in zip(fresh.tolist(), (batch.readings[i][batch.updates[i][fresh]] & 0xFFFF).tolist()):
                bank[base + point] = word
            now = float(batch.scans[i + 1])
            for loop, outs, (normal, warning, alm, _since) in zip(loops, batch.outputs_at, batch.alarms):
                inst, st = loop.inst, loop.st
                mem.words[inst.or_.kind][inst.or_.index:inst.or_.index + st.zn] = outs[i].tolist()
                mem.words[inst.wr.kind][inst.wr.index:inst.wr.index + 4] = [int(w[i]) for w in (*normal, *warning)]
                mem.bits[inst.alm.kind][inst.alm.index] = 1 if alm[i] else 0
                on_time, y_on, y_off = fun86.waves(st, loop.enabled, outs[i])
                mem.bits[inst.yn.kind][inst.yn.index:inst.yn.index + st.zn] = fun86.outputs_at(st, now, on_time,
                                                                                             y_on, y_off)
            engine.now = now
            for observer in engine.observers:
                observer(engine)
        engine.now = end

class _Batch:
    """A batch's scans computed (see the module docstring): the measurements as a row of columns per scan, the
    plant's columns (those measurements, then every slot at the scan), and what each scan left."""

    def __init__(self, engine: "Engine", ready: dict[str, Any], scans: np.ndarray) -> None:
        self.tm: TemperatureModel = ready["tm"]
        self.plant: ThermalPlant = ready["plant"]
        self.scans = scans
        self.st_time = engine.scan_time
        self.n_scans = len(scans) - 1
        self._measurements(engine.memory, ready["table"])
        self._plant_columns(ready["loops"])
        bank, base = engine.memory.words[ready["table"].readings.kind], ready["table"].readings.index
        self.pv = signed16(bank[base:base + min(MAX_POINTS, len(bank) - base)])
        # the column of each point's last reading at each scan (its PV register's new value; −1: none)
        self.updates = np.full((self.n_scans, len(self.pv)), -1, dtype=np.intp)
        last = last_of_each(self.scan_of * 64 + self.points)
        self.updates[self.scan_of[last], self.points[last]] = self.col[last]
        self.alarms: list = []

    def rows(self, flat: np.ndarray, fill: Any) -> np.ndarray:  # noqa: ANN401
        """A value per measurement as a row per scan (``fill`` where a scan has fewer)."""
        if self._order is not None:  # every scan as wide: the values in scan order, cut in rows
            return flat[self._order].reshape(self.n_scans, self.width)
        out = np.full((self.n_scans, self.width), fill, dtype=np.asarray(flat).dtype)
        out[self.scan_of, self.col] = flat
        return out

    def _measurements(self, mem: "Memory", table: _Table) -> None:
        """Every measurement of the batch: each module's in time order (its points in turn), module after module
        (as each scan takes them), with its column in its scan's row; then what each needs but the plant."""
        tm, plant, scans, n_scans = self.tm, self.plant, self.scans, self.n_scans
        parts = []
        filled = np.zeros(n_scans, dtype=np.int64)  # columns placed in each scan's row so far
        ends = scans[1:] + 1e-9
        for k, first, code in table.measured:
            t, p = tm.measure_module(float(scans[-1]), k, first)
            scan = np.searchsorted(ends, t, side="left")
            within = np.arange(len(t)) - np.searchsorted(scan, np.arange(n_scans))[scan]
            parts.append((t, p, np.full(len(t), code >> 8), scan, filled[scan] + within,
                          within // tm.fitted[k].points))  # (the how-many-th reading of its point at that scan)
            filled += np.bincount(scan, minlength=n_scans)
        self.times, self.points, codes, self.scan_of, self.col, self.rank = (np.concatenate(x) for x in zip(*parts))
        self.per_scan = filled
        self.width = width = int(filled.max()) if len(self.times) else 0
        times, points = self.times, self.points
        self._order = None
        if width and (filled == width).all():
            self._order = np.empty(len(times), dtype=np.intp)
            self._order[self.scan_of * width + self.col] = np.arange(len(times))

        every = np.arange(MAX_POINTS)  # (the seams per point, then for each measurement)
        installed = np.asarray(tm.installed(mem, every), dtype=bool)[points]
        broken = np.isin(every, list(tm.broken))[points]
        self.good = good = installed & ~broken
        self.some_bad = not good.all()
        self.bad_flag = np.zeros(len(points), dtype=bool)
        if self.some_bad:
            bad_reading, bad_flag = tm.point_result(points, installed, broken, np.zeros(len(points), dtype=np.int64))
            self.bad_flag = np.broadcast_to(np.asarray(bad_flag, dtype=bool), points.shape)
            self.c_bad = self.rows(np.broadcast_to(np.asarray(bad_reading, dtype=np.int64), points.shape), 0)
            self.c_good = self.rows(good, True)
        slot_of = np.full(MAX_POINTS, -1)
        for point, source in tm.sources.items():
            if isinstance(source, PlantSource) and source.plant is plant:
                slot_of[point] = source.slot
        slot = slot_of[points]
        heated = slot >= 0
        self.mixed = not (heated | ~good).all()
        if self.mixed:  # sources of their own: their values known beforehand
            other = good & ~heated
            pre = np.zeros(len(points))
            pre[other] = tm.values(times[other], points[other])
            self.c_pre, self.c_heated = self.rows(pre, 0.0), self.rows(heated | ~good, True)
        noise = np.zeros(len(points))
        if plant.normals is not None and heated.any():
            noise[heated] = plant.normals[noise_index(plant.seed, points[heated], times[heated])] \
                * plant.noise[slot[heated]]
        self.c_noise = self.rows(noise, 0.0)
        low, high = SENSOR_LOW[codes], SENSOR_HIGH[codes]
        self.wraps = not (np.isfinite(low).all() and np.isfinite(high).all())  # (in range, PVs fit in 16 bits)
        self.limits = None
        if not self._within(slot, heated, low, high):
            self.limits = self.rows(low, -math.inf), self.rows(high, math.inf)
        self.c_points = self.rows(points, 0) if tm.config.averaging > 1 else None
        self.m_slot = self.rows(np.where(heated, slot, 0), 0)
        self.m_time = self.rows(times, 0.0)
        if self._order is None:  # (padding: nothing elapsed)
            self.m_time = np.where(self.rows(np.ones(len(times), dtype=bool), False), self.m_time, scans[:-1, None])
        if not width:
            self.m_slot, self.m_time = np.zeros((n_scans, 0), dtype=np.intp), np.zeros((n_scans, 0))

    def _within(self, slot: np.ndarray, heated: np.ndarray, low: np.ndarray, high: np.ndarray) -> bool:
        """No measurement can leave its sensor's range (the plant's bounds within it): no clamping to do."""
        plant = self.plant
        if not heated.all():
            return False
        top = np.array([plant.upper(s) for s in range(len(plant.order))])
        bottom = np.minimum(plant.initial, plant.ambient) - NOISE_CLIP * plant.noise
        return bool((top[slot] <= high).all() and (bottom[slot] >= low).all())

    def _plant_columns(self, loops: list[_Loop]) -> None:
        """The plant's columns and what of their solution does not depend on the loop: the cycles of the PWM each
        scan's interval meets, the decays and the heater-off part (:func:`cycle_terms`)."""
        plant, scans, st_time, n_scans = self.plant, self.scans, self.st_time, self.n_scans
        n_slots = len(plant.order)
        self.c_slot = c_slot = np.hstack((self.m_slot, np.broadcast_to(np.arange(n_slots), (n_scans, n_slots))))
        c_time = np.hstack((self.m_time, np.broadcast_to(scans[1:, None], (n_scans, n_slots))))
        # each slot's waveform: the instance driving its heater (or constant: the plant's wave as it is)
        started, period = np.zeros(n_slots), np.full(n_slots, 1e9)
        u_on, u_off = plant.w_uoff.copy(), plant.w_uoff.copy()
        self.on = np.zeros(n_slots)
        for loop in loops:
            if len(loop.slots):
                started[loop.slots], period[loop.slots] = loop.st.started, loop.st.pwm
                u_on[loop.slots], u_off[loop.slots] = loop.lit, loop.dark
                self.on[loop.slots] = np.minimum(Fun86Model.on_times(loop.st, loop.output[loop.driven]), loop.st.pwm)
        t_off = plant.ambient + plant.gain * u_off
        lift = plant.ambient + plant.gain * u_on - t_off
        rate = 1.0 / plant.tau
        self.c_lift = lift[c_slot]
        a = scans[:-1, None]

        def cycle(x: np.ndarray, before: bool) -> np.ndarray:
            """Per slot, the cycle whose start (on the grid) is the last at or before x (``before``: before x)."""
            k = np.floor((x - started) / period)
            start, end = (scan_grid(started + j * period, st_time) for j in (k, k + 1))
            k = np.where(start >= x if before else start > x, k - 1, k)
            return np.where(end < x if before else end <= x, k + 1, k)

        # from the cycle each scan's interval starts in to the last starting before the scan: scans × cycles × slots
        first = cycle(a, False)
        n_cycles = max(1, int((cycle(scans[1:, None], True) - first).max()) + 1)
        raw = started + (first[:, None] + np.arange(n_cycles)[:, None]) * period
        shape = (n_scans, n_cycles, c_slot.shape[1])
        self.s3 = np.ascontiguousarray(np.broadcast_to(c_slot[:, None], shape))
        self.raw = np.take_along_axis(raw, self.s3, axis=2)  # (each column's, where a scan's step is cheapest)
        self.t3 = np.ascontiguousarray(np.broadcast_to(c_time[:, None], shape))
        self.r3 = np.ascontiguousarray(np.broadcast_to(rate[c_slot][:, None], shape))
        self.decay, self.base = cycle_terms(a, self.t3.transpose(1, 0, 2),
                                            scan_grid(self.raw, st_time).transpose(1, 0, 2), t_off[c_slot],
                                            self.c_lift, self.r3.transpose(1, 0, 2))

    def steps(self, fun86: Fun86Model, loops: list[_Loop], due: list[list[bool]]) -> None:
        """Scan after scan: the plant through the last interval's waveforms, the readings, the PID steps due."""
        tm, plant, n_scans, width, st_time = self.tm, self.plant, self.n_scans, self.width, self.st_time
        n_slots = len(plant.order)
        averaging = tm.config.averaging
        limits = self.limits
        plain = not (self.mixed or limits or tm.config.unit != "C" or averaging > 1 or self.some_bad or self.wraps)
        readings = np.zeros((n_scans, width)) if averaging > 1 or self.some_bad else None  # (else: from values)
        values = np.zeros((n_scans, width))
        pv_at = np.zeros((n_scans, len(self.pv)))
        temps_at = np.zeros((n_scans, n_slots))
        outputs_at = [np.zeros((n_scans, loop.st.zn), dtype=np.int64) for loop in loops]
        runs = [_Step(loop, len(self.pv), n_slots) for loop in loops]
        alone = len(runs) == 1 and runs[0].every_slot  # (then a PID step's on-times are the slots' whole)
        control, in_unit, resolution, on_times = fun86.control, tm.in_unit, tm.resolution, fun86.on_times
        whole = (self.updates >= 0).all(axis=1).tolist()  # every PV read anew at the scan
        pv = self.pv.astype(float)  # (readings are whole numbers: as floats, the PID law's arithmetic is the same)
        temps = self.plant.temperatures(np.arange(n_slots), np.full(n_slots, self.scans[0]))
        on, starts = self.on, self.scans[:-1].tolist()
        c_slot, raw, s3, t3, r3, c_lift, decay, base, c_noise = (self.c_slot, self.raw, self.s3, self.t3, self.r3,
                                                                 self.c_lift, self.decay, self.base, self.c_noise)
        updates = self.updates
        for i in range(n_scans):
            slots = c_slot[i]
            offs = scan_grid(raw[i] + on[s3[i]], st_time)
            temp = cycles_temperature(temps[slots], starts[i], t3[i], offs, c_lift[i], r3[i], (decay[i], base[i]))
            temps = temp[width:]
            temps_at[i] = temps
            value = temp[:width] + c_noise[i]
            if plain:
                values[i] = value
                reading = None
            else:
                if self.mixed:
                    value = np.where(self.c_heated[i], value, self.c_pre[i])
                value = values[i] = in_unit(value, *(limits[0][i], limits[1][i]) if limits else (None, None))
                if averaging > 1:
                    n = self.per_scan[i]
                    mean = value.copy()
                    mean[:n] = tm.average(self.c_points[i, :n], value[:n])
                else:
                    mean = value
                reading = resolution(mean)
                if self.some_bad:
                    reading = np.where(self.c_good[i], reading, self.c_bad[i])
                if readings is not None:
                    readings[i] = reading
            if whole[i]:
                pv = resolution(value[updates[i]]) if reading is None else reading[updates[i]]
            else:
                pv = pv.copy()
                fresh = updates[i] >= 0
                pv[fresh] = resolution(value[updates[i][fresh]]) if reading is None else reading[updates[i][fresh]]
            if self.wraps:
                pv = signed16(pv.astype(np.int64) & 0xFFFF).astype(float)
            pv_at[i] = pv
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
                outs[i] = run.output
        for loop, run in zip(loops, runs):
            loop.output = run.output.astype(np.int64)
        self.runs, self.outputs_at, self.temps_at = runs, outputs_at, temps_at
        self.pv_at = pv_at.astype(np.int64)
        self.values = values[self.scan_of, self.col]
        self.readings = (resolution(values) if readings is None else readings).astype(np.int64)
        self.flat_readings = self.readings[self.scan_of, self.col]
