"""FUN86 TPCTL, temperature PID, in the emulator (manual ch. 20.7; spec/fbs-pid.md).

One :class:`Fun86Model` runs every FUN86 instance of the bench profile's ``[pid]``, as the ladder's FUN86 boxes
would, after the temperature modules in each scan.  Per instance and scan:

* EN = 0: the instruction is not executed; **[our choice]** its outputs Yn… go off, ERR and ALM are cleared.
* Sn/Zn (the profile's constants, or the registers ``sn_register``/``zn_register`` when the profile names them)
  out of range → nothing is done and ERR = 1.
* first execution → PR/IR/DR of each point get 110/17/50.
* EN 0 → 1 latches R4005 (PID interval, PWM period); a later change of R4005 waits for the next rising edge.
* nothing else happens until every fitted temperature point has been measured once (execution code 56H).
* each PID interval: the control law (spec) for every enabled point (R4012/R4013), output OR 0–16383; disabled
  points get OR = 0 and their output off; each scan: time-proportional Yn… (ON for OR/16383 of the PWM period).
* each scan: the normal bits (WR+0/1), the pre-alarm count (PV ≥ R4008 for 10 consecutive scans), the heater-loop
  timer (OR ≥ R4006 % for R4007 s while not normal), the warning bits (WR+2/3) and ALM.

Temperatures come from the readings, where R4003/R4004 or the temperature table say; PV is in 0.1°.
Every decision a faulty PLC could get wrong is one small method (a "seam"), so the harness's tests can build
broken PLCs as tiny subclasses.  The per-point ones take and return arrays over an instance's points: the points'
state is kept in arrays (:class:`InstanceState`), stepped all at once.  The manual's sections are modules of their
own, mixed in here: the control law (models/fun86_law.py), the PWM outputs (models/fun86_pwm.py) and the alarm
bits (models/fun86_alarms.py); this one keeps EN, the ERR check, the first execution, R4005 and the schedule.

Time: the model asks the virtual-time engine for a scan wherever what it shows can change
(:meth:`Fun86Model.next_event`) — each PID interval, heater-loop deadline and measurement of the temperature
modules (a new PV may start a pre-alarm count or the heater-loop timer), every scan while a pre-alarm count is
running, and each PWM edge unless the thermal plant integrates the published waveforms exactly (no dead time:
``pwm_exact``; the waveforms are in models/fun86_waveforms.py: they model no manual statement); otherwise the
engine jumps.  With EN off it asks for nothing (the default bench's virtual day stays one jump).  The instances'
state between scans is in models/fun86_state.py.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from hil.families.fbs import registers as reg
from hil.families.fbs.address import Address, parse
from hil.families.fbs.pid import OUTPUT_FULL, PidConfig, PidInstance, timing_seconds, valid_sn_zn
from hil.families.fbs.sim.models.fun86_alarms import AlarmBits
from hil.families.fbs.sim.models.fun86_law import ControlLaw
from hil.families.fbs.sim.models.fun86_pwm import PwmOutputs
from hil.families.fbs.sim.models.fun86_state import InstanceState, View
from hil.families.fbs.temperature import EXEC_MEASURING, TemperatureConfig, decode_start
from hil.sim.columns import signed16 as signed
from hil.sim.model import Model, scan_grid
from hil.sim.timing import INSTANT, Timing

if TYPE_CHECKING:
    from hil.families.fbs.sim.memory import Memory
    from hil.families.fbs.sim.plc import Emulator

_R = {name: parse(name).index for name in (reg.PID_SOURCE_KEY, reg.PID_SOURCE, reg.PID_TIMING,
                                           reg.HEATER_LOOP_PERCENT, reg.HEATER_LOOP_SECONDS, reg.PREALARM_LIMIT,
                                           reg.PID_ENABLE_LOW)}
SOURCE_KEY = 0xA55A
DEFAULT_GAINS = (110, 17, 50)  # Kc, Ki, Td loaded at the first execution


def _unchanged(view: View | None, key: tuple, part: int) -> View | None:
    """``view`` when the registers of ``part`` of its key are as in ``key`` (what it read of them stands), else
    None."""
    return view if view is not None and view.key[part] == key[part] else None


class Fun86Model(ControlLaw, AlarmBits, PwmOutputs, Model["Emulator"]):
    name = "fun86"

    def __init__(self, config: PidConfig, temperature: TemperatureConfig | None) -> None:
        self.config = config
        self.temperature = temperature
        self.states = [InstanceState() for _ in config.instances]
        self._emu: Emulator | None = None
        #: the temperature model's next measurement time (set by build_emulator): PV changes only there
        self.next_measurement: Callable[[], float] | None = None
        #: set by the thermal plant when it integrates the PWM waveforms exactly: no scans at PWM edges
        self.pwm_exact = False
        self.init_waveforms()
        self._wiring: list[tuple] = []  # see _scan_at_rest
        self._wiring_for: Memory | None = None
        #: when the PID steps begin after EN rises (hil.sim.timing; build_emulator sets the emulator's)
        self.phases: Timing = INSTANT

    # -- the seams broken variants override (per point: arrays over an instance's points) -------------------------
    def valid(self, sn: int, zn: int) -> bool:
        """Sn/Zn in range (else ERR)."""
        return valid_sn_zn(sn, zn)

    def timing(self, r4005: int) -> tuple[float, float]:
        """(PID interval, PWM period) in seconds from R4005 (low byte, high byte)."""
        return float(timing_seconds(r4005 & 0xFF)), float(timing_seconds(r4005 >> 8))

    def enabled(self, mem: Memory, point: np.ndarray) -> np.ndarray:
        """Points' bits in R4012 (points 0–15) or R4013 (16–31)."""
        first, point = _R[reg.PID_ENABLE_LOW], np.asarray(point)
        words = np.array(mem.words["R"][first:first + int(point.max(initial=0)) // 16 + 1])  # (a point past 31 too)
        return (words[point // 16] >> (point % 16) & 1).astype(bool)

    @staticmethod
    def enable_words(mem: Memory, sn: int, zn: int) -> list[int]:
        """The enable words (R4012, R4013, …) that hold the bits of points Sn … Sn + Zn − 1."""
        first = _R[reg.PID_ENABLE_LOW]
        return mem.words["R"][first:first + (sn + zn - 1) // 16 + 1]

    # -- helpers ---------------------------------------------------------------------------------------------------
    def sn_zn(self, mem: Memory, inst: PidInstance) -> tuple[int, int]:
        sn, zn = inst.sn_register, inst.zn_register
        if sn is not None and zn is not None:  # (settable: the ladder takes Sn/Zn from these registers)
            words = mem.words
            return reg.signed16(words[sn.kind][sn.index]), reg.signed16(words[zn.kind][zn.index])
        return inst.sn, inst.zn

    def readings_start(self, mem: Memory) -> Address | None:
        """Where PVs are read: R4004 when R4003 = A55AH and R4004 names R0–R3839 / D0–D3999, else the table's."""
        words = mem.words["R"]
        if words[_R[reg.PID_SOURCE_KEY]] == SOURCE_KEY:
            code = words[_R[reg.PID_SOURCE]]
            if 10000 <= code <= 13839 or 20000 <= code <= 23999:
                return decode_start(code)
        if self.temperature is None:
            return None
        return decode_start(mem.words[self.temperature.table.kind][self.temperature.table.index + 2])

    def all_measured(self, mem: Memory) -> bool:
        if self.temperature is None:
            return False
        sr = self.temperature.table
        work = decode_start(mem.words[sr.kind][sr.index + 3])
        return work is not None and mem.words[work.kind][work.index] >> 8 == EXEC_MEASURING

    @staticmethod
    def pid_due(st: InstanceState, now: float) -> bool:
        """Is a PID step due at the scan at ``now``?  (The schedule then moves past now.)"""
        if now < st.next_pid - 1e-9:
            return False
        while st.next_pid <= now + 1e-9:
            st.next_pid += st.interval
        return True

    # -- the engine ---------------------------------------------------------------------------------------------
    def power_on(self, emu: Emulator) -> None:
        self._emu = emu

    def scan(self, emu: Emulator) -> None:
        mem = emu.memory
        if self._scan_at_rest(mem):
            return
        for inst, st in zip(self.config.instances, self.states):
            self._scan_instance(emu, mem, inst, st)
            if not st.running:
                self._drop_waveforms(inst, st)

    def next_event(self, now: float) -> float:
        """The next scan the instances need: a PID step, a heater-loop deadline, a measurement (while an instance
        waits for its points or runs: a new PV may start a pre-alarm count or the heater-loop timer), a PWM edge the
        plant does not integrate — every scan while a pre-alarm count runs; on the scan grid (:meth:`scan_for`)."""
        mem = self._emu.memory if self._emu is not None else None
        if mem is None:
            return math.inf
        loop_seconds = mem.words["R"][_R[reg.HEATER_LOOP_SECONDS]]
        due, active = math.inf, False
        for inst, st in zip(self.config.instances, self.states):
            active = active or st.waiting or st.running
            if not st.running:
                continue
            if self.counting(st):
                return now  # counting consecutive scans: every scan matters
            if np.count_nonzero(st.loop_since == st.loop_since):  # (a heater-loop start not NaN)
                deadlines = st.loop_since + loop_seconds
                pending = deadlines > now + 1e-9  # (once open, its bit is recomputed each scan)
                if np.count_nonzero(pending):
                    due = min(due, float(deadlines[pending].min()))
            due = min(due, st.next_pid)
            if not self.pwm_exact:
                due = min(due, self.next_pwm_edge(mem, inst, st, now))
        if active and self.next_measurement is not None:
            due = min(due, self.next_measurement())
        return due if due == math.inf else self.scan_for(due, now)

    def scan_for(self, due: float, now: float) -> float:
        """The first scan at or after an event at ``due``, on the scan grid: a jump then takes the very scan that
        stepping scan by scan would (PID samples, PWM edges and PVs seen at the same scans either way)."""
        if self._emu is None:  # (not powered on: no scan grid yet)
            return max(now, due)
        return max(now, float(scan_grid(due, self._emu.scan_time)))

    def _scan_at_rest(self, mem: Memory) -> bool:
        """The scan of every instance when all are at rest — EN off, and never ran or already stopped with no
        points (the default bench's case, on every request): of _scan_instance then only ERR := 0 and ALM := 0
        change anything, and _drop_waveforms over zn = 0 outputs does nothing.  False (nothing done) otherwise."""
        cls = type(self)
        if cls._scan_instance is not Fun86Model._scan_instance or cls._drop_waveforms is not Fun86Model._drop_waveforms:
            return False
        if self._wiring_for is not mem:  # the banks are fixed for a Memory's life
            self._wiring = [(mem.bits[i.en.kind], i.en.index, mem.bits[i.err.kind], i.err.index,
                             mem.bits[i.alm.kind], i.alm.index) for i in self.config.instances]
            self._wiring_for = mem
        wiring = self._wiring
        for st, (en_bank, en_index, _eb, _ei, _ab, _ai) in zip(self.states, wiring):
            if en_bank[en_index] or st.running or st.waiting or st.en_prev or st.zn:
                return False
        for _en_bank, _en_index, err_bank, err_index, alm_bank, alm_index in wiring:
            err_bank[err_index] = 0
            alm_bank[alm_index] = 0
        return True

    def _scan_instance(self, emu: Emulator, mem: Memory, inst: PidInstance, st: InstanceState) -> None:
        """One scan of one FUN86 box, in the manual's order: EN, the Sn/Zn check (ERR), the first execution, R4005
        latched on EN's rising edge, the wait for every point measured, then the running box's scan."""
        now = emu.now
        en = bool(mem.bits[inst.en.kind][inst.en.index])
        rising = en and not st.en_prev
        st.en_prev = en
        if not en:
            self._not_executed(mem, inst, st)
            return
        if not self._points_valid(mem, inst, st):
            return
        if not st.executed:
            self._first_execution(mem, inst, st)
        if rising:
            self._latch_timing(mem, inst, st, now)
        start = self.readings_start(mem)
        if start is None or not self.all_measured(mem):
            st.running = False
            st.waiting = start is not None  # acts once the temperature modules have measured every point
            return
        st.waiting = False
        st.running = True
        self._run(mem, inst, st, start, now)

    def _not_executed(self, mem: Memory, inst: PidInstance, st: InstanceState) -> None:
        """EN = 0: the instruction is not executed; [our choice] its outputs go off, ERR and ALM are cleared."""
        if st.running or st.zn:
            self._outputs_off(mem, inst, st)
        st.running = st.waiting = False
        mem.bits[inst.err.kind][inst.err.index] = 0
        mem.bits[inst.alm.kind][inst.alm.index] = 0

    def _points_valid(self, mem: Memory, inst: PidInstance, st: InstanceState) -> bool:
        """ERR: Sn/Zn out of range → nothing is done and ERR = 1.  Valid ones that changed start the points
        afresh (the old points' outputs off)."""
        sn, zn = self.sn_zn(mem, inst)
        if not self.valid(sn, zn):
            st.running = st.waiting = False
            mem.bits[inst.err.kind][inst.err.index] = 1
            return False
        mem.bits[inst.err.kind][inst.err.index] = 0
        if (sn, zn) != (st.sn, st.zn):
            if st.zn:
                self._outputs_off(mem, inst, st)
            st.sn, st.zn = sn, zn
            st.new_points(zn)
        return True

    def _first_execution(self, mem: Memory, inst: PidInstance, st: InstanceState) -> None:
        """The first execution loads the default gains 110/17/50 into PR/IR/DR of every point."""
        st.executed = True
        words = mem.words
        for b in range(st.zn):
            for a, value in zip((inst.pr, inst.ir, inst.dr), DEFAULT_GAINS):
                words[a.kind][a.index + b] = value

    def _latch_timing(self, mem: Memory, inst: PidInstance, st: InstanceState, now: float) -> None:
        """EN's rising edge latches R4005 (PID interval, PWM period): PWM cycles and PID steps count from here."""
        st.interval, st.pwm = self.timing(mem.words["R"][_R[reg.PID_TIMING]])
        st.started = now
        # the first PID step: at the edge's scan (instant timing) or up to one interval later (bench timing,
        # each instance at its own phase: hil.sim.timing)
        st.next_pid = now + self.phases.phase(f"fun86:{inst.name}:{inst.en}", st.interval)

    def _run(self, mem: Memory, inst: PidInstance, st: InstanceState, start: Address, now: float) -> None:
        """A running box's scan: the PID step when one is due, the PWM outputs Yn…, the alarm bits."""
        limit = mem.words["R"][_R[reg.PREALARM_LIMIT]]
        high_at = self.loop_threshold(mem) * OUTPUT_FULL
        heating = bool(mem.bits[inst.hc.kind][inst.hc.index])
        pid_due = self.pid_due(st, now)
        view = self._view(mem, inst, st, start, limit, high_at, heating)
        output = self._pid_step(mem, inst, st, view, heating) if pid_due else view.output
        self.drive_outputs(mem, inst, st, now, view.enabled, output, None if pid_due else view)
        # the alarms: this scan's PV — or, with the same registers as the last scan, as that scan left them
        self.alarm_bits(mem, inst, st, view, output, limit, high_at, now, stepped=pid_due)

    def _pid_step(self, mem: Memory, inst: PidInstance, st: InstanceState, view: View, heating: bool) -> np.ndarray:
        """Each PID interval: the control law for every enabled point; a disabled point gets OR = 0 (its integral
        and last PV forgotten); OR written."""
        words, zn, idx = mem.words, st.zn, view.idx
        after = np.zeros(zn, dtype=np.int64)
        if len(idx):
            kc, ki, td = (np.array(words[a.kind][a.index:a.index + zn], dtype=np.int64)[idx]
                          for a in (inst.pr, inst.ir, inst.dr))
            law = self.law(inst, kc, ki, td, heating, st.interval)
            after[idx], st.integral[idx] = self.control(law, st.integral[idx], st.pv_prev[idx], st.has_prev[idx],
                                                        view.sv[idx], view.pv[idx])
            st.pv_prev[idx], st.has_prev[idx] = view.pv[idx], True
        off = ~view.enabled
        st.integral[off], st.has_prev[off] = 0.0, False
        words[inst.or_.kind][inst.or_.index:inst.or_.index + zn] = after.tolist()
        return after

    def _view(self, mem: Memory, inst: PidInstance, st: InstanceState, start: Address, limit: int, high_at: int,
              heating: bool) -> View:
        """The instance's registers as this scan reads them — the last scan's view while they are unchanged (the
        arrays of those unchanged otherwise)."""
        words, zn, sn = mem.words, st.zn, st.sn
        key = (words[start.kind][start.index + sn:start.index + sn + zn], words[inst.sv.kind][inst.sv.index:
               inst.sv.index + zn], words[inst.os.kind][inst.os.index:inst.os.index + zn],
               self.enable_words(mem, sn, zn),
               words[inst.or_.kind][inst.or_.index:inst.or_.index + zn], limit,
               high_at, heating, start)
        view = st.view
        plain = type(self).enabled is Fun86Model.enabled  # (a seam of its own may read other registers)
        if view is not None and view.key == key and plain:
            return view
        same_enable = _unchanged(view, key, 3) if plain else None
        if same_enable is not None:
            enabled, idx = same_enable.enabled, same_enable.idx
        else:
            enabled = np.asarray(self.enabled(mem, sn + np.arange(zn)), dtype=bool)
            idx = np.flatnonzero(enabled)
        every = len(idx) == zn
        pv, sv, os = (kept.pv if (kept := _unchanged(view, key, 0)) else signed(key[0]),
                      kept.sv if (kept := _unchanged(view, key, 1)) else signed(key[1]),
                      kept.os if (kept := _unchanged(view, key, 2)) else signed(key[2]))
        same_output = _unchanged(view, key, 4)
        output = same_output.output if same_output else np.array(key[4], dtype=np.int64)
        waves = same_output.waves if same_output and same_enable else None  # (then the same waveforms)
        st.view = View(key, pv, sv, os, enabled, idx, output, every, slice(None) if every else idx, waves=waves)
        return st.view

    def _outputs_off(self, mem: Memory, inst: PidInstance, st: InstanceState) -> None:
        self._drop_waveforms(inst, st)
        ys = mem.bits[inst.yn.kind]
        ys[inst.yn.index:inst.yn.index + st.zn] = bytes(st.zn)
        st.prealarm.fill(0)
        st.loop_since.fill(math.nan)


