"""When a FUN86 model needs a scan — the virtual-time engine's wake-up hints, no PLC behaviour: a PLC scans all the
time, the emulator only where something can change (a PID interval, a heater-loop deadline, a PWM edge the plant
does not integrate, a measurement that could reach R4008, every scan while a pre-alarm count runs), and runs the
scans at PID intervals in batches (models/span.py).  A wrong hint makes the emulator skip a scan the PLC would
have had: tests/test_model_golden*.py hold it to stepping scan by scan.  :class:`WakeUps` is mixed into
:class:`Fun86Model`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from hil.families.fbs import registers as reg
from hil.families.fbs.address import parse
from hil.sim.model import scan_grid

if TYPE_CHECKING:
    from hil.sim.engine import Engine
    from hil.families.fbs.sim.memory import Memory
    from hil.families.fbs.sim.models.fun86 import InstanceState

_LIMIT = parse(reg.PREALARM_LIMIT).index  # R4008
_LOOP_SECONDS = parse(reg.HEATER_LOOP_SECONDS).index  # R4007


class WakeUps:
    """The scans a FUN86 model asks the engine for."""

    #: the model class whose seams the hints assume (a broken variant overriding one gets every scan)
    plain: ClassVar[type]
    #: the manual's 10 consecutive scans of the pre-alarm (the model's constant)
    prealarm_scans: ClassVar[int]

    def counting(self, st: "InstanceState") -> bool:
        """Is a pre-alarm count running (then every scan matters, and none may be jumped over or batched)?  A
        count past 4 × 10 scans has long set its warning: it can run on unwatched."""
        return bool(np.count_nonzero(st.prealarm)  # (a quick no first: most scans count nothing)
                    and np.count_nonzero((st.prealarm > 0) & (st.prealarm < 4 * self.prealarm_scans)))

    def prealarm_possible(self, mem: "Memory", st: InstanceState) -> bool:
        """Could a reading of an enabled point reach R4008 (then every measurement needs its scan)?"""
        if type(self).prealarm_count is not self.plain.prealarm_count or self.temperature_model is None:
            return True
        limit = mem.words["R"][_LIMIT]
        view = st.view  # (its enabled points, while R4012/R4013 are as it read them)
        if view is not None and view.key[3] == self.enable_words(mem, st.sn, st.zn) and \
                type(self).enabled is self.plain.enabled:
            points = st.sn + view.idx
        else:
            points = st.sn + np.flatnonzero(np.asarray(self.enabled(mem, st.sn + np.arange(st.zn)), dtype=bool))
        return bool(len(points)) and self.temperature_model.readings_upper(mem, points) >= limit

    def next_event(self, now: float) -> float:
        mem = self._emu.memory if self._emu is not None else None
        if mem is None:
            return math.inf
        loop_seconds = mem.words["R"][_LOOP_SECONDS]
        due = math.inf
        measurements = False  # a scan at every measurement (a PV could reach R4008)
        for inst, st in zip(self.config.instances, self.states):
            if st.waiting and self.next_measurement is not None:
                due = min(due, self.next_measurement())
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
            if not measurements:
                measurements = self.prealarm_possible(mem, st)
            if self.pwm_exact:
                continue  # the plant integrates the PWM between scans; the outputs are recomputed at each scan
            # PWM: every cycle start, and the end of each point's ON time within the current cycle
            cycle = self.cycle_start(st, now)
            due = min(due, cycle + st.pwm)
            edges = cycle + self.on_times(st, np.array(mem.words[inst.or_.kind][inst.or_.index:inst.or_.index + st.zn]))
            later = edges > now + 1e-9
            if np.count_nonzero(later):
                due = min(due, float(edges[later].min()))
        if due < math.inf and self.next_measurement is not None and (measurements or self._log_off()):
            due = min(due, self.next_measurement())  # PV may cross R4008 or the band there
        if due == math.inf:
            return due
        return self.scan_for(due, now)

    def scan_for(self, due: float, now: float) -> float:
        """The first scan at or after an event at ``due``, on the scan grid: a jump then takes the very scan that
        stepping scan by scan would (PID samples, PWM edges and PVs seen at the same scans either way)."""
        return max(now, float(scan_grid(due, self._emu.scan_time)))

    def span(self, engine: "Engine", target: float) -> bool:
        """The scans at PID intervals between requests in batches (models/span.py), when nothing else needs one."""
        if not self.pwm_exact or self.temperature_model is None or self.temperature_model.log is None:
            return False  # (scans at PWM edges or at every measurement: none to batch)
        if self.batcher is None or not any(st.running for st in self.states):
            return False
        if not engine.leaves_a_scan(engine.landing(self.next_pid_scan(engine.now), target), target):
            return False  # (no PID scan before the last one, which is the engine's: nothing to batch)
        return self.batcher.run(self, engine, target)

    def next_pid_scan(self, now: float) -> float:
        """The scan of the next PID step of any running instance."""
        return self.scan_for(min(st.next_pid for st in self.states if st.running), now)
