"""A thermal plant for the emulator: per temperature point, a heater driven by a PWM output, heat loss to ambient,
optional dead time and seeded measurement noise; faults heater open (no heating) and SSR shorted (full heating).

Model (per point, first order): τ·dT/dt = ambient + gain·u(t − dead_time) − T, u ∈ {0, 1} the heater's state.
``gain`` is how far above ambient full power would settle.  u is what the point's output (Y…) showed at the last
scan, so the plant is exactly as good as the PWM the PLC produces; without dead time, a FUN86 output's PWM is known
between scans (its waveform, switching on the scan grid) and is integrated exactly, so it needs no scans at its edges.
Measurement noise is clipped at ±6 σ.  Between scans (and PWM switches) u is constant, so T is solved
analytically piece by piece: the plant answers T at any time in the current scan window (the temperature model
catches measurements up at their scheduled, past times) and needs no scans of its own.

``[plant]`` (emulator only; a real bench has a real oven)::

    [plant]
    ambient = 25.0     # °C
    gain = 300.0       # °C above ambient at 100 % heater power (steady state)
    tau = 300.0        # s, time constant
    dead_time = 0.0    # s, transport delay between heater and sensor
    noise = 0.05       # °C, standard deviation of the measurement noise (seeded by [emulator] seed)
    initial = 25.0     # °C at power-on (default: ambient)
    [plant.points.3]   # per-point overrides of any key above
    gain = 400.0

Heaters: the point controlled by a FUN86 instance (``[pid]``) is heated by that instance's output Yn + (p − Sn).
"""

from __future__ import annotations

import functools
import math
import random
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

from hil.families.fbs.address import Address
from hil.sim.model import Model
from hil.core.errors import InvalidValue, ProfileError

if TYPE_CHECKING:
    from hil.families.fbs.sim.plc import Emulator

FAULTS = ("heater_open", "ssr_short")


@dataclass(frozen=True)
class PlantPoint:
    ambient: float = 25.0
    gain: float = 300.0
    tau: float = 300.0
    dead_time: float = 0.0
    noise: float = 0.05
    initial: float | None = None


@dataclass(frozen=True)
class PlantConfig:
    default: PlantPoint = PlantPoint()
    points: dict[int, PlantPoint] | None = None

    def point(self, p: int) -> PlantPoint:
        return (self.points or {}).get(p, self.default)


_LIMITS = {"ambient": (-200.0, 1000.0), "gain": (0.0, 2000.0), "tau": (0.1, 1e6), "dead_time": (0.0, 3600.0),
           "noise": (0.0, 50.0), "initial": (-200.0, 2000.0)}


def parse_plant(section: dict[str, Any], where: str = "<profile>") -> PlantConfig:
    """Validate ``[plant]``; ProfileError names the key."""
    def values(table: dict[str, Any], label: str, base: PlantPoint) -> PlantPoint:
        out = {}
        for key, value in table.items():
            if key not in _LIMITS:
                raise ProfileError(f"{where}: [{label}] unknown key {key!r} (known: {', '.join(_LIMITS)})")
            low, high = _LIMITS[key]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not low <= value <= high:
                raise ProfileError(f"{where}: [{label}] {key}: must be a number {low:g}–{high:g}, not {value!r}")
            out[key] = float(value)
        return replace(base, **out)

    if not isinstance(section, dict):
        raise ProfileError(f"{where}: [plant] must be a table")
    top = {k: v for k, v in section.items() if k != "points"}
    default = values(top, "plant", PlantPoint())
    raw = section.get("points", {})
    if not isinstance(raw, dict):
        raise ProfileError(f"{where}: [plant] points must be a table of point → overrides ([plant.points.3])")
    points = {}
    for key, table in raw.items():
        if not str(key).isdigit() or not 0 <= int(key) <= 31:
            raise ProfileError(f"{where}: [plant.points.{key}] is not a temperature point 0–31")
        if not isinstance(table, dict):
            raise ProfileError(f"{where}: [plant.points.{key}] must be a table")
        points[int(key)] = values(table, f"plant.points.{key}", default)
    return PlantConfig(default, points)


class _Heated:
    """One point: the anchor (t0, T0) at the last scan, and the heater's switch history (for the dead time)."""

    __slots__ = ("p", "t0", "temp0", "history", "seed", "normals")

    def __init__(self, p: PlantPoint, now: float, seed: int) -> None:
        self.p = p
        self.t0 = now
        self.temp0 = p.ambient if p.initial is None else p.initial
        self.history: list[tuple[float, int]] = [(-math.inf, 0)]  # (time the heater switched, u)
        self.seed = seed
        self.normals = _normals(seed) if p.noise else None

    def temperature(self, t: float) -> float:
        """T at t ≥ t0, integrating over the instants at which the delayed heater state changes."""
        p = self.p
        temp, at = self.temp0, self.t0
        if t <= at:
            return temp
        hist = self.history
        # u in effect at time s is the heater state at s − dead_time
        k = len(hist) - 1
        while k > 0 and hist[k][0] + p.dead_time > at:
            k -= 1
        while at < t:
            nxt = hist[k + 1][0] + p.dead_time if k + 1 < len(hist) else math.inf
            end = min(nxt, t)
            target = p.ambient + p.gain * hist[k][1]
            temp = target + (temp - target) * math.exp(-(end - at) / p.tau)
            at = end
            k += 1
        return temp

    def advance(self, now: float, u: int) -> None:
        if u == self.history[-1][1]:
            return  # nothing changes: the anchor stays and T keeps being solved from it
        if now > self.t0:
            self.temp0 = self.temperature(now)
            self.t0 = now
        self.history.append((now, u))
        # forget switches whose effect is entirely before the anchor (keep the one in effect)
        cut = self.t0 - self.p.dead_time
        while len(self.history) > 1 and self.history[1][0] <= cut:
            self.history.pop(0)

    def measured(self, point: int, t: float) -> float:
        """T at t plus the measurement's noise: a function of (seed, point, time) only, so a jump and stepping
        agree."""
        normals = self.normals
        if normals is None:
            return self.temperature(t)
        return self.temperature(t) + normals[_noise_index(self.seed, point, t)] * self.p.noise

    def upper(self) -> float:
        """No measurement of this point ever exceeds this (T stays between its start, ambient and full power)."""
        p = self.p
        start = p.ambient if p.initial is None else p.initial
        return max(start, p.ambient, p.ambient + p.gain) + NOISE_CLIP * p.noise


#: measurement noise is clipped at this many standard deviations (so a reading has a hard bound: the FUN86 model
#: can then skip the scans at measurements that can never reach the pre-alarm limit)
NOISE_CLIP = 6.0


_NORMALS: dict[int, list[float]] = {}


def _normals(seed: int) -> list[float]:
    """65536 standard normal values, clipped at ±NOISE_CLIP, drawn once per seed."""
    table = _NORMALS.get(seed)
    if table is None:
        rng = random.Random(seed)
        table = _NORMALS[seed] = [min(max(rng.gauss(0.0, 1.0), -NOISE_CLIP), NOISE_CLIP) for _ in range(65536)]
    return table


_MASK64 = (1 << 64) - 1


def _noise_index(seed: int, point: int, t: float) -> int:
    """Which of the 65536 normals a measurement at ``t`` draws: splitmix64's finaliser over (t in µs, point, seed),
    integer arithmetic (exact for any seed: Python ints, masked to 64 bits)."""
    x = (round(t * 1000000.0) * 0x9E3779B97F4A7C15 + point * 0xBF58476D1CE4E5B9 + seed * 0x94D049BB133111EB) & _MASK64
    x ^= x >> 30
    x = x * 0xBF58476D1CE4E5B9 & _MASK64
    x ^= x >> 27
    x = x * 0x94D049BB133111EB & _MASK64
    x ^= x >> 31
    return x & 0xFFFF


def _grid(x: float, st: float) -> float:
    """The first scan at or after virtual time x, on the scan grid (as the engine's fast-forward lands)."""
    return math.ceil(x / st - 1e-6) * st


class _Waved:
    """One point without dead time whose heater follows a known waveform between scans: the anchor (t0, T0) moves
    only when the waveform changes (a scan with a new PID output, a fault, a new output), and T at any later time
    is solved through the PWM's switches, on the scan grid (where stepping would switch): the partial cycles at
    either end segment by segment, the whole cycles between them in closed form.

    The waveform: ``(u,)`` constant, or ``(started, period, on, u_on, u_off, scan_time)``: u_on from
    grid(started + k·period) to grid(started + k·period + on), u_off for the rest of each cycle."""

    __slots__ = ("p", "t0", "temp0", "wave", "seed", "normals")

    def __init__(self, p: PlantPoint, now: float, seed: int) -> None:
        self.p = p
        self.t0 = now
        self.temp0 = p.ambient if p.initial is None else p.initial
        self.wave: tuple = (0,)
        self.seed = seed
        self.normals = _normals(seed) if p.noise else None

    def temperature(self, t: float) -> float:
        temp, a = self.temp0, self.t0
        if t <= a:
            return temp
        p = self.p
        wave = self.wave
        tau = p.tau
        exp = math.exp
        if len(wave) == 1:
            target = p.ambient + p.gain * wave[0]
            return target + (temp - target) * exp(-(t - a) / tau)
        started, period, on, u_on, u_off, st = wave
        t_on, t_off = p.ambient + p.gain * u_on, p.ambient + p.gain * u_off
        ceil = math.ceil
        k = math.floor((a - started) / period) - 1
        start = ceil((started + k * period) / st - 1e-6) * st
        off = ceil((started + k * period + on) / st - 1e-6) * st
        nxt = ceil((started + (k + 1) * period) / st - 1e-6) * st
        while start < t:
            whole = math.floor((t - start) / period) - 1  # whole cycles from this one on, the last one left out
            if whole >= 1 and start >= a:
                # A first-order plant under one PWM period is the affine map T → A·T + B (A = e^(−period/τ)): over
                # `whole` identical periods T → T* + (T − T*)·A^whole, T* = B / (1 − A) its fixed point.
                on_decay, off_decay = exp(-(off - start) / tau), exp(-(nxt - off) / tau)
                gain_ = on_decay * off_decay
                offset = (t_on - t_on * on_decay) * off_decay + t_off - t_off * off_decay
                if gain_ < 1.0:
                    fixed = offset / (1.0 - gain_)
                    temp = fixed + (temp - fixed) * gain_ ** whole
                k += whole
                start = ceil((started + k * period) / st - 1e-6) * st
                off = ceil((started + k * period + on) / st - 1e-6) * st
                nxt = ceil((started + (k + 1) * period) / st - 1e-6) * st
                continue
            lo, hi = (start if start > a else a), (off if off < t else t)
            if hi > lo:
                temp = t_on + (temp - t_on) * exp(-(hi - lo) / tau)
            lo, hi = (off if off > a else a), (nxt if nxt < t else t)
            if hi > lo:
                temp = t_off + (temp - t_off) * exp(-(hi - lo) / tau)
            k += 1
            start = nxt
            if start >= t:
                break
            off = ceil((started + k * period + on) / st - 1e-6) * st
            nxt = ceil((started + (k + 1) * period) / st - 1e-6) * st
        return temp

    def set_wave(self, now: float, wave: tuple) -> None:
        if wave == self.wave:
            return
        if now > self.t0:
            self.temp0 = self.temperature(now)
            self.t0 = now
        self.wave = wave

    measured = _Heated.measured  # (its own temperature(), the same noise)
    upper = _Heated.upper


def _source(heated, point: int) -> functools.partial:  # noqa: ANN001
    """A heated point as a temperature source: a callable of time (its measurement, called without a Python frame
    of its own — the temperature model calls it ten times a second of virtual time), with a hard upper bound."""
    source = functools.partial(heated.measured, point)
    source.upper_bound = heated.upper
    return source


class ThermalPlant(Model):
    name = "plant"

    def __init__(self, config: PlantConfig, heaters: dict[int, Address], seed: int = 0) -> None:
        """``heaters``: temperature point → the output (Y…) that switches its heater."""
        self.config = config
        self.heaters = dict(heaters)
        self.seed = seed
        self.points: dict[int, _Heated] = {}
        self.faults: dict[str, set[int]] = {name: set() for name in FAULTS}
        self._wiring: list | None = None  # (point, state, bit bank, index) per heater, built at the first scan
        self._spans: list = []  # (bit bank, first, end) covering every heater output
        self._last_outputs: object = None  # those outputs (and FUN86's waveforms version) at the last fast-path scan
        self._fun86 = None
        self._scan_time = 0.01
        self.waved = False

    # -- faults (injectors) ------------------------------------------------------------------------------------------
    def set_fault(self, fault: str, point: int, on: bool) -> None:
        if fault not in self.faults:
            raise InvalidValue(f"unknown plant fault {fault!r} (known: {', '.join(FAULTS)})")
        if point not in self.heaters:
            raise InvalidValue(f"temperature point {point} has no heater in the plant (heated: "
                             f"{sorted(self.heaters)})")
        (self.faults[fault].add if on else self.faults[fault].discard)(point)

    # -- seam --------------------------------------------------------------------------------------------------
    def power(self, point: int, output: bool) -> int:
        """The heater's state from its output and the faults: open → off, shorted SSR → on."""
        if point in self.faults["heater_open"]:
            return 0
        if point in self.faults["ssr_short"]:
            return 1
        return 1 if output else 0

    def temperature(self, point: int, t: float) -> float:
        """The true temperature (no noise) of a heated point at ``t`` (≥ the last scan)."""
        return self.points[point].temperature(t)

    # -- the engine ---------------------------------------------------------------------------------------------
    def power_on(self, emu: "Emulator") -> None:
        from hil.families.fbs.sim.models.temperature import TemperatureModel
        temperature = emu.model(TemperatureModel)
        from hil.families.fbs.sim.models.fun86 import Fun86Model
        self._fun86 = emu.model(Fun86Model)
        self._scan_time = emu.scan_time
        #: without dead time the heaters' PWM is integrated exactly between scans (FUN86 then needs no scans at its
        #: PWM edges); with dead time the plant follows the outputs scan by scan (FUN86 scans at every edge)
        self.waved = all(self.config.point(p).dead_time == 0.0 for p in self.heaters)
        if self._fun86 is not None:
            self._fun86.pwm_exact = self.waved
        for point in self.heaters:
            heated = (_Waved if self.waved else _Heated)(self.config.point(point), emu.now, self.seed)
            self.points[point] = heated
            if temperature is not None and point < temperature.config.points:
                temperature.set_source(point, _source(heated, point))

    def scan(self, emu: "Emulator") -> None:
        y = emu.memory.bits
        now = emu.now
        if self._wiring is None:
            self._wiring = [(point, heated, y[self.heaters[point].kind], self.heaters[point].index)
                            for point, heated in self.points.items()]
            kinds = {self.heaters[p].kind for p in self.points}
            self._spans = [(y[kind], min(a.index for a in self.heaters.values() if a.kind == kind),
                            max(a.index for a in self.heaters.values() if a.kind == kind) + 1) for kind in kinds]
        if self.waved:
            # each point's waveform follows from its output, FUN86's published waveform and the faults: with all
            # three as at the last scan, every set_wave below would find its waveform unchanged
            key = None
            if type(self).power is ThermalPlant.power and not any(self.faults.values()):
                key = ([bytes(bank[lo:hi]) for bank, lo, hi in self._spans],
                       self._fun86.waveforms_version if self._fun86 is not None else 0)
                if key == self._last_outputs:
                    return
            self._last_outputs = key
            waves = self._fun86.waveforms if self._fun86 is not None else {}
            power, st = self.power, self._scan_time
            for point, heated, bank, index in self._wiring:
                w = waves.get((self.heaters[point].kind, index))
                if w is None:
                    wave = (power(point, bool(bank[index])),)
                else:
                    started, period, on, y_on, y_off = w
                    u_on, u_off = power(point, bool(y_on)), power(point, bool(y_off))
                    if u_on == u_off or on <= 0:
                        wave = (u_off,)
                    elif on >= period:
                        wave = (u_on,)
                    else:
                        wave = (started, period, on, u_on, u_off, st)
                heated.set_wave(now, wave)
            return
        if type(self).power is ThermalPlant.power and not any(self.faults.values()):
            # the common case, without a call per point: u is the output itself; a point whose u is unchanged
            # keeps its anchor (what _Heated.advance would do), so outputs unchanged since the last such scan
            # mean nothing to do
            # (one bytes for all spans — each has a fixed length, so the concatenation tells them apart — built
            # without a comprehension: this runs on every request)
            outputs = b""
            for bank, lo, hi in self._spans:
                outputs += bank[lo:hi]
            if outputs == self._last_outputs:
                return
            for _point, heated, bank, index in self._wiring:
                if bank[index] != heated.history[-1][1]:
                    heated.advance(now, 1 if bank[index] else 0)
            self._last_outputs = outputs
            return
        self._last_outputs = None
        for point, heated, bank, index in self._wiring:
            heated.advance(now, self.power(point, bool(bank[index])))

    def next_event(self, now: float) -> float:
        return math.inf  # solved analytically between scans; u changes only at scans
