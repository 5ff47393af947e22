"""Replaying the readings a FUN86 model did not scan — an emulator speed-up no PLC has: between requests the
virtual-time engine jumps over scans, the temperature model logs the measurements taken meanwhile, and the next
scan replays them (pre-alarm counts, heater-loop starts), each at the scan that would have seen it.  Held to the
scan-by-scan path by tests/test_model_golden*.py; :class:`ReadingsReplay` is mixed into :class:`Fun86Model`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from hil.sim.columns import occurrence
from hil.sim.model import seen_at_skipped_scans

if TYPE_CHECKING:
    from hil.families.fbs.address import Address
    from hil.families.fbs.sim.plc import Emulator


class ReadingsReplay:
    """The log of readings a FUN86 model replays at its next scan."""

    def init_replay(self) -> None:
        self._log: tuple | None = None
        self._last_scan = -math.inf  # when this model last scanned (the readings logged since came after it)

    def collect_log(self, emu: "Emulator", tm) -> None:  # noqa: ANN001 - the temperature model
        """The readings logged for scans skipped since the last: (landed, points, PVs) (see _replayed)."""
        self._log = None
        if tm is not None and tm.log:
            times, points, pvs = (np.concatenate(parts) for parts in zip(*tm.log))
            previous, now, st = self._last_scan, emu.now, emu.scan_time
            if seen_at_skipped_scans(float(times.min()), previous, now, st)[1]:  # (most scans: none at all)
                landed, skipped = seen_at_skipped_scans(times, previous, now, st)
                self._log = (landed[skipped], points[skipped], pvs[skipped])

    def replayed_for(self, start: "Address", sn: int, zn: int, enabled: np.ndarray) -> tuple | None:
        """The logged readings of points Sn… (None: nothing to replay — PVs not from the logged readings)."""
        if self._log is not None and (start.kind, start.index) == self.temperature_model.log_start:
            return self._replayed(sn + np.arange(zn), enabled)
        return None

    def _replayed(self, points: np.ndarray, enabled: np.ndarray) -> tuple | None:
        """The readings of ``points`` (enabled ones) the temperature model logged for the scans skipped since the
        last one — those read at this very scan left out: (rows of PV, rows of the scan each landed at, valid),
        rows in time order, a column per point (None: no such reading).  Where a point has fewer readings than
        others its row is not valid (to be filled with its reading at this scan)."""
        landed, logged, pvs = self._log
        first, n = int(points[0]), len(points)
        b = logged - first
        mine = (b >= 0) & (b < n)
        mine[mine] = enabled[b[mine]]
        if not mine.any():
            return None
        b, landed, pv_cells = b[mine], landed[mine], pvs[mine]
        row = occurrence(b)
        rows = int(row.max()) + 1
        pv, at, valid = np.zeros((rows, n), dtype=np.int64), np.zeros((rows, n)), np.zeros((rows, n), dtype=bool)
        pv[row, b], at[row, b], valid[row, b] = pv_cells, landed, True
        return pv, at, valid

    def readings_replayed(self, last_scan: float) -> None:
        """The temperature model's log of readings was consumed elsewhere, by a batch of scans whose last was at
        ``last_scan``: nothing to replay."""
        self._log = None
        self._last_scan = last_scan

    def _log_off(self) -> bool:
        """Without the temperature model's log of readings, every measurement needs its scan."""
        return self.temperature_model is None or self.temperature_model.log is None
