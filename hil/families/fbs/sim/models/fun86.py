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
build broken PLCs as tiny subclasses.

Time: the model asks for a scan at each PID interval and heater-loop deadline, and for every scan while a
pre-alarm count is running; otherwise the engine jumps.  In between:

* PWM edges need no scan when the thermal plant integrates the published :attr:`Fun86Model.waveforms` exactly
  (no dead time: ``pwm_exact``); otherwise the model asks for a scan at every edge.
* measurements need no scan: the temperature model logs the readings taken between scans, and the next scan replays
  them (pre-alarm count, heater-loop start, each at the scan that would have seen it), unless a reading of an
  enabled point could reach R4008 (the temperature model's hard bound on its readings; the plant clips its noise at
  6 σ for that), a pre-alarm seam is overridden, or there is no log: then every measurement gets its scan.

With EN off it asks for nothing (the default bench's virtual day stays one jump).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable

from hil.families.fbs.address import Address, parse
from hil.sim.model import Model
from hil.families.fbs import registers as reg
from hil.families.fbs.registers import signed16
from hil.families.fbs.pid import OUTPUT_FULL, PidConfig, PidInstance, timing_seconds, valid_sn_zn
from hil.families.fbs.temperature import EXEC_MEASURING, TemperatureConfig, decode_start

if TYPE_CHECKING:
    from hil.families.fbs.sim.plc import Emulator
    from hil.families.fbs.sim.memory import Memory

_R = {name: parse(name).index for name in (reg.PID_SOURCE_KEY, reg.PID_SOURCE, reg.PID_TIMING,
                                           reg.HEATER_LOOP_PERCENT, reg.HEATER_LOOP_SECONDS, reg.PREALARM_LIMIT,
                                           reg.PID_ENABLE_LOW)}
SOURCE_KEY = 0xA55A
DEFAULT_GAINS = (110, 17, 50)  # Kc, Ki, Td loaded at the first execution
PREALARM_SCANS = 10


@dataclass(slots=True)  # (read and written per point on every scan)
class PointState:
    integral: float = 0.0
    pv_prev: int | None = None
    prealarm: int = 0  # consecutive scans with PV ≥ R4008
    loop_since: float | None = None  # when "output ≥ R4006 % and not normal" began


@dataclass
class InstanceState:
    en_prev: bool = False
    executed: bool = False  # first execution done (defaults loaded)
    interval: float = 4.0
    pwm: float = 2.0
    started: float = 0.0  # EN rising edge: PWM cycles and PID intervals count from here
    next_pid: float = math.inf
    running: bool = False  # executing with valid Sn/Zn and every point measured
    waiting: bool = False  # executing, but not every point measured yet
    sn: int = 0
    zn: int = 0
    points: dict[int, PointState] = field(default_factory=dict)


class Fun86Model(Model):
    name = "fun86"

    def __init__(self, config: PidConfig, temperature: TemperatureConfig | None) -> None:
        self.config = config
        self.temperature = temperature
        self.states = [InstanceState() for _ in config.instances]
        self._emu: "Emulator | None" = None
        #: the temperature model's next measurement time (set by build_emulator): PV changes only there
        self.next_measurement: Callable[[], float] | None = None
        #: the temperature model itself (set by build_emulator): its log of readings between scans, its bounds
        self.temperature_model = None
        #: set by the thermal plant when it integrates the PWM waveforms below exactly: no scans at PWM edges
        self.pwm_exact = False
        #: (bit kind, index) of each output Yn… driven now → (started, PWM period, ON seconds, Y when on, Y when off)
        self.waveforms: dict[tuple[str, int], tuple] = {}
        #: bumped whenever :attr:`waveforms` changes (the plant skips its per-point work while it has not)
        self.waveforms_version = 0
        self._wiring: list[tuple] = []  # see _scan_at_rest
        self._wiring_for: "Memory | None" = None

    # -- the seams broken variants override ---------------------------------------------------------------------
    def valid(self, sn: int, zn: int) -> bool:
        """Sn/Zn in range (else ERR)."""
        return valid_sn_zn(sn, zn)

    def timing(self, r4005: int) -> tuple[float, float]:
        """(PID interval, PWM period) in seconds from R4005 (low byte, high byte)."""
        return float(timing_seconds(r4005 & 0xFF)), float(timing_seconds(r4005 >> 8))

    def enabled(self, mem: "Memory", point: int) -> bool:
        """Point's bit in R4012 (points 0–15) or R4013 (16–31)."""
        return bool(mem.words["R"][_R[reg.PID_ENABLE_LOW] + point // 16] >> (point % 16) & 1)

    def drive(self, enabled: bool, on: bool) -> bool:
        """The PWM output of a point: a disabled point's output is forced off."""
        return enabled and on

    def in_band(self, pv: int, sv: int, os: int) -> bool:
        """The "temperature normal" rule: SV − Os ≤ PV ≤ SV + Os (edges included)."""
        return sv - os <= pv <= sv + os

    def prealarm_count(self, count: int, pv: int, limit: int) -> int:
        """Consecutive scans with PV ≥ R4008: one more, or back to 0 on a scan below."""
        return count + 1 if pv >= limit else 0

    def prealarm(self, count: int) -> bool:
        return count >= PREALARM_SCANS

    def loop_threshold(self, mem: "Memory") -> int:
        """R4006: the heater-loop check's high output, in %."""
        return mem.words["R"][_R[reg.HEATER_LOOP_PERCENT]]

    def loop_elapsed(self, since: float, now: float) -> float:
        """Seconds the heater-loop condition has held."""
        return now - since

    def bit_position(self, b: int) -> tuple[int, int]:
        """(word 0/1, bit) of the point at operand offset b (b counts from Sn): WR+0/2 for b < 16, WR+1/3 above."""
        return b // 16, b % 16

    def alarm(self, enabled_not_normal: bool, any_warning: bool) -> bool:
        """ALM: a point out of its band, or a warning."""
        return enabled_not_normal or any_warning

    def control(self, inst: PidInstance, st: PointState, kc: int, ki: int, td: int, sv: int, pv: int,
                heating: bool, ts: float) -> int:
        """One PID step (spec: the manual's formula; derivative on PV; Md 0 freezes the integral outside the
        proportional band).  Units: 0.1° in, output counts 0–16383 out."""
        error = (sv - pv) if heating else (pv - sv)
        proportional = kc * error
        slope = 0.0 if st.pv_prev is None else (pv - st.pv_prev) / ts
        derivative = -kc * (td / 100 * 60) * slope * (1 if heating else -1)
        if ki and (inst.md == 1 or abs(proportional) < OUTPUT_FULL):
            st.integral += kc * (ki / 100 / 60) * ts * error
            st.integral = min(max(st.integral, -OUTPUT_FULL), OUTPUT_FULL)
        if not ki:
            st.integral = 0.0
        st.pv_prev = pv
        return int(min(max(round(proportional + st.integral + derivative), 0), OUTPUT_FULL))

    # -- helpers ---------------------------------------------------------------------------------------------------
    def sn_zn(self, mem: "Memory", inst: PidInstance) -> tuple[int, int]:
        if inst.settable:
            return (signed16(mem.words[inst.sn_register.kind][inst.sn_register.index]),
                    signed16(mem.words[inst.zn_register.kind][inst.zn_register.index]))
        return inst.sn, inst.zn

    def readings_start(self, mem: "Memory") -> Address | None:
        """Where PVs are read: R4004 when R4003 = A55AH and R4004 names R0–R3839 / D0–D3999, else the table's."""
        words = mem.words["R"]
        if words[_R[reg.PID_SOURCE_KEY]] == SOURCE_KEY:
            code = words[_R[reg.PID_SOURCE]]
            if 10000 <= code <= 13839 or 20000 <= code <= 23999:
                return decode_start(code)
        if self.temperature is None:
            return None
        return decode_start(mem.words[self.temperature.table.kind][self.temperature.table.index + 2])

    def all_measured(self, mem: "Memory") -> bool:
        if self.temperature is None:
            return False
        sr = self.temperature.table
        work = decode_start(mem.words[sr.kind][sr.index + 3])
        return work is not None and mem.words[work.kind][work.index] >> 8 == EXEC_MEASURING

    # -- the engine ---------------------------------------------------------------------------------------------
    def power_on(self, emu: "Emulator") -> None:
        self._emu = emu

    def scan(self, emu: "Emulator") -> None:
        mem = emu.memory
        tm = self.temperature_model
        self._log = tm.log if tm is not None and tm.log else None
        if self._scan_at_rest(mem):
            if tm is not None:
                tm.log = None
            return
        for inst, st in zip(self.config.instances, self.states):
            self._scan_instance(emu, mem, inst, st)
            if not st.running:
                self._drop_waveforms(inst, st)
        if tm is not None:
            # log the readings measured until the next scan (replayed there) while any instance runs
            tm.log = {} if any(st.running for st in self.states) else None

    def _scan_at_rest(self, mem: "Memory") -> bool:
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

    def _drop_waveforms(self, inst: PidInstance, st: InstanceState) -> None:
        if self.waveforms:
            for b in range(max(st.zn, 0)):
                if self.waveforms.pop((inst.yn.kind, inst.yn.index + b), None) is not None:
                    self.waveforms_version += 1

    def _replay(self, ps: PointState, entries: list, now: float, scan_time: float, high: bool, sv: int, os: int,
                limit: int) -> None:
        """The scans skipped since the last one, each of which saw a new reading of this point (the readings the
        temperature model logged): the pre-alarm count and the heater-loop start as stepping would leave them."""
        for at, pv in entries:
            landed = math.ceil(at / scan_time - 1e-6) * scan_time
            if landed >= now - scan_time / 2:
                continue  # read at this very scan
            ps.prealarm = self.prealarm_count(ps.prealarm, pv, limit)
            if high and not self.in_band(pv, sv, os):
                if ps.loop_since is None:
                    ps.loop_since = landed
            else:
                ps.loop_since = None

    def _scan_instance(self, emu: "Emulator", mem: "Memory", inst: PidInstance, st: InstanceState) -> None:
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
            st.points = {p: PointState() for p in range(sn, sn + zn)}
        words = mem.words
        if not st.executed:
            st.executed = True
            for b in range(zn):
                for a, value in zip((inst.pr, inst.ir, inst.dr), DEFAULT_GAINS):
                    words[a.kind][a.index + b] = value
        if rising:
            st.interval, st.pwm = self.timing(words["R"][_R[reg.PID_TIMING]])
            st.started = now
            st.next_pid = now
        start = self.readings_start(mem)
        if start is None or not self.all_measured(mem):
            st.running = False
            st.waiting = start is not None  # acts once the temperature modules have measured every point
            return
        st.waiting = False
        st.running = True
        r = words["R"]
        limit = r[_R[reg.PREALARM_LIMIT]]
        loop_percent = self.loop_threshold(mem)
        loop_seconds = r[_R[reg.HEATER_LOOP_SECONDS]]
        heating = bool(bits[inst.hc.kind][inst.hc.index])
        pid_due = now >= st.next_pid - 1e-9
        if pid_due:
            while st.next_pid <= now + 1e-9:
                st.next_pid += st.interval
        # the time into the PWM cycle, the cycle found as next_event() finds it (with its 1e-9): a scan it
        # scheduled at a cycle start a rounding error early is in the new cycle, not at the old one's end —
        # else that output is OFF for its ON time and ON for the rest, cycle after cycle
        phase = max(0.0, now - (st.started + math.floor((now - st.started) / st.pwm + 1e-9) * st.pwm))
        log = self._log
        if log is not None and (start.kind, start.index) != self.temperature_model.log_start:
            log = None  # PVs come from registers of the ladder's choosing (R4003/R4004): they change only at requests
        waveforms = self.waveforms
        driven = {e: (bool(self.drive(e, True)), bool(self.drive(e, False))) for e in (False, True)}
        enabled_of, in_band, count_of, prealarm_of = self.enabled, self.in_band, self.prealarm_count, self.prealarm
        loop_elapsed, bit_position = self.loop_elapsed, self.bit_position
        pvs, pv_base = words[start.kind], start.index + sn
        svs, sv_base = words[inst.sv.kind], inst.sv.index
        oss, os_base = words[inst.os.kind], inst.os.index
        outputs, or_base = words[inst.or_.kind], inst.or_.index
        ys, y_kind, y_base = bits[inst.yn.kind], inst.yn.kind, inst.yn.index
        points, pwm, started = st.points, st.pwm, st.started
        prs, pr_base = words[inst.pr.kind], inst.pr.index
        irs, ir_base = words[inst.ir.kind], inst.ir.index
        drs, dr_base = words[inst.dr.kind], inst.dr.index
        high_at = loop_percent * OUTPUT_FULL
        normal_words, warning_words = [0, 0], [0, 0]
        out_of_band = warning = False
        for b in range(zn):
            point = sn + b
            ps = points[point]
            pv = pvs[pv_base + b]
            pv = pv - 0x10000 if pv & 0x8000 else pv
            sv = svs[sv_base + b]
            sv = sv - 0x10000 if sv & 0x8000 else sv
            os = oss[os_base + b]
            os = os - 0x10000 if os & 0x8000 else os
            enabled = enabled_of(mem, point)
            if log is not None and enabled and point in log:
                self._replay(ps, log[point], now, emu.scan_time, outputs[or_base + b] * 100 >= high_at, sv, os,
                             limit)
            if pid_due:
                if enabled:
                    kc, ki, td = prs[pr_base + b], irs[ir_base + b], drs[dr_base + b]
                    outputs[or_base + b] = self.control(inst, ps, kc, ki, td, sv, pv, heating, st.interval)
                else:
                    outputs[or_base + b] = 0
                    ps.integral, ps.pv_prev = 0.0, None
            value = outputs[or_base + b]
            on_time = value / OUTPUT_FULL * pwm
            y_on, y_off = driven[bool(enabled)]
            ys[y_base + b] = 1 if (y_on if phase < on_time else y_off) else 0
            wave = (started, pwm, on_time, y_on, y_off)
            if waveforms.get((y_kind, y_base + b)) != wave:
                waveforms[(y_kind, y_base + b)] = wave
                self.waveforms_version += 1
            word, bit = bit_position(b)
            if not enabled:
                ps.prealarm, ps.loop_since = 0, None
                continue
            normal = in_band(pv, sv, os)
            if normal:
                normal_words[word] |= 1 << bit
            else:
                out_of_band = True
            ps.prealarm = count_of(ps.prealarm, pv, limit)
            if value * 100 >= high_at and not normal:
                if ps.loop_since is None:
                    ps.loop_since = now
            else:
                ps.loop_since = None
            loop_open = ps.loop_since is not None and loop_elapsed(ps.loop_since, now) >= loop_seconds
            if prealarm_of(ps.prealarm) or loop_open:
                warning_words[word] |= 1 << bit
                warning = True
        wr = inst.wr
        words[wr.kind][wr.index:wr.index + 4] = [normal_words[0] & 0xFFFF, normal_words[1] & 0xFFFF,
                                                  warning_words[0] & 0xFFFF, warning_words[1] & 0xFFFF]
        bits[inst.alm.kind][inst.alm.index] = 1 if self.alarm(out_of_band, warning) else 0

    def _outputs_off(self, mem: "Memory", inst: PidInstance, st: InstanceState) -> None:
        self._drop_waveforms(inst, st)
        ys = mem.bits[inst.yn.kind]
        for b in range(st.zn):
            ys[inst.yn.index + b] = 0
        for ps in st.points.values():
            ps.prealarm, ps.loop_since = 0, None

    def _log_off(self) -> bool:
        """Without the temperature model's log of readings, every measurement needs its scan."""
        return self.temperature_model is None or self.temperature_model.log is None

    def _prealarm_possible(self, mem: "Memory", st: InstanceState) -> bool:
        """Could a reading of an enabled point reach R4008 (then every measurement needs its scan)?"""
        if type(self).prealarm_count is not Fun86Model.prealarm_count or self.temperature_model is None:
            return True
        limit = mem.words["R"][_R[reg.PREALARM_LIMIT]]
        points = [p for p in st.points if self.enabled(mem, p)]
        return bool(points) and self.temperature_model.readings_upper(mem, points) >= limit

    def next_event(self, now: float) -> float:
        mem = self._emu.memory if self._emu is not None else None
        if mem is None:
            return math.inf
        loop_seconds = mem.words["R"][_R[reg.HEATER_LOOP_SECONDS]]
        due = math.inf
        measurements = False  # a scan at every measurement (a PV could reach R4008)
        for inst, st in zip(self.config.instances, self.states):
            if st.waiting and self.next_measurement is not None:
                due = min(due, self.next_measurement())
            if not st.running:
                continue
            for ps in st.points.values():
                if 0 < ps.prealarm < 4 * PREALARM_SCANS:
                    return now  # counting consecutive scans: every scan matters
                if ps.loop_since is not None and ps.loop_since + loop_seconds > now + 1e-9:
                    due = min(due, ps.loop_since + loop_seconds)  # (once open, its bit is recomputed each scan)
            due = min(due, st.next_pid)
            if not measurements:
                measurements = self._prealarm_possible(mem, st)
            if self.pwm_exact:
                continue  # the plant integrates the PWM between scans; the outputs are recomputed at each scan
            # PWM: every cycle start, and the end of each point's ON time within the current cycle
            cycle = st.started + math.floor((now - st.started) / st.pwm + 1e-9) * st.pwm
            due = min(due, cycle + st.pwm)
            outputs = mem.words[inst.or_.kind]
            for b in range(st.zn):
                edge = cycle + outputs[inst.or_.index + b] / OUTPUT_FULL * st.pwm
                if edge > now + 1e-9:
                    due = min(due, edge)
        if due < math.inf and self.next_measurement is not None and (measurements or self._log_off()):
            due = min(due, self.next_measurement())  # PV may cross R4008 or the band there
        if due == math.inf:
            return due
        # The first scan at or after the event, on the scan grid: a jump then takes the very scan that stepping
        # scan by scan would (PID samples, PWM edges and PVs seen at the same scans either way).
        st = self._emu.scan_time
        return max(now, math.ceil(due / st - 1e-6) * st)
