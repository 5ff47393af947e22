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
Every decision a faulty PLC could get wrong is one small method (the "seams" below), so the harness's tests can
build broken PLCs as tiny subclasses.  The per-point ones take and return arrays over an instance's points: the
points' state is kept in arrays (:class:`InstanceState`), stepped all at once.

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
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from hil.families.fbs import registers as reg
from hil.families.fbs.address import Address, parse
from hil.families.fbs.pid import OUTPUT_FULL, PidConfig, PidInstance, timing_seconds, valid_sn_zn
from hil.families.fbs.sim.models.fun86_state import InstanceState, View

# (the plant's waveforms, which only the emulator needs, model no manual statement: in a module of their own)
from hil.families.fbs.sim.models.fun86_waveforms import PublishedWaveforms
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
PREALARM_SCANS = 10


#: the output's bounds as 0-d arrays: numpy takes a Python number as an operand at a cost several times that of a
#: 0-d array (and a control step over a few dozen points is a dozen such operations, once per PID interval)
_FULL, _LOWEST, _ZERO = np.array(float(OUTPUT_FULL)), np.array(-float(OUTPUT_FULL)), np.array(0.0)


@dataclass(frozen=True)
class Law:
    """The control law's coefficients for some points of an instance (constant while its registers are)."""

    kc: np.ndarray  # Kc
    ki: np.ndarray  # Ki ≠ 0
    every_ki: bool  # Ki ≠ 0 for every point
    integrate: np.ndarray  # Kc·(Ki/100/60)·ts: the integral's change per unit of error
    derivative: np.ndarray  # −Kc·(Td/100·60), signed for heating (+) or cooling (−): the output per unit of slope
    heating: bool
    md1: bool  # Md = 1: the integral runs outside the proportional band too
    ts: float


class Fun86Model(PublishedWaveforms, Model):
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

    def drive(self, enabled: np.ndarray, on: bool) -> np.ndarray:
        """The PWM outputs of points: a disabled point's output is forced off."""
        return enabled & on

    def in_band(self, pv: np.ndarray, sv: np.ndarray, os: np.ndarray) -> np.ndarray:
        """The "temperature normal" rule: SV − Os ≤ PV ≤ SV + Os (edges included)."""
        return (sv - os <= pv) & (pv <= sv + os)

    def prealarm_count(self, count: np.ndarray, pv: np.ndarray, limit: int) -> np.ndarray:
        """Consecutive scans with PV ≥ R4008: one more, or back to 0 on a scan below."""
        return np.where(pv >= limit, count + 1, 0)

    def prealarm(self, count: np.ndarray) -> np.ndarray:
        return count >= PREALARM_SCANS

    def loop_threshold(self, mem: Memory) -> int:
        """R4006: the heater-loop check's high output, in %."""
        return mem.words["R"][_R[reg.HEATER_LOOP_PERCENT]]

    def loop_elapsed(self, since: np.ndarray, now: float) -> np.ndarray:
        """Seconds the heater-loop condition has held."""
        return now - since

    def bit_position(self, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(word 0/1, bit) of the point at operand offset b (b counts from Sn): WR+0/2 for b < 16, WR+1/3 above."""
        return b // 16, b % 16

    def alarm(self, enabled_not_normal: bool, any_warning: bool) -> bool:
        """ALM: a point out of its band, or a warning."""
        return enabled_not_normal | any_warning

    def law(self, inst: PidInstance, kc: np.ndarray, ki: np.ndarray, td: np.ndarray, heating: bool,
            ts: float) -> Law:
        """The PID law's coefficients from the gains (spec: the manual's formula; derivative on PV)."""
        kc = np.asarray(kc, dtype=float)  # (gains are whole numbers: as floats, the arithmetic is the same and
        # each step's operations take operands of one type, without a cast)
        derivative = -kc * (td / 100 * 60) * (1 if heating else -1)
        return Law(kc, ki != 0, bool((ki != 0).all()), kc * (ki / 100 / 60) * ts, derivative, heating, inst.md == 1,
                   ts)

    def control(self, law: Law, integral: np.ndarray, pv_prev: np.ndarray, has_prev: np.ndarray | bool,
                sv: np.ndarray, pv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One PID step: (outputs, integrals) of points at ``pv`` whose integrals and PVs at the last step (where
        ``has_prev``; none: no slope) were ``integral`` and ``pv_prev``.  Md 0 freezes the integral outside the
        proportional band.  Units: 0.1° in, output counts 0–16383 out (as floats)."""
        error = (sv - pv) if law.heating else (pv - sv)
        proportional = law.kc * error
        if has_prev is not True:
            pv_prev = np.where(has_prev, pv_prev, pv)
        derivative = law.derivative * ((pv - pv_prev) / law.ts)
        integrate = law.ki if law.md1 else np.abs(proportional) < _FULL
        if not law.md1 and not law.every_ki:
            integrate &= law.ki
        # (an integral not integrating gains 0.0 and stays within ±16383)
        integral = np.minimum(np.maximum(integral + law.integrate * error * integrate, _LOWEST), _FULL)
        if not law.every_ki:
            integral = np.where(law.ki, integral, 0.0)
        return np.minimum(np.maximum(np.rint(proportional + integral + derivative), _ZERO), _FULL), integral

    # -- helpers ---------------------------------------------------------------------------------------------------
    def sn_zn(self, mem: Memory, inst: PidInstance) -> tuple[int, int]:
        if inst.settable:
            words = mem.words
            return (reg.signed16(words[inst.sn_register.kind][inst.sn_register.index]),
                    reg.signed16(words[inst.zn_register.kind][inst.zn_register.index]))
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

    @staticmethod
    def counting(st: InstanceState) -> bool:
        """Is a pre-alarm count running (then every scan matters)?  A count past 4 × 10 scans has long set its
        warning: it can run on unwatched."""
        return bool(np.count_nonzero((st.prealarm > 0) & (st.prealarm < 4 * PREALARM_SCANS)))

    def next_pwm_edge(self, mem: Memory, inst: PidInstance, st: InstanceState, now: float) -> float:
        """The next PWM edge of the instance's outputs: the next cycle's start, or a point's ON time ending."""
        cycle = self.cycle_start(st, now)
        edges = cycle + self.on_times(st, np.array(mem.words[inst.or_.kind][inst.or_.index:inst.or_.index + st.zn]))
        later = edges > now + 1e-9
        return min(cycle + st.pwm, float(edges[later].min()) if np.count_nonzero(later) else math.inf)

    def scan_for(self, due: float, now: float) -> float:
        """The first scan at or after an event at ``due``, on the scan grid: a jump then takes the very scan that
        stepping scan by scan would (PID samples, PWM edges and PVs seen at the same scans either way)."""
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

    def track(self, st: InstanceState, idx: np.ndarray, pv: np.ndarray, high: np.ndarray, normal: np.ndarray,
              limit: int, now: float) -> None:
        """Points ``idx`` seeing ``pv`` at the scan at ``now``: the pre-alarm counts, and when the heater-loop
        condition — output ``high`` and PV out of band (not ``normal``) — began (NaN: not holding)."""
        if type(self).prealarm_count is not Fun86Model.prealarm_count or np.count_nonzero(pv >= limit):
            st.prealarm[idx] = self.prealarm_count(st.prealarm[idx], pv, limit)
        else:  # (no reading at R4008: every count back to 0, as the rule says)
            st.prealarm[idx] = 0
        holds = high & ~normal
        since = st.loop_since[idx]
        if not np.count_nonzero(holds) and not np.count_nonzero(since == since):  # (nothing holding, now or before)
            return
        st.loop_since[idx] = np.where(holds, np.where(np.isnan(since), now, since), math.nan)

    def bit_words(self, st: InstanceState, bits: np.ndarray) -> tuple:
        """WR+0/1 (or WR+2/3) from a bit per point."""
        if st.weights is None:  # each point's weight in word 0 and in word 1
            word, bit = self.bit_position(np.arange(st.zn))
            st.weights = np.stack((np.where(word == 0, 1 << bit, 0), np.where(word == 1, 1 << bit, 0)))
        both = np.bitwise_or.reduce(np.where(bits[None, :], st.weights, 0), axis=-1) & 0xFFFF
        return both[0], both[1]

    def _scan_instance(self, emu: Emulator, mem: Memory, inst: PidInstance, st: InstanceState) -> None:
        now = emu.now
        bits = mem.bits
        en = bool(bits[inst.en.kind][inst.en.index])
        rising = en and not st.en_prev
        st.en_prev = en
        if not en:
            if st.running or st.zn:
                self._outputs_off(mem, inst, st)
            st.running = st.waiting = False
            bits[inst.err.kind][inst.err.index] = 0
            bits[inst.alm.kind][inst.alm.index] = 0
            return
        sn, zn = self.sn_zn(mem, inst)
        if not self.valid(sn, zn):
            st.running = st.waiting = False
            bits[inst.err.kind][inst.err.index] = 1
            return
        bits[inst.err.kind][inst.err.index] = 0
        if (sn, zn) != (st.sn, st.zn):
            if st.zn:
                self._outputs_off(mem, inst, st)
            st.sn, st.zn = sn, zn
            st.new_points(zn)
        words = mem.words
        if not st.executed:
            st.executed = True
            for b in range(zn):
                for a, value in zip((inst.pr, inst.ir, inst.dr), DEFAULT_GAINS):
                    words[a.kind][a.index + b] = value
        if rising:
            st.interval, st.pwm = self.timing(words["R"][_R[reg.PID_TIMING]])
            st.started = now
            # the first PID step: at the edge's scan (instant timing) or up to one interval later (bench timing,
            # each instance at its own phase: hil.sim.timing)
            st.next_pid = now + self.phases.phase(f"fun86:{inst.name}:{inst.en}", st.interval)
        start = self.readings_start(mem)
        if start is None or not self.all_measured(mem):
            st.running = False
            st.waiting = start is not None  # acts once the temperature modules have measured every point
            return
        st.waiting = False
        st.running = True
        r = words["R"]
        limit = r[_R[reg.PREALARM_LIMIT]]
        loop_seconds = r[_R[reg.HEATER_LOOP_SECONDS]]
        high_at = self.loop_threshold(mem) * OUTPUT_FULL
        heating = bool(bits[inst.hc.kind][inst.hc.index])
        pid_due = self.pid_due(st, now)
        view = self._view(mem, inst, st, start, limit, high_at, heating)
        new = view.normal is None
        pv, sv, os, enabled, idx, before = view.pv, view.sv, view.os, view.enabled, view.idx, view.output
        after = before
        if pid_due:
            after = np.zeros(zn, dtype=np.int64)
            if len(idx):
                gains = [np.array(words[a.kind][a.index:a.index + zn], dtype=np.int64)[idx]
                         for a in (inst.pr, inst.ir, inst.dr)]
                law = self.law(inst, *gains, heating, st.interval)
                after[idx], st.integral[idx] = self.control(law, st.integral[idx], st.pv_prev[idx], st.has_prev[idx],
                                                            sv[idx], pv[idx])
                st.pv_prev[idx], st.has_prev[idx] = pv[idx], True
            off = ~enabled
            st.integral[off], st.has_prev[off] = 0.0, False
            words[inst.or_.kind][inst.or_.index:inst.or_.index + zn] = after.tolist()
        self.drive_outputs(mem, inst, st, now, enabled, after, None if pid_due else view)
        # the alarms: this scan's PV — or, with the same registers as the last scan, as that scan left them
        sel = view.sel
        if new:
            view.normal = enabled & np.asarray(self.in_band(pv, sv, os), dtype=bool)
            view.normal_words = self.bit_words(st, view.normal)
            view.out_of_band = bool(np.count_nonzero(enabled & ~view.normal))
        if pid_due or new:
            self.track(st, sel, pv[sel], after[sel] * 100 >= high_at, view.normal[sel], limit, now)
            if not view.every:
                off = ~enabled
                st.prealarm[off], st.loop_since[off] = 0, math.nan
        elif not (view.calm and type(self).prealarm_count is Fun86Model.prealarm_count):
            st.prealarm[sel] = self.prealarm_count(st.prealarm[sel], pv[sel], limit)
        held = st.loop_since[sel]
        timing = bool(np.count_nonzero(held == held))  # a heater-loop timer running (a start not NaN)
        if new or timing or not view.calm or view.warning is None:
            warning = np.asarray(self.prealarm(st.prealarm), dtype=bool)
            if timing:
                warning = warning.copy()
                warning[sel] |= np.asarray(self.loop_elapsed(held, now) >= loop_seconds, dtype=bool)
            warning = warning & enabled
            if view.warning is None or np.count_nonzero(warning != view.warning):
                view.warning, view.warning_words = warning, self.bit_words(st, warning)
            # (calm: no PV at R4008 and no count running — the pre-alarm counts stay 0 while the registers do)
            view.calm = not np.count_nonzero(pv[sel] >= limit) and not np.count_nonzero(st.prealarm)
        wr = inst.wr
        words[wr.kind][wr.index:wr.index + 4] = [int(w) for w in (*view.normal_words, *view.warning_words)]
        bits[inst.alm.kind][inst.alm.index] = 1 if self.alarm(view.out_of_band, bool(np.count_nonzero(view.warning))) else 0

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
        old = view.key if view is not None else (None,) * len(key)
        if plain and old[3] == key[3]:
            enabled, idx = view.enabled, view.idx
        else:
            enabled = np.asarray(self.enabled(mem, sn + np.arange(zn)), dtype=bool)
            idx = np.flatnonzero(enabled)
        every = len(idx) == zn
        same_output = old[4] == key[4] and old[3] == key[3] and plain  # (then the same waveforms)
        st.view = View(key, *(getattr(view, name) if old[i] == key[i] else signed(key[i])
                               for i, name in ((0, "pv"), (1, "sv"), (2, "os"))),
                        enabled, idx, view.output if old[4] == key[4] else np.array(key[4], dtype=np.int64),
                        every, slice(None) if every else idx, waves=view.waves if same_output else None)
        return st.view

    def drive_outputs(self, mem: Memory, inst: PidInstance, st: InstanceState, now: float, enabled: np.ndarray,
               output: np.ndarray, view: View | None = None) -> None:
        """Yn… at ``now`` from the outputs (ON for OR/16383 of each PWM period), and their published waveforms
        (``view``: the registers as at the last scan — its waveforms, if known, stand)."""
        if view is not None and view.waves is not None:
            waves = view.waves
        else:
            waves = self.waves(st, enabled, output)
            if view is not None:
                view.waves = waves
        ys = mem.bits[inst.yn.kind]
        ys[inst.yn.index:inst.yn.index + st.zn] = self.outputs_at(st, now, *waves)
        self.republish(inst, st, waves)

    def waves(self, st: InstanceState, enabled: np.ndarray, output: np.ndarray) -> tuple[np.ndarray, ...]:
        """(ON seconds of each PWM period, Y when on, Y when off) of the instance's outputs."""
        y_on, y_off = (np.asarray(self.drive(enabled, level), dtype=bool) for level in (True, False))
        if y_on.shape != enabled.shape:
            y_on = np.full(enabled.shape, bool(y_on))
        if y_off.shape != enabled.shape:
            y_off = np.full(enabled.shape, bool(y_off))
        return self.on_times(st, output), y_on, y_off

    @staticmethod
    def on_times(st: InstanceState, output: np.ndarray) -> np.ndarray:
        """Seconds ON of each PWM period for outputs (OR): OR/16383 of the period."""
        return output / _FULL * st.pwm

    @staticmethod
    def outputs_at(st: InstanceState, now: float, on_time: np.ndarray, y_on: np.ndarray, y_off: np.ndarray) -> bytes:
        """Yn… at ``now``: as when on for the first ``on_time`` seconds of each PWM period, else as when off."""
        # the time into the PWM cycle, the cycle found as next_event() finds it (with its 1e-9): a scan it scheduled
        # at a cycle start a rounding error early is in the new cycle, not at the old one's end — else that output
        # is OFF for its ON time and ON for the rest, cycle after cycle
        phase = max(0.0, now - Fun86Model.cycle_start(st, now))
        return np.where(phase < on_time, y_on, y_off).tobytes()  # (bools: bytes 0/1)

    @staticmethod
    def cycle_start(st: InstanceState, now: float) -> float:
        """The start of the PWM cycle ``now`` is in — with 1e-9 to spare, so that a scan scheduled at a cycle's
        start that lands a rounding error early is in that cycle (outputs_at and next_event agree on it)."""
        return st.started + math.floor((now - st.started) / st.pwm + 1e-9) * st.pwm

    def _outputs_off(self, mem: Memory, inst: PidInstance, st: InstanceState) -> None:
        self._drop_waveforms(inst, st)
        ys = mem.bits[inst.yn.kind]
        ys[inst.yn.index:inst.yn.index + st.zn] = bytes(st.zn)
        st.prealarm.fill(0)
        st.loop_since.fill(math.nan)


