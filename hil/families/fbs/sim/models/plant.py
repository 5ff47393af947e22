"""A thermal plant for the emulator: per temperature point, a heater driven by a PWM output, heat loss to ambient,
optional dead time and seeded measurement noise; faults heater open (no heating) and SSR shorted (full heating).

Model (per point, first order): τ·dT/dt = ambient + gain·u(t − dead_time) − T, u ∈ {0, 1} the heater's state.
``gain`` is how far above ambient full power would settle.  u is what the point's output (Y…) showed at the last
scan, so the plant is exactly as good as the PWM the PLC produces; without dead time, a FUN86 output's PWM is known
between scans (its waveform, switching on the scan grid) and is integrated exactly, so it needs no scans at its edges.
Measurement noise is clipped at ±6 σ.  Between scans (and PWM switches) u is constant, so T is solved
analytically piece by piece: the plant answers T at any time in the current scan window (the temperature model
catches measurements up at their scheduled, past times) and needs no scans of its own.

The state of every point lives in arrays over the heated points (slots), and T is solved for many (slot, time)
pairs at once (:func:`waved_temperature`): the temperature model measures through :meth:`ThermalPlant.measured`.

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

import math
from typing import TYPE_CHECKING

import numpy as np

from hil.core.errors import InvalidValue
from hil.families.fbs.address import Address
from hil.families.fbs.sim.models.fun86 import Fun86Model

# one concept a module: the [plant] section, the noise and the closed form each have their own
from hil.families.fbs.sim.models.plant_config import PlantConfig, PlantPoint
from hil.families.fbs.sim.models.plant_noise import noise_index, normals
from hil.families.fbs.sim.models.plant_solution import waved_temperature
from hil.families.fbs.sim.models.temperature import TemperatureModel
from hil.sim.model import Model

if TYPE_CHECKING:
    from hil.families.fbs.sim.plc import Emulator

FAULTS = ("heater_open", "ssr_short")


class _Heated:
    """One point with dead time: the anchor (t0, T0) at the last switch it saw, and the heater's switch history (u
    in effect at s is the heater state at s − dead_time).  Stepped scan by scan (FUN86 scans at every PWM edge)."""

    __slots__ = ("p", "t0", "temp0", "history")

    def __init__(self, p: PlantPoint, now: float) -> None:
        self.p = p
        self.t0 = now
        self.temp0 = p.ambient if p.initial is None else p.initial
        self.history: list[tuple[float, int]] = [(-math.inf, 0)]  # (time the heater switched, u)

    def temperature(self, t: float) -> float:
        """T at t ≥ t0, integrating over the instants at which the delayed heater state changes."""
        p = self.p
        temp, at = self.temp0, self.t0
        if t <= at:
            return temp
        hist = self.history
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


class PlantSource:
    """A heated point as a temperature source: a callable of time (its measurement, noise included); the
    temperature model measures the points of one ``group`` together (:meth:`ThermalPlant.measured` of their
    slots)."""

    __slots__ = ("plant", "point", "slot")

    def __init__(self, plant: ThermalPlant, point: int, slot: int) -> None:
        self.plant, self.point, self.slot = plant, point, slot

    @property
    def group(self) -> ThermalPlant:
        return self.plant

    def __call__(self, t: float) -> float:
        return float(self.plant.measured(np.array([self.slot]), np.array([self.point]), np.array([t]))[0])


class ThermalPlant(Model["Emulator"]):
    name = "plant"

    def __init__(self, config: PlantConfig, heaters: dict[int, Address], seed: int = 0) -> None:
        """``heaters``: temperature point → the output (Y…) that switches its heater."""
        self.config = config
        self.heaters = dict(heaters)
        self.seed = seed
        #: the heated points in slot order: every per-point array below is indexed by slot
        self.order = list(self.heaters)
        self.slot = {point: i for i, point in enumerate(self.order)}
        params = [config.point(p) for p in self.order]
        self.ambient = np.array([p.ambient for p in params], dtype=float)
        self.gain = np.array([p.gain for p in params], dtype=float)
        self.tau = np.array([p.tau for p in params], dtype=float)
        self.noise = np.array([p.noise for p in params], dtype=float)
        self.initial = np.array([p.ambient if p.initial is None else p.initial for p in params], dtype=float)
        self.normals = normals(seed) if any(p.noise for p in params) else None
        self.faults: dict[str, set[int]] = {name: set() for name in FAULTS}
        #: without dead time the heaters' PWM is integrated exactly between scans (FUN86 then needs no scans at its
        #: PWM edges); with dead time the plant follows the outputs scan by scan (FUN86 scans at every edge)
        self.waved = all(p.dead_time == 0.0 for p in params)
        n = len(self.order)
        # waved: each slot's anchor (t0, T0) and waveform (pwm False: constant u = w_uoff)
        self.t0 = np.zeros(n)
        self.temp0 = self.initial.copy()
        self.w_pwm = np.zeros(n, dtype=bool)
        self.w_started, self.w_period, self.w_on = np.zeros(n), np.ones(n), np.zeros(n)
        self.w_uon, self.w_uoff = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
        self.heated: list[_Heated] = []  # with dead time
        self._wiring: list[tuple] | None = None  # (slot, point, bit bank, index) per heater: _wire
        self._spans: list = []  # (bit bank, first, end) covering every heater output
        self._last_outputs: object = None  # those outputs (and FUN86's waveforms version) at the last fast-path scan
        self._fun86: Fun86Model | None = None
        self._scan_time = 0.01

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

    # -- the solution ------------------------------------------------------------------------------------------
    def temperatures(self, slots: np.ndarray, times: np.ndarray) -> np.ndarray:
        """The true temperatures (no noise) of heated slots at ``times`` (each ≥ the last scan)."""
        if not self.waved:
            heated = self.heated
            return np.array([heated[s].temperature(t) for s, t in zip(slots.tolist(), times.tolist())], dtype=float)
        return waved_temperature(self.t0[slots], self.temp0[slots], times, self.w_pwm[slots], self.w_started[slots],
                                 self.w_period[slots], self.w_on[slots], self.settles_at(slots, self.w_uon[slots]),
                                 self.settles_at(slots, self.w_uoff[slots]), self.tau[slots], self._scan_time)

    def settles_at(self, slots: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Where slots settle under a constant heater power ``u`` (0–1): ambient + gain·u."""
        return self.ambient[slots] + self.gain[slots] * u

    def measurement_noise(self, slots: np.ndarray, points: np.ndarray, times: np.ndarray) -> np.ndarray:
        """The noise on measurements of slots (temperature points ``points``) at ``times``: a function of (seed,
        point, time) only, so a jump and stepping agree (0 without noise)."""
        if self.normals is None:
            return np.zeros(len(points))
        return self.normals[noise_index(self.seed, points, times)] * self.noise[slots]

    def measured(self, slots: np.ndarray, points: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Measurements of heated slots (temperature points ``points``) at ``times``: T plus the measurement noise,
        a function of (seed, point, time) only, so a jump and stepping agree."""
        values = self.temperatures(slots, times)
        if self.normals is None:
            return values
        return values + self.measurement_noise(slots, points, times)

    def temperature(self, point: int, t: float) -> float:
        """The true temperature (no noise) of a heated point at ``t`` (≥ the last scan)."""
        return float(self.temperatures(np.array([self.slot[point]]), np.array([float(t)]))[0])

    def wave(self, slot: int) -> tuple:
        """A waved slot's waveform: ``(u,)`` constant, or ``(started, period, on, u_on, u_off, scan_time)``."""
        if not self.w_pwm[slot]:
            return (int(self.w_uoff[slot]),)
        return (float(self.w_started[slot]), float(self.w_period[slot]), float(self.w_on[slot]),
                int(self.w_uon[slot]), int(self.w_uoff[slot]), self._scan_time)

    def state(self) -> list[tuple]:
        """(t0, T0, waveform — or the switch history with dead time) per heated point, in slot order."""
        if not self.waved:
            return [(h.t0, h.temp0, list(h.history)) for h in self.heated]
        return [(float(self.t0[s]), float(self.temp0[s]), self.wave(s)) for s in range(len(self.order))]

    # -- the engine ---------------------------------------------------------------------------------------------
    def power_on(self, emu: Emulator) -> None:
        temperature = emu.model(TemperatureModel)
        self._fun86 = emu.model(Fun86Model)
        self._scan_time = emu.scan_time
        if self._fun86 is not None:
            self._fun86.pwm_exact = self.waved
        self.t0[:] = emu.now
        self.temp0[:] = self.initial
        self.heated = [] if self.waved else [_Heated(self.config.point(p), emu.now) for p in self.order]
        for point, slot in self.slot.items():
            if temperature is not None and point < temperature.config.points:
                temperature.set_source(point, PlantSource(self, point, slot))

    def set_waves(self, now: float, slots: np.ndarray, pwm: np.ndarray, started: np.ndarray, period: np.ndarray,
                  on: np.ndarray, u_on: np.ndarray, u_off: np.ndarray) -> None:
        """New waveforms for ``slots`` from ``now``: a slot whose waveform changes is re-anchored at now."""
        same = (pwm == self.w_pwm[slots]) & (u_off == self.w_uoff[slots]) & (
            ~pwm | ((started == self.w_started[slots]) & (period == self.w_period[slots]) & (on == self.w_on[slots])
                    & (u_on == self.w_uon[slots])))
        if same.all():
            return
        changed = slots[~same]
        moved = changed[now > self.t0[changed]]
        if len(moved):
            self.temp0[moved] = self.temperatures(moved, np.full(len(moved), now))
            self.t0[moved] = now
        keep = ~same
        self.w_pwm[changed], self.w_started[changed], self.w_period[changed] = pwm[keep], started[keep], period[keep]
        self.w_on[changed], self.w_uon[changed], self.w_uoff[changed] = on[keep], u_on[keep], u_off[keep]

    def scan(self, emu: Emulator) -> None:
        """The heaters follow the outputs as this scan left them: as waveforms (no dead time), else switch by
        switch — the faults and the power seam as they say, or the outputs themselves (``plain``)."""
        wiring = self._wiring if self._wiring is not None else self._wire(emu.memory.bits)
        plain = type(self).power is ThermalPlant.power and not any(self.faults.values())
        if self.waved:
            self._follow_waveforms(emu.now, plain)
        elif plain:
            self._follow_outputs(emu.now, wiring)
        else:
            self._last_outputs = None
            for slot, point, bank, index in wiring:
                self.heated[slot].advance(emu.now, self.power(point, bool(bank[index])))

    def _wire(self, bits: dict[str, bytearray]) -> list[tuple]:
        """(slot, point, bit bank, index) of each heater's output, and the spans of the banks covering them: the
        banks are fixed for the memory's life, so looked up once, at the first scan."""
        self._wiring = [(slot, point, bits[self.heaters[point].kind], self.heaters[point].index)
                        for point, slot in self.slot.items()]
        kinds = {self.heaters[p].kind for p in self.order}
        self._spans = [(bits[kind], min(a.index for a in self.heaters.values() if a.kind == kind),
                        max(a.index for a in self.heaters.values() if a.kind == kind) + 1) for kind in kinds]
        return self._wiring

    def _follow_waveforms(self, now: float, plain: bool) -> None:
        """Without dead time: each point's waveform follows from its output, FUN86's published waveform and the
        faults — with all three as at the last scan (``plain``: no faults), every waveform is as it is."""
        key = None
        if plain:
            key = ([bytes(bank[lo:hi]) for bank, lo, hi in self._spans],
                   self._fun86.waveforms_version if self._fun86 is not None else 0)
            if key == self._last_outputs:
                return
        self._last_outputs = key
        self.set_waves(now, *self.waveforms())

    def _follow_outputs(self, now: float, wiring: list[tuple]) -> None:
        """With dead time and no faults — the common case, without a call per point: u is the output itself; a
        point whose u is unchanged keeps its anchor (what _Heated.advance would do), so outputs unchanged since the
        last such scan mean nothing to do."""
        # (one bytes for all spans — each has a fixed length, so the concatenation tells them apart — built
        # without a comprehension: this runs on every request)
        outputs = b""
        for bank, lo, hi in self._spans:
            outputs += bank[lo:hi]
        if outputs == self._last_outputs:
            return
        heated = self.heated
        for slot, _point, bank, index in wiring:
            if bank[index] != heated[slot].history[-1][1]:
                heated[slot].advance(now, 1 if bank[index] else 0)
        self._last_outputs = outputs

    def waveforms(self) -> tuple[np.ndarray, ...]:
        """(slots, pwm, started, period, on, u_on, u_off) of every slot from its output, FUN86's published
        waveform of that output and the faults."""
        waves: dict[tuple[str, int], tuple] = self._fun86.waveforms if self._fun86 is not None else {}
        wiring = self._wiring if self._wiring is not None else []
        power = self.power
        n = len(wiring)
        waved = np.zeros(n, dtype=bool)
        started, period, on = np.zeros(n), np.ones(n), np.zeros(n)
        lit, dark = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
        for slot, point, bank, index in wiring:
            w = waves.get((self.heaters[point].kind, index))
            if w is None:  # no waveform published: the output as it is
                dark[slot] = power(point, bool(bank[index]))
                continue
            waved[slot] = True
            started[slot], period[slot], on[slot], y_on, y_off = w
            lit[slot], dark[slot] = power(point, bool(y_on)), power(point, bool(y_off))
        pwm, level = self.classify(on, period, lit, dark)
        pwm &= waved
        u_off = np.where(waved, level, dark)
        return (np.arange(n), pwm, np.where(pwm, started, 0.0), np.where(pwm, period, 1.0), np.where(pwm, on, 0.0),
                np.where(pwm, lit, 0), u_off)

    @staticmethod
    def classify(on: np.ndarray, period: np.ndarray, lit: np.ndarray, dark: np.ndarray) -> tuple[np.ndarray, ...]:
        """What a heater does under a PWM waveform (ON ``on`` seconds of each ``period``; power ``lit`` when on,
        ``dark`` when off): (pulsed — a true PWM —, the constant power when not pulsed).  Equal powers, no ON time
        or an ON time of the whole period make it constant."""
        differ, some = lit != dark, on > 0
        return differ & some & (on < period), np.where(differ & some & (on >= period), lit, dark)

    def next_event(self, now: float) -> float:
        return math.inf  # solved analytically between scans; u changes only at scans
