"""The temperature model's side of the emulator's speed-ups — no PLC has these: what a batch of scans run
elsewhere (FUN86's spans, models/span.py) reads and leaves, the hard upper bound of the readings that lets FUN86
skip scans no pre-alarm can need (models/fun86_wakeup.py), the measurement cycles a long virtual-time jump can
skip unseen, and the samples the harness's own tests inspect.

Each is held to the scan-by-scan path of the model (models/temperature.py, the manual's behaviour) by
tests/test_model_golden*.py; :class:`BatchingShortcuts` is mixed into :class:`TemperatureModel`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from hil.families.fbs import registers as reg
from hil.families.fbs.address import Address
from hil.families.fbs.temperature import MAX_MODULES, MAX_POINTS, TABLE_MARKER, to_unit
from hil.families.fbs.sim.models.sensor_inputs import Fixed, Ramp

if TYPE_CHECKING:
    from hil.families.fbs.sim.memory import Memory

_MASK_LOW = int(reg.INSTALLED_LOW[1:])  # R4010: the installed mask (R4010/R4011) the bound's cache is keyed on


@dataclass(frozen=True)
class MeasuringTable:
    """The temperature table as the model reads it while measuring, every point measured once."""

    readings: Address
    work: Address
    measured: tuple  # (module k, first point, table code) of the modules measured
    header: tuple[int, ...]
    count: int  # modules in the table
    total: int  # points in the table


class BatchingShortcuts:
    """The speed-ups' state and interface of a temperature model."""

    #: the model class whose seams the shortcuts assume (a broken variant overriding one takes the slow path)
    plain: ClassVar[type]

    def init_shortcuts(self) -> None:
        self._top = np.full(MAX_POINTS, -math.inf)  # each point's highest sample (−inf: none)
        self._upper_cache: dict[int, tuple] = {}
        #: (points, sources version, R4010/R4011) → the highest of their sources' bounds, all installed
        self._bounds: tuple = ((), None, False)

    def forget_top(self, points: np.ndarray) -> None:
        self._top[points] = -math.inf

    def note_only_sample(self, points: np.ndarray, values: np.ndarray) -> None:
        """Without averaging, each point's highest sample is its only one."""
        self._top[points] = values

    def note_top(self, points: np.ndarray, ring: np.ndarray, count: np.ndarray, n: int) -> None:
        """Each point's highest sample still in its average (the last ``count`` of its ring of ``n``)."""
        self._top[points] = np.where(np.arange(n) >= n - count[points][:, None], ring[points], -math.inf).max(axis=1)

    def skip_unseen(self, next_due: float, now: float, cycle: float, averaging: int, logging: bool) -> float:
        """Where module measurements may resume after a long jump: only the last ``averaging`` cycles can still
        show in a reading, so whole cycles before them are skipped (the multiplexer ends each cycle where it
        began, so the schedule is unchanged) — unless a FUN86 replays the readings (``logging``: it needs them all)."""
        keep = (averaging + 1) * cycle
        if now - next_due > keep and not logging:
            next_due += math.floor((now - next_due - keep) / cycle) * cycle
        return next_due

    def samples(self) -> dict[int, list[float]]:
        """Each point's samples (oldest first) of the averaging, for the points that have any."""
        n = self.config.averaging
        return {p: self._ring[p, n - c:].tolist() for p, c in enumerate(self._count.tolist()) if c}

    def measuring_table(self, mem: "Memory") -> MeasuringTable | None:
        """The table as this model's scan reads it, if it is measuring and every point was measured."""
        words = mem.words[self.config.table.kind]
        sr = self.config.table.index
        if words[sr] != TABLE_MARKER:
            return None
        count = words[sr + 1]
        header = tuple(words[sr:sr + 4 + min(count, MAX_MODULES)])
        state, readings, work, codes, table_modules, total = self._layout(header)
        if state != "measuring" or readings is None or work is None or work.kind not in mem.words:
            return None
        _mismatch, expected, _entries, measured = self._plan(codes, table_modules, words[sr + 2])
        if not expected or not expected <= self._measured:
            return None
        return MeasuringTable(readings, work, measured, header, min(count, MAX_MODULES), total)

    def schedule_state(self) -> tuple:
        """The measurement schedule and samples, to be put back by :meth:`restore_schedule` (a batch computed and
        then dropped for a shorter one moves them)."""
        return list(self._next), list(self._mux), self._ring.copy(), self._count.copy(), self._top.copy()

    def restore_schedule(self, state: tuple) -> None:
        next_due, mux, ring, count, top = state
        self._next, self._mux = list(next_due), list(mux)
        self._ring, self._count, self._top = ring.copy(), count.copy(), top.copy()

    def batch_measured(self, points: np.ndarray, good: np.ndarray, values: np.ndarray, flagged: np.ndarray) -> None:
        """Samples, break bits and measured points as after a batch whose last measurement of each of ``points``
        was ``values`` (in the unit; used where ``good``) with break bits ``flagged``."""
        if self.config.averaging == 1:
            self.average(points[good], values[good])
        if not good.all():
            self._forget(points[~good])
        self._record_results(points.tolist(), flagged.tolist())
        self._quiet = None

    def readings_upper(self, mem: "Memory", points) -> float:  # noqa: ANN001
        """The highest reading any of ``points`` can show from now on (``inf`` when the model cannot tell)."""
        points = np.asarray(list(points), dtype=np.intp)
        key = (tuple(points.tolist()), self._sources_version, tuple(mem.words["R"][_MASK_LOW:_MASK_LOW + 2]))
        if self._bounds[0] != key:  # (the sources' bounds, and whether every point is installed)
            cache = self._upper_cache
            bounds = []
            for point in key[0]:
                source = self.sources.get(point)
                hit = cache.get(point)
                if hit is None or hit[0] is not source:
                    hit = cache[point] = (source, self._source_upper(source))
                bounds.append(hit[1])
            self._bounds = (key, max(bounds, default=-math.inf), bool(np.all(self.installed(mem, points))))
        _key, top, installed = self._bounds
        if len(points):
            top = max(top, float(self._top[points].max()))
        if (type(self).point_result is not self.plain.point_result or type(self)._live is not self.plain._live
                or math.isinf(top) or not installed or any(p in self.broken for p in key[0])):
            return math.inf
        return (math.ceil(top) + 1) * 10 if self.config.rate == "fast" else math.ceil(top * 10) + 1

    def _source_upper(self, source) -> float:  # noqa: ANN001
        """A source's highest value, in the configured unit (``inf`` when unknown)."""
        if isinstance(source, Fixed):
            celsius = source.celsius
        elif isinstance(source, Ramp):  # falling: never above where it started
            celsius = source.high if source.per_s > 0 else min(max(source.start, source.low), source.high)
        elif hasattr(source, "upper_bound"):
            celsius = source.upper_bound()
        else:
            return math.inf
        return math.inf if math.isinf(celsius) else to_unit(celsius, self.config.unit)

