"""The waveforms a FUN86 model publishes for the emulator's thermal plant (models/plant.py) — no PLC has them: a
plant integrates a PWM output between scans exactly from (started, PWM period, ON seconds, Y when on, Y when off),
so the virtual-time engine needs no scan at each PWM edge.  What the PLC shows — Yn… at each scan — is the model's
(models/fun86.py, the manual's behaviour); :class:`PublishedWaveforms` is mixed into :class:`Fun86Model`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from hil.families.fbs.pid import PidInstance
    from hil.families.fbs.sim.models.fun86_state import InstanceState


class PublishedWaveforms:
    """The outputs' waveforms of a FUN86 model, for the plant."""

    def init_waveforms(self) -> None:
        #: (bit kind, index) of each output Yn… driven now → (started, PWM period, ON seconds, Y when on, Y when off)
        self.waveforms: dict[tuple[str, int], tuple] = {}
        #: bumped whenever :attr:`waveforms` changes (the plant skips its per-point work while it has not)
        self.waveforms_version = 0
        self._output_keys: dict[tuple, frozenset] = {}

    def republish(self, inst: PidInstance, st: InstanceState, waves: tuple) -> None:
        """The instance's waveforms published again if they (or the PWM cycle, or another instance's) changed."""
        last = st.published
        if last is None or last[0] != (st.started, st.pwm, self.waveforms_version) or last[1] is not waves[0]:
            self.publish(inst, st, *waves)

    def _drop_waveforms(self, inst: PidInstance, st: InstanceState) -> None:
        st.published = None
        if self.waveforms and st.zn > 0:
            keys = self._output_keys.get((inst.yn, st.zn))
            if keys is None:
                keys = self._output_keys[(inst.yn, st.zn)] = frozenset((inst.yn.kind, inst.yn.index + b)
                                                                       for b in range(st.zn))
            for key in self.waveforms.keys() & keys:
                del self.waveforms[key]
                self.waveforms_version += 1

    def publish(self, inst: PidInstance, st: InstanceState, on_time: np.ndarray, y_on: np.ndarray,
                y_off: np.ndarray) -> None:
        """The waveforms of the instance's outputs (for the plant): (started, PWM period, ON seconds, Y when on,
        Y when off), rewritten where they changed."""
        last = st.published
        bs: range | list = range(st.zn)
        if last is not None and last[0] == (st.started, st.pwm, self.waveforms_version):
            changed = (on_time != last[1]) | (y_on != last[2]) | (y_off != last[3])
            bs = np.flatnonzero(changed).tolist()
        waveforms, kind, base = self.waveforms, inst.yn.kind, inst.yn.index
        if bs:
            ons, lits, darks = on_time.tolist(), y_on.tolist(), y_off.tolist()
            for b in bs:
                wave = (st.started, st.pwm, ons[b], lits[b], darks[b])
                if waveforms.get((kind, base + b)) != wave:
                    waveforms[(kind, base + b)] = wave
                    self.waveforms_version += 1
        # (the version as left here: another instance writing the same outputs shows as a newer one)
        st.published = ((st.started, st.pwm, self.waveforms_version), on_time, y_on, y_off)
