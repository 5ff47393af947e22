"""The thermal plant's closed form: first-order T through PWM cycles switching on the scan grid, for many (slot,
time) pairs at once — what the plant answers between scans."""

from __future__ import annotations

import numpy as np

from hil.sim.model import scan_grid as grid

#: 0 as a 0-d array: numpy takes a Python number as an operand at a cost several times that of a 0-d array (and
#: this runs once per point group and PID interval)
_ZERO = np.array(0.0)


def cycle_terms(a: np.ndarray, t: np.ndarray, starts: np.ndarray, t_off: np.ndarray, lift: np.ndarray,
                rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The part of :func:`cycles_temperature` that does not depend on when the heater switches off (nor on T(a)):
    (e^(−(t−a)/τ), T_off·(1 − e^(−(t−a)/τ)) − lift·Σ over the cycles of e^(−(t − lo)/τ), lo each cycle's start
    clipped to [a, t]).  ``t``, ``starts`` and ``rate`` (1/τ): a row per cycle (axis 0), or one row for every
    cycle."""
    decay = np.exp((a - t[0]) * rate[0])
    begins = np.exp(np.minimum((np.maximum(starts, a) - t) * rate, _ZERO))
    return decay, t_off - t_off * decay - lift * _cycles_sum(begins)


def cycles_temperature(temp_a: np.ndarray, a: np.ndarray, t: np.ndarray, offs: np.ndarray, lift: np.ndarray,
                       rate: np.ndarray, terms: tuple[np.ndarray, np.ndarray],
                       out: np.ndarray | None = None) -> np.ndarray:
    """T at ``t`` from ``temp_a`` at ``a`` while the heater is on over [starts[c], offs[c]] of every cycle c (a row
    each: ``offs``; ``t`` and ``rate`` (1/τ) too, or one row for all; ``terms``: :func:`cycle_terms` of the starts) and
    off otherwise — the cycles may be any that cover (a, t): one wholly outside adds exactly nothing.  ``lift``: how
    much higher the plant settles with the heater on than off; ``out``: where the result goes, if anywhere.

    A first-order plant: T(t) = T_off + (T(a) − T_off)·e^(−(t−a)/τ) + lift·Σ over the on-segments [lo, hi] within
    [a, t] of e^(−(t−hi)/τ) − e^(−(t−lo)/τ)."""
    decay, base = terms
    ends = np.minimum((np.maximum(offs, a) - t) * rate, _ZERO)
    return np.add(temp_a * decay + base, lift * _cycles_sum(np.exp(ends, out=ends)), out=out)


def _cycles_sum(rows: np.ndarray) -> np.ndarray:
    """The sum of a few rows, in order (cheaper than a reduction for two or three)."""
    total = rows[0]
    for row in rows[1:]:
        total = total + row
    return total


#: cycles solved one by one around an interval's ends (its start falls in the first two, its end in the last
#: three); the whole cycles between them in closed form
_HEAD, _TAIL = 2, 3


def waved_temperature(t0: np.ndarray, temp0: np.ndarray, t: np.ndarray, pwm: np.ndarray, started: np.ndarray,
                      period: np.ndarray, on: np.ndarray, t_on: np.ndarray, t_off: np.ndarray, tau: np.ndarray,
                      st: float) -> np.ndarray:
    """T at ``t`` (≥ t0) of points anchored at (t0, temp0) whose heater follows a waveform on the scan grid: ``pwm``
    False — constant, at T_off; True — on from grid(started + k·period) to grid(started + k·period + on), off for
    the rest of each cycle.  All arguments are arrays over the points (or broadcast), solved at once.

    The partial cycles at either end are solved cycle by cycle (:func:`cycles_temperature`), the whole cycles
    between them in closed form: under one PWM period T → A·T + B (A = e^(−period/τ)), so over n identical periods
    T → T* + (T − T*)·Aⁿ, T* = B / (1 − A) its fixed point."""
    t0, temp0, t = np.asarray(t0, dtype=float), np.asarray(temp0, dtype=float), np.asarray(t, dtype=float)
    later = t > t0
    out = np.where(later, t_off + (temp0 - t_off) * np.exp(-(t - t0) / tau), temp0)
    pulsed = later & pwm
    if not pulsed.any():
        return out
    a, temp, t = t0[pulsed], temp0[pulsed], t[pulsed]
    started, period, on, t_on, t_off, tau = (np.broadcast_to(x, pulsed.shape)[pulsed] if np.ndim(x) == 0 else
                                             x[pulsed] for x in (started, period, on, t_on, t_off, tau))
    k = np.floor((a - started) / period) - 1  # the cycle before the one a falls in (the grid rounds up)
    free = k + np.where(grid(started + (k + 1) * period, st) >= a, 1, 2)  # the first cycle starting at or after a
    free_start = grid(started + free * period, st)
    whole = np.floor((t - free_start) / period) - 1  # whole cycles from there on, the last one left out
    jump = (whole >= 1) & (free_start < t)
    head_end = np.where(jump, free_start, t)
    cyc = k + np.arange(_HEAD + _TAIL)[:, None]
    raw = started + cyc * period
    rate, lift = np.broadcast_to(1.0 / tau, raw.shape), t_on - t_off
    ends = np.broadcast_to(head_end, raw.shape)
    temp = cycles_temperature(temp, a, ends, grid(raw + on, st), lift, rate,
                              cycle_terms(a, ends, grid(raw, st), t_off, lift, rate))
    if jump.any():
        j = jump
        raw0 = started[j] + free[j] * period[j]
        start0, off0, nxt0 = grid(raw0, st), grid(raw0 + on[j], st), grid(started[j] + (free[j] + 1) * period[j], st)
        on_decay, off_decay = np.exp(-(off0 - start0) / tau[j]), np.exp(-(nxt0 - off0) / tau[j])
        gain = on_decay * off_decay
        offset = (t_on[j] - t_on[j] * on_decay) * off_decay + t_off[j] - t_off[j] * off_decay
        with np.errstate(divide="ignore", invalid="ignore"):
            fixed = offset / (1.0 - gain)
            jumped = np.where(gain < 1.0, fixed + (temp[j] - fixed) * gain ** whole[j], temp[j])
        landed = free[j] + whole[j]
        cyc = landed + np.arange(_TAIL)[:, None]
        raw = started[j] + cyc * period[j]
        at = grid(started[j] + landed * period[j], st)
        ends, rates = np.broadcast_to(t[j], raw.shape), np.broadcast_to(rate[0][j], raw.shape)
        temp[j] = cycles_temperature(jumped, at, ends, grid(raw + on[j], st), lift[j], rates,
                                     cycle_terms(at, ends, grid(raw, st), t_off[j], lift[j], rates))
    out[pulsed] = temp
    return out
