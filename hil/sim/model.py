"""What a model of PLC behaviour (RTC, temperature modules, FUN86, plant) plugs into the scan engine with."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from hil.sim.engine import Engine


class Model:
    """Base class: override what you need.

    * :meth:`power_on` — set the model's registers to their power-on values.
    * :meth:`scan` — one PLC scan at virtual time ``emu.now`` (seconds since power-on).
    * :meth:`next_event` — the next virtual time at which this model must see a scan; the engine fast-forwards
      to it when nothing else is pending.  ``math.inf`` means "only when a request comes".  A model that must see
      every scan (counting consecutive scans) returns ``now``.
    """

    name = "model"

    def power_on(self, emu: "Engine") -> None:
        pass

    def scan(self, emu: "Engine") -> None:
        pass

    def next_event(self, now: float) -> float:
        return math.inf
