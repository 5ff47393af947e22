"""FUN86's time-proportional outputs (manual ch. 20.7; spec/fbs-pid.md PID-PWM): each output Yn… is ON for the
first OR/16383 of every PWM period (R4005's high byte), the periods counted from EN's rising edge; a disabled point's
output is off.  The waveforms this gives are published for the thermal plant (:mod:`.fun86_waveforms`).

Mixed into :class:`hil.families.fbs.sim.models.fun86.Fun86Model`; :meth:`PwmOutputs.drive` and
:meth:`PwmOutputs.waves` are seams a broken PLC overrides (tests/test_pid_suites.py, tests/test_model_golden_edges.py).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from hil.families.fbs.pid import OUTPUT_FULL
from hil.families.fbs.sim.models.fun86_waveforms import PublishedWaveforms

if TYPE_CHECKING:
    from hil.families.fbs.pid import PidInstance
    from hil.families.fbs.sim.memory import Memory
    from hil.families.fbs.sim.models.fun86_state import InstanceState, View

_FULL = np.array(float(OUTPUT_FULL))  # (a 0-d array: numpy's cheaper operand, as in fun86_law)


class PwmOutputs(PublishedWaveforms):
    """The PWM outputs Yn… of a FUN86 model, and their waveforms published for the plant."""

    def drive(self, enabled: np.ndarray, on: bool) -> np.ndarray:
        """The PWM outputs of points: a disabled point's output is forced off."""
        return enabled & on

    def next_pwm_edge(self, mem: Memory, inst: PidInstance, st: InstanceState, now: float) -> float:
        """The next PWM edge of the instance's outputs: the next cycle's start, or a point's ON time ending."""
        cycle = self.cycle_start(st, now)
        edges = cycle + self.on_times(st, np.array(mem.words[inst.or_.kind][inst.or_.index:inst.or_.index + st.zn]))
        later = edges > now + 1e-9
        return min(cycle + st.pwm, float(edges[later].min()) if np.count_nonzero(later) else math.inf)

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
        phase = max(0.0, now - PwmOutputs.cycle_start(st, now))
        return np.where(phase < on_time, y_on, y_off).tobytes()  # (bools: bytes 0/1)

    @staticmethod
    def cycle_start(st: InstanceState, now: float) -> float:
        """The start of the PWM cycle ``now`` is in — with 1e-9 to spare, so that a scan scheduled at a cycle's
        start that lands a rounding error early is in that cycle (outputs_at and next_event agree on it)."""
        return st.started + math.floor((now - st.started) / st.pwm + 1e-9) * st.pwm


__all__ = ["PwmOutputs"]
