"""The state a FUN86 model keeps per instance between scans — its own module so that the model and its helpers
(models/fun86_waveforms.py) both take it from below, neither from the other."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


def _none() -> np.ndarray:
    return np.zeros(0)


@dataclass
class InstanceState:
    en_prev: bool = False
    executed: bool = False  # first execution done (defaults loaded)
    interval: float = 4.0
    pwm: float = 2.0
    started: float = 0.0  # EN rising edge: PWM cycles and PID intervals count from here
    next_pid: float = math.inf
    running: bool = False  # executing with valid Sn/Zn and every point measured
    waiting: bool = False  # executing, but not every point measured yet
    sn: int = 0
    zn: int = 0
    # per point b (point Sn + b):
    integral: np.ndarray = field(default_factory=_none)
    pv_prev: np.ndarray = field(default_factory=_none)  # PV at the last PID step (where has_prev)
    has_prev: np.ndarray = field(default_factory=_none)
    prealarm: np.ndarray = field(default_factory=_none)  # consecutive scans with PV ≥ R4008
    loop_since: np.ndarray = field(default_factory=_none)  # when "output ≥ R4006 % and not normal" began (NaN: no)
    #: (on times, Y when on, Y when off) as last published in the waveforms (None: to publish whole)
    published: tuple | None = None
    #: what the last scan read and derived from it (see Fun86Model._view), while those registers stay as they are
    view: View | None = None
    #: the WR+0/1 (or +2/3) weight of each point (bit_words), for the seams' bit positions
    weights: np.ndarray | None = None

    def new_points(self, zn: int) -> None:
        self.view, self.weights = None, None
        self.integral = np.zeros(zn)
        self.pv_prev = np.zeros(zn, dtype=np.int64)
        self.has_prev = np.zeros(zn, dtype=bool)
        self.prealarm = np.zeros(zn, dtype=np.int64)
        self.loop_since = np.full(zn, math.nan)

    def point_states(self) -> list[tuple]:
        """(integral, PV at the last PID step or None, pre-alarm count, heater-loop start or None) per point."""
        return [(i, p if h else None, c, None if math.isnan(s) else s) for i, p, h, c, s in
                zip(self.integral.tolist(), self.pv_prev.tolist(), self.has_prev.tolist(), self.prealarm.tolist(),
                    self.loop_since.tolist())]


@dataclass
class View:
    """An instance's registers as a scan read them, and what follows from them alone: the next scan with the same
    registers needs none of it again."""

    key: tuple
    pv: np.ndarray
    sv: np.ndarray
    os: np.ndarray
    enabled: np.ndarray
    idx: np.ndarray  # the enabled points
    output: np.ndarray  # OR
    every: bool  # every point enabled
    sel: slice | np.ndarray  # the enabled points, as an index (a whole slice when every one is)
    normal: np.ndarray | None = None  # (the alarms' part, filled by the scan that made the view)
    normal_words: tuple = ()
    out_of_band: bool = False
    warning: np.ndarray | None = None  # the warning bits the last scan found, and their words
    warning_words: tuple = ()
    calm: bool = False  # no PV at or above R4008 and every pre-alarm count 0
    waves: tuple | None = None  # (ON seconds, Y when on, Y when off)
