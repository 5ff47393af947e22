"""What a model of PLC behaviour (RTC, temperature modules, FUN86, plant) plugs into the scan engine with."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Generic, TypeVar

import numpy as np

if TYPE_CHECKING:
    from hil.sim.engine import Engine


Time = TypeVar("Time", float, np.ndarray)
#: the engine a model runs in: a family's models take its emulator (``Model["Emulator"]``), whose memory they read
EngineT = TypeVar("EngineT", bound="Engine")
_SLACK = np.array(1e-6)


def scan_grid(t: Time, scan_time: float) -> Time:
    """The first scan at or after virtual time ``t`` (a float or an array of them), on the scan grid — where a
    fast-forward jump lands, so the scan stepping would take."""
    if isinstance(t, float):  # (the same arithmetic, without numpy's overhead on one number)
        return math.ceil(t / scan_time - 1e-6) * scan_time
    step = np.array(scan_time)  # (a 0-d array: cheaper as an operand than a Python number)
    return np.ceil(t / step - _SLACK) * step


class Model(Generic[EngineT]):
    """Base class: override what you need.

    * :meth:`power_on` — set the model's registers to their power-on values.
    * :meth:`scan` — one PLC scan at virtual time ``emu.now`` (seconds since power-on).
    * :meth:`next_event` — the next virtual time at which this model must see a scan; the engine fast-forwards
      to it when nothing else is pending.  ``math.inf`` means "only when a request comes".  A model that must see
      every scan (counting consecutive scans) returns ``now``.
    """

    name = "model"

    def power_on(self, emu: EngineT) -> None:
        pass

    def scan(self, emu: EngineT) -> None:
        pass

    def next_event(self, now: float) -> float:
        return math.inf
