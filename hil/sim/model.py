"""What a model of PLC behaviour (RTC, temperature modules, FUN86, plant) plugs into the scan engine with."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, ClassVar, TypeVar

import numpy as np

if TYPE_CHECKING:
    from hil.sim.engine import Engine


Time = TypeVar("Time", float, np.ndarray)
_SLACK = np.array(1e-6)


def scan_grid(t: Time, scan_time: float) -> Time:
    """The first scan at or after virtual time ``t`` (a float or an array of them), on the scan grid — where a
    fast-forward jump lands, so the scan stepping would take."""
    if isinstance(t, float):  # (the same arithmetic, without numpy's overhead on one number)
        return math.ceil(t / scan_time - 1e-6) * scan_time
    step = np.array(scan_time)  # (a 0-d array: cheaper as an operand than a Python number)
    return np.ceil(t / step - _SLACK) * step


def first_scan_after(at: Time, previous: Time, scan_time: float) -> Time:
    """The scan that first sees what happened at ``at``, after the scan at ``previous``: the scan grid's next, but
    never one at or before ``previous`` — a scan train off the grid (a jump clipped at a request's time lands
    between two grid points, and scans follow from there) sees it at ``previous + scan_time``, not at a grid
    point it has already passed (which would make a skipped scan of the very scan that sees it)."""
    landed = scan_grid(at, scan_time)
    if isinstance(landed, float):
        return landed if landed >= previous + scan_time / 2 else previous + scan_time
    return np.where(landed < previous + scan_time / 2, previous + scan_time, landed)


def seen_at_skipped_scans(at: Time, previous: Time, now: Time, scan_time: float) -> tuple[Time, Time]:
    """For what happened at ``at`` after the scan at ``previous``: (the scan that first saw it —
    :func:`first_scan_after` —, whether that was a scan the engine skipped before the one at ``now`` rather than
    that one itself)."""
    landed = first_scan_after(at, previous, scan_time)
    return landed, landed < now - scan_time / 2


class Model:
    """Base class: override what you need.

    * :meth:`power_on` — set the model's registers to their power-on values.
    * :meth:`scan` — one PLC scan at virtual time ``emu.now`` (seconds since power-on).
    * :meth:`next_event` — the next virtual time at which this model must see a scan; the engine fast-forwards
      to it when nothing else is pending.  ``math.inf`` means "only when a request comes".  A model that must see
      every scan (counting consecutive scans) returns ``now``.
    * :meth:`span` — run a stretch of the coming scans itself, in a batch (optional).
    * :meth:`footprint` — the memory elements the model reads or writes at every scan (lets another model's
      batch know that skipping this one's scans changes nothing).
    """

    name = "model"
    #: the model's scans may be computed in batches, and its seams read as this class's own code reads them: the
    #: batchers (a family's ``span``) and caches rely on exactly this code.  Declared by each class for itself,
    #: never inherited: a subclass that overrides a seam (a broken variant) runs scan by scan unless it says so.
    batchable: ClassVar[bool] = False

    def __init_subclass__(cls, **kwargs: object) -> None:
        super().__init_subclass__(**kwargs)
        cls.batchable = bool(cls.__dict__.get("batchable", False))

    def power_on(self, emu: "Engine") -> None:
        pass

    def scan(self, emu: "Engine") -> None:
        pass

    def next_event(self, now: float) -> float:
        return math.inf

    def span(self, engine: "Engine", target: float) -> bool:
        """Run, without scanning the other models, some of the scans the engine would run from ``engine.now``
        towards ``target`` — each landed and ticked on the engine's clock (:meth:`Engine.land`,
        :meth:`Engine.tick`), the observers called after each — and return True; or do nothing and return False.
        Only what no request can see in between may be batched: never the last scan before ``target``."""
        return False

    def footprint(self) -> "frozenset[tuple[str, int]] | None":
        """The (bank, index) elements the model's scans read or write (None: unknown, anything)."""
        return None
