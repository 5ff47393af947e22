"""What the emulator's temperature sensors are exposed to — the simulated world, not the PLC: each point's true
temperature (a *source*: :class:`Fixed`, :class:`Ramp`, or a thermal plant's point, models/plant.py), the defaults
a profile leaves open, and the faults a bench's rig injects on a sensor (an open circuit).

The FBs manual says nothing of any of it: a real bench has real sensors, ovens and a relay that opens a
thermocouple.  :class:`SensorInputs` is what the temperature model (models/temperature.py, the manual's behaviour)
measures through — :meth:`SensorInputs.values` — and where the harness's fault injectors and the plant act.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, cast

import numpy as np

from hil.core.errors import InvalidValue
from hil.families.fbs.temperature import MAX_POINTS, TemperatureConfig

Source = Callable[[float], float]  # virtual seconds since power-on → true temperature, °C


class GroupMember(Protocol):
    """A source measured together with the others of its ``group`` (a thermal plant's point, its ``slot`` there):
    ``group.measured(slots, points, times)``."""

    group: Any
    slot: int

    def __call__(self, t: float) -> float: ...


@dataclass(frozen=True)
class Fixed:
    celsius: float

    def __call__(self, t: float) -> float:
        return self.celsius


@dataclass(frozen=True)
class Ramp:
    start: float
    per_s: float
    low: float = -math.inf
    high: float = math.inf

    def __call__(self, t: float) -> float:
        return min(max(self.start + self.per_s * t, self.low), self.high)


def source_from_spec(spec: dict) -> Source:
    if spec["kind"] == "fixed":
        return Fixed(float(spec["celsius"]))
    return Ramp(float(spec["start"]), float(spec["per_s"]), float(spec.get("low", -math.inf)),
                float(spec.get("high", math.inf)))


def default_sources(config: TemperatureConfig) -> dict[int, Source]:
    """Each fitted point's source when nothing else is said: a fixed temperature inside its sensor's range (25 °C
    plus 0.3 °C per point, where 25 °C is in range), the profile's reference points and its ``sources``."""
    sources: dict[int, Source] = {}
    for point in range(config.points):
        _, module = config.point_module(point)
        low, high = module.sensor.low_c, module.sensor.high_c
        base = 25.0 if low <= 25.0 <= high else low + 50.0
        sources[point] = Fixed(round(base + 0.3 * point, 1))
    for point, celsius in config.reference.items():  # (a bench's calibrator holds these points there)
        sources[point] = Fixed(celsius)
    for point, spec in config.sources.items():
        sources[point] = source_from_spec(spec)
    return sources


class SensorInputs:
    """The sources and open circuits of a temperature model's points (under the readings' pipeline,
    models/temperature_readings.py, whose :meth:`forget` drops a re-sourced point's samples)."""

    sources: dict[int, Source]
    broken: set[int]

    def init_inputs(self, config: TemperatureConfig) -> None:
        self.sources = default_sources(config)
        self.broken = set()
        self._sources_version = 0  # bumped by set_source (values caches what the sources are)
        self._slots: tuple = (-1, None, None)  # (sources version, plant, slot per point): see _plant_slots

    def set_source(self, point: int, source: Source) -> None:
        self._check_point(point)
        self.sources[point] = source
        self._sources_version += 1
        self.forget(np.array([point]))

    def forget(self, points: np.ndarray) -> None:
        """Drop what is kept of ``points``' earlier measurements (nothing here: the readings keep samples)."""

    def open(self, point: int) -> None:
        """Open point's sensor circuit (a broken thermocouple); seen at the point's next measurement."""
        self._check_point(point)
        self.broken.add(point)

    def repair(self, point: int) -> None:
        self._check_point(point)
        self.broken.discard(point)

    @staticmethod
    def _check_point(point: int) -> None:
        if not 0 <= point < MAX_POINTS:
            raise InvalidValue(f"temperature point {point} is outside 0–{MAX_POINTS - 1}")

    def values(self, times: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Each point's source at its time, °C.  Sources of one group (a source with ``group`` and ``slot``, e.g.
        a thermal plant's points) are measured together: ``group.measured(slots, points, times)``."""
        plant, slots = self._plant_slots()
        if plant is not None:
            slot = slots[points]
            if (slot >= 0).all():
                return plant.measured(slot, points, times)
        out = np.empty(len(points))
        sources = [self.sources[p] for p in points.tolist()]
        plants: dict[int, list[int]] = {}
        members = cast(list[GroupMember], sources)  # (those with a group: the others are not asked for one)
        for i, source in enumerate(sources):
            if getattr(source, "group", None) is not None:
                plants.setdefault(id(members[i].group), []).append(i)
            else:
                out[i] = source(float(times[i]))
        for columns in plants.values():
            cols = np.array(columns)
            group = members[columns[0]].group
            out[cols] = group.measured(np.array([members[i].slot for i in columns]), points[cols], times[cols])
        return out

    def _plant_slots(self) -> tuple:
        """(a group of sources — a plant —, the slot of each point in it — −1 for a point with another source), for
        the group with the most points."""
        if self._slots[0] != self._sources_version:
            counts: dict[int, list] = {}
            for source in self.sources.values():
                group = getattr(source, "group", None)
                if group is not None:
                    counts.setdefault(id(group), [group, 0])[1] += 1
            plant = max(counts.values(), key=lambda entry: entry[1])[0] if counts else None
            self._slots = (self._sources_version, plant, self.plant_slots(plant))
        return self._slots[1], self._slots[2]

    def plant_slots(self, group: object) -> np.ndarray:
        """Each point's slot in ``group`` (a plant its sources are measured through), −1 for a point with another
        source."""
        slots = np.full(MAX_POINTS, -1)
        for point, source in self.sources.items():
            if group is not None and getattr(source, "group", None) is group:
                slots[point] = cast(GroupMember, source).slot
        return slots

