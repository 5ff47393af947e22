"""How a temperature module turns what its sensor sees into a reading (manual ch. 20.1–20.4; spec/fbs-temperature.md):
the source's °C, held within the sensor's range, in the configured unit, averaged over the last ``averaging``
samples, at the rate's resolution (0.1°, or 1° at the fast rate), in 0.1° units.

Mixed into :class:`hil.families.fbs.sim.models.temperature.TemperatureModel` over its inputs (sensor_inputs.py);
``in_unit``, ``resolution`` and ``average`` are seams a broken PLC overrides (tests/test_temperature_suites*.py).
Arrays over measurements, as everywhere in the model.
"""

from __future__ import annotations

import math

import numpy as np

from hil.families.fbs.sim.models.sensor_inputs import SensorInputs
from hil.families.fbs.temperature import MAX_POINTS, SENSOR_BY_CODE, TemperatureConfig, to_unit
from hil.sim.columns import last_of_each, occurrence

_TEN = np.array(10.0)  # (a 0-d array: cheaper as a numpy operand than a Python number)


class Readings(SensorInputs):
    """The readings of a temperature model's working sensors, and the samples their averaging keeps."""

    config: TemperatureConfig

    def init_readings(self, config: TemperatureConfig) -> None:
        self.init_inputs(config)
        #: the last ``averaging`` samples of each point (in the unit), oldest first and right-aligned: the valid
        #: ones are the last _count[point] of its row (the others 0.0, so adding the row in order is their sum)
        self._ring = np.zeros((MAX_POINTS, config.averaging))
        self._count = np.zeros(MAX_POINTS, dtype=np.int64)

    def samples(self) -> dict[int, list[float]]:
        """Each point's samples (oldest first) of the averaging, for the points that have any."""
        n = self.config.averaging
        return {p: self._ring[p, n - c:].tolist() for p, c in enumerate(self._count.tolist()) if c}

    def forget(self, points: np.ndarray) -> None:
        """Drop points' samples ([our choice] a repaired or re-sourced sensor reads its live value at once)."""
        self._count[points] = 0
        self._ring[points] = 0.0

    def _live(self, times: np.ndarray, points: np.ndarray, codes: np.ndarray,
              last: np.ndarray | None = None) -> np.ndarray:
        """The readings of working sensors: source → sensor range → unit → averaging → resolution, in 0.1°
        (``last``: each point's last measurement, if known)."""
        return self.resolution(self.average(points, self.in_unit(self.values(times, points), SENSOR_LOW[codes],
                                                                 SENSOR_HIGH[codes]), last))

    def in_unit(self, celsius: np.ndarray, low: np.ndarray | None, high: np.ndarray | None) -> np.ndarray:
        """Sensor values within the sensors' range (``low``, ``high``; None: known to be within), in the configured
        unit."""
        if low is not None and high is not None:
            celsius = np.minimum(np.maximum(celsius, low), high)
        return to_unit(celsius, self.config.unit)

    def resolution(self, mean: np.ndarray) -> np.ndarray:
        """Averaged values as readings in 0.1° (the fast rate has 1° resolution, still shown in 0.1° units): whole
        numbers, as floats."""
        if self.config.rate == "fast":
            return np.rint(mean) * _TEN
        return np.rint(mean * _TEN)

    def average(self, points: np.ndarray, value: np.ndarray, last: np.ndarray | None = None) -> np.ndarray:
        """Each value's mean with the point's samples before it (the last ``averaging``), the samples updated.

        The sum runs oldest first from 0.0 (not sum(), whose float algorithm changed in Python 3.12: the same
        profile gives the same readings on every Python).  ``last``: each point's last value, if known."""
        ring, count, n = self._ring, self._count, self.config.averaging
        if n == 1:
            last = last_of_each(points) if last is None else last
            ring[points[last], 0] = value[last]
            count[points[last]] = 1
            return value
        mean = np.empty(len(points))
        rounds = occurrence(points)
        for r in range(int(rounds.max()) + 1 if len(points) else 0):
            cols = np.flatnonzero(rounds == r)
            pts = points[cols]
            ring[pts, :-1] = ring[pts, 1:]
            ring[pts, -1] = value[cols]
            count[pts] = np.minimum(count[pts] + 1, n)
            total = np.zeros(len(cols))
            for c in range(n):
                total = total + ring[pts, c]
            mean[cols] = total / count[pts]
        return mean


#: each sensor code's measuring range, °C (unbounded for a code no sensor has)
SENSOR_LOW, SENSOR_HIGH = np.full(256, -math.inf), np.full(256, math.inf)
for _code, _sensor in SENSOR_BY_CODE.items():
    SENSOR_LOW[_code], SENSOR_HIGH[_code] = _sensor.low_c, _sensor.high_c


__all__ = ["SENSOR_HIGH", "SENSOR_LOW", "Readings"]
