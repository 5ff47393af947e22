"""The thermal plant's ``[plant]`` profile section (emulator only): each point's ambient, gain, time constant, dead
time, noise and initial temperature, validated once (:func:`parse_plant`)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from hil.core.errors import ProfileError


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
