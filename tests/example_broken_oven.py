"""A broken-emulator variant of the example line's oven (examples/heat_treatment): its FUN86 never raises the
high-temperature pre-alarm.  Loaded as a pytest plugin (``-p example_broken_oven`` from a directory it is copied
into): the example's pre-alarm test must fail on it, and only that one.  Test code only, as tests/broken.py."""

from __future__ import annotations

import numpy as np

from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.sim.models.fun86 import Fun86Model
from hil.families.fbs.sim.models.temperature import TemperatureModel


class PrealarmNever(Fun86Model):
    def prealarm(self, count):
        return np.zeros_like(count, dtype=bool)


def pytest_hil_make_emulator(profile, epoch):
    emulator = build_emulator(profile, epoch)
    good = emulator.model(Fun86Model)
    broken = PrealarmNever(good.config, good.temperature)
    broken.next_measurement = emulator.model(TemperatureModel).next_measurement
    index = emulator.models.index(good)
    broken.power_on(emulator)
    emulator.models[index] = broken
    return emulator
