"""FUN86's control law (manual ch. 20.7; spec/fbs-pid.md PID-LAW): the PID step that turns PV, SV and the gains
PR/IR/DR of an instance's points into their outputs OR 0–16383, once per PID interval.

Mixed into :class:`hil.families.fbs.sim.models.fun86.Fun86Model`; :meth:`ControlLaw.law` and
:meth:`ControlLaw.control` are seams a broken PLC overrides (tests/test_pid_suites.py).  Arrays over an
instance's points, as everywhere in the model.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from hil.families.fbs.pid import OUTPUT_FULL

if TYPE_CHECKING:
    from hil.families.fbs.pid import PidInstance

#: the output's bounds as 0-d arrays: numpy takes a Python number as an operand at a cost several times that of a
#: 0-d array (and a control step over a few dozen points is a dozen such operations, once per PID interval)
_FULL, _LOWEST, _ZERO = np.array(float(OUTPUT_FULL)), np.array(-float(OUTPUT_FULL)), np.array(0.0)


@dataclass(frozen=True)
class Law:
    """The control law's coefficients for some points of an instance (constant while its registers are)."""

    kc: np.ndarray  # Kc
    ki: np.ndarray  # Ki ≠ 0
    every_ki: bool  # Ki ≠ 0 for every point
    integrate: np.ndarray  # Kc·(Ki/100/60)·ts: the integral's change per unit of error
    derivative: np.ndarray  # −Kc·(Td/100·60), signed for heating (+) or cooling (−): the output per unit of slope
    heating: bool
    md1: bool  # Md = 1: the integral runs outside the proportional band too
    ts: float


class ControlLaw:
    """The PID step of a FUN86 model."""

    def law(self, inst: PidInstance, kc: np.ndarray, ki: np.ndarray, td: np.ndarray, heating: bool,
            ts: float) -> Law:
        """The PID law's coefficients from the gains (spec: the manual's formula; derivative on PV)."""
        kc = np.asarray(kc, dtype=float)  # (gains are whole numbers: as floats, the arithmetic is the same and
        # each step's operations take operands of one type, without a cast)
        derivative = -kc * (td / 100 * 60) * (1 if heating else -1)
        return Law(kc, ki != 0, bool((ki != 0).all()), kc * (ki / 100 / 60) * ts, derivative, heating, inst.md == 1,
                   ts)

    def control(self, law: Law, integral: np.ndarray, pv_prev: np.ndarray, has_prev: np.ndarray | bool,
                sv: np.ndarray, pv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One PID step: (outputs, integrals) of points at ``pv`` whose integrals and PVs at the last step (where
        ``has_prev``; none: no slope) were ``integral`` and ``pv_prev``.  Md 0 freezes the integral outside the
        proportional band.  Units: 0.1° in, output counts 0–16383 out (as floats)."""
        error = (sv - pv) if law.heating else (pv - sv)
        proportional = law.kc * error
        if has_prev is not True:
            pv_prev = np.where(has_prev, pv_prev, pv)
        derivative = law.derivative * ((pv - pv_prev) / law.ts)
        integrate = law.ki if law.md1 else np.abs(proportional) < _FULL
        if not law.md1 and not law.every_ki:
            integrate &= law.ki
        # (an integral not integrating gains 0.0 and stays within ±16383)
        integral = np.minimum(np.maximum(integral + law.integrate * error * integrate, _LOWEST), _FULL)
        if not law.every_ki:
            integral = np.where(law.ki, integral, 0.0)
        return np.minimum(np.maximum(np.rint(proportional + integral + derivative), _ZERO), _FULL), integral


__all__ = ["ControlLaw", "Law"]
