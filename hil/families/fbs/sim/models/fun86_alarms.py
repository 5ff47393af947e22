"""FUN86's alarm bits (manual ch. 20.7; spec/fbs-pid.md PID-WR): each scan, per enabled point, the "temperature
normal" bit (SV − Os ≤ PV ≤ SV + Os, WR+0/1), the high-temperature pre-alarm (PV ≥ R4008 for 10 consecutive scans)
and the heater-loop timer (output ≥ R4006 % for R4007 s while not normal), the warning bits (WR+2/3) and ALM.

Mixed into :class:`hil.families.fbs.sim.models.fun86.Fun86Model`; every rule is a seam a broken PLC overrides
(tests/test_pid_suites.py).  Arrays over an instance's points, as everywhere in the model.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from hil.families.fbs import registers as reg
from hil.families.fbs.address import parse

if TYPE_CHECKING:
    from hil.families.fbs.pid import PidInstance
    from hil.families.fbs.sim.memory import Memory
    from hil.families.fbs.sim.models.fun86_state import InstanceState, View

PREALARM_SCANS = 10
_HEATER_LOOP_PERCENT = parse(reg.HEATER_LOOP_PERCENT).index
_HEATER_LOOP_SECONDS = parse(reg.HEATER_LOOP_SECONDS).index


class AlarmBits:
    """The alarm bits of a FUN86 model: the rules (seams) and the scan's step that applies them."""

    # -- the rules ----------------------------------------------------------------------------------------------
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
        return mem.words["R"][_HEATER_LOOP_PERCENT]

    def loop_elapsed(self, since: np.ndarray, now: float) -> np.ndarray:
        """Seconds the heater-loop condition has held."""
        return now - since

    def bit_position(self, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(word 0/1, bit) of the point at operand offset b (b counts from Sn): WR+0/2 for b < 16, WR+1/3 above."""
        return b // 16, b % 16

    def alarm(self, enabled_not_normal: bool, any_warning: bool) -> bool:
        """ALM: a point out of its band, or a warning."""
        return enabled_not_normal | any_warning

    @staticmethod
    def counting(st: InstanceState) -> bool:
        """Is a pre-alarm count running (then every scan matters)?  A count past 4 × 10 scans has long set its
        warning: it can run on unwatched."""
        return bool(np.count_nonzero((st.prealarm > 0) & (st.prealarm < 4 * PREALARM_SCANS)))

    def track(self, st: InstanceState, idx: slice | np.ndarray, pv: np.ndarray, high: np.ndarray,
              normal: np.ndarray, limit: int, now: float) -> None:
        """Points ``idx`` seeing ``pv`` at the scan at ``now``: the pre-alarm counts, and when the heater-loop
        condition — output ``high`` and PV out of band (not ``normal``) — began (NaN: not holding)."""
        if type(self).prealarm_count is not AlarmBits.prealarm_count or np.count_nonzero(pv >= limit):
            st.prealarm[idx] = self.prealarm_count(st.prealarm[idx], pv, limit)
        else:  # (no reading at R4008: every count back to 0, as the rule says)
            st.prealarm[idx] = 0
        holds = high & ~normal
        since = st.loop_since[idx]
        if not np.count_nonzero(holds) and not np.count_nonzero(since == since):  # (nothing holding, now or before)
            return
        st.loop_since[idx] = np.where(holds, np.where(np.isnan(since), now, since), math.nan)

    def bit_words(self, st: InstanceState, bits: np.ndarray) -> tuple[int, int]:
        """WR+0/1 (or WR+2/3) from a bit per point."""
        if st.weights is None:  # each point's weight in word 0 and in word 1
            word, bit = self.bit_position(np.arange(st.zn))
            st.weights = np.stack((np.where(word == 0, 1 << bit, 0), np.where(word == 1, 1 << bit, 0)))
        both = np.bitwise_or.reduce(np.where(bits[None, :], st.weights, 0), axis=-1) & 0xFFFF
        return both[0], both[1]

    # -- the scan's step ----------------------------------------------------------------------------------------
    def alarm_bits(self, mem: Memory, inst: PidInstance, st: InstanceState, view: View, output: np.ndarray,
                   limit: int, high_at: int, now: float, *, stepped: bool) -> None:
        """WR+0 … WR+3 and ALM at the scan at ``now``, from this scan's PV and ``output`` (``stepped``: a PID step
        wrote it) — or, with the same registers as the last scan (``view``), as that scan left them."""
        new = view.normal is None
        normal = self._normal_bits(st, view) if view.normal is None else view.normal
        if stepped or new:
            self._track_enabled(st, view, normal, output, limit, high_at, now)
        elif not (view.calm and type(self).prealarm_count is AlarmBits.prealarm_count):
            st.prealarm[view.sel] = self.prealarm_count(st.prealarm[view.sel], view.pv[view.sel], limit)
        held = st.loop_since[view.sel]
        timing = bool(np.count_nonzero(held == held))  # a heater-loop timer running (a start not NaN)
        if new or timing or not view.calm or view.warning is None:
            self._warning_bits(mem, st, view, held if timing else None, limit, now)
        wr = inst.wr
        mem.words[wr.kind][wr.index:wr.index + 4] = [int(w) for w in (*view.normal_words, *view.warning_words)]
        any_warning = view.warning is not None and bool(np.count_nonzero(view.warning))
        mem.bits[inst.alm.kind][inst.alm.index] = 1 if self.alarm(view.out_of_band, any_warning) else 0

    def _normal_bits(self, st: InstanceState, view: View) -> np.ndarray:
        """The normal bits of the enabled points, for a view of registers not seen before (kept in ``view``)."""
        normal = view.enabled & np.asarray(self.in_band(view.pv, view.sv, view.os), dtype=bool)
        view.normal = normal
        view.normal_words = self.bit_words(st, normal)
        view.out_of_band = bool(np.count_nonzero(view.enabled & ~normal))
        return normal

    def _track_enabled(self, st: InstanceState, view: View, normal: np.ndarray, output: np.ndarray, limit: int,
                       high_at: int, now: float) -> None:
        """The pre-alarm counts and heater-loop timers of the enabled points; a disabled point's are cleared."""
        sel = view.sel
        self.track(st, sel, view.pv[sel], output[sel] * 100 >= high_at, normal[sel], limit, now)
        if not view.every:
            off = ~view.enabled
            st.prealarm[off], st.loop_since[off] = 0, math.nan

    def _warning_bits(self, mem: Memory, st: InstanceState, view: View, held: np.ndarray | None, limit: int,
                      now: float) -> None:
        """The warning bits: a pre-alarm, or a heater-loop timer (``held``: the enabled points' starts, None when
        none runs) past R4007 s — of enabled points only."""
        warning = np.asarray(self.prealarm(st.prealarm), dtype=bool)
        if held is not None:
            loop_seconds = mem.words["R"][_HEATER_LOOP_SECONDS]
            warning = warning.copy()
            warning[view.sel] |= np.asarray(self.loop_elapsed(held, now) >= loop_seconds, dtype=bool)
        warning = warning & view.enabled
        if view.warning is None or np.count_nonzero(warning != view.warning):
            view.warning, view.warning_words = warning, self.bit_words(st, warning)
        # (calm: no PV at R4008 and no count running — the pre-alarm counts stay 0 while the registers do)
        view.calm = not np.count_nonzero(view.pv[view.sel] >= limit) and not np.count_nonzero(st.prealarm)


__all__ = ["PREALARM_SCANS", "AlarmBits"]
