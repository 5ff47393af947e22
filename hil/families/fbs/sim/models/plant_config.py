"""The thermal plant's ``[plant]`` profile section (emulator only): each point's ambient, gain, time constant, dead
time, noise and initial temperature, validated once (:func:`parse_plant`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from hil.bench.schema import Key, Section
from hil.core.errors import ProfileError


def _number(name: str, doc: str, default: float | None, low: float, high: float, unit: str) -> Key:
    return Key(name, float, doc, default, low=low, high=high, unit=unit, live=False)


#: one point's keys: [plant] gives every point's, [plant.points.N] overrides them for point N
_POINT_KEYS = (
    _number("ambient", "The temperature the point settles to with its heater off.", 25.0, -200, 1000, "°C"),
    _number("gain", "How far full heating raises it above ambient.", 300.0, 0, 2000, "°C"),
    _number("tau", "Its time constant.", 300.0, 0.1, 1e6, "s"),
    _number("dead_time", "Its dead time.", 0.0, 0, 3600, "s"),
    _number("noise", "The standard deviation of its measurement noise.", 0.05, 0, 50, "°C"),
    _number("initial", "Its temperature at start (default: ambient).", None, -200, 2000, "°C"),
)
PLANT = Section("plant", "The emulator's thermal plant, one first-order-plus-dead-time loop per temperature "
                "point (emulator only).", (*_POINT_KEYS,
    Key("points", dict, "Per-point overrides: [plant.points.N] with the keys above, N a point 0–31.", {},
        live=False, json={"additionalProperties": {"type": "object"}}),
), family="fbs")


@dataclass(frozen=True)
class PlantPoint:
    """One point's plant (:data:`PLANT` describes each key)."""

    ambient: float = PLANT.default("ambient")
    gain: float = PLANT.default("gain")
    tau: float = PLANT.default("tau")
    dead_time: float = PLANT.default("dead_time")
    noise: float = PLANT.default("noise")
    initial: float | None = PLANT.default("initial")


@dataclass(frozen=True)
class PlantConfig:
    default: PlantPoint = PlantPoint()
    points: dict[int, PlantPoint] | None = None

    def point(self, p: int) -> PlantPoint:
        return (self.points or {}).get(p, self.default)


def parse_plant(section: dict[str, Any], where: str = "<profile>") -> PlantConfig:
    """Validate ``[plant]``; ProfileError names the key."""
    top = PLANT.read(section, where)
    raw = top.pop("points")
    default = PlantPoint(**top)
    points = {}
    for key, table in raw.items():
        if not str(key).isdigit() or not 0 <= int(key) <= 31:
            raise ProfileError(f"{where}: [plant.points.{key}] is not a temperature point 0–31")
        point = Section(f"plant.points.{key}", PLANT.doc, _POINT_KEYS)
        points[int(key)] = PlantPoint(**point.read(table, where, defaults=vars(default)))
    return PlantConfig(default, points)
