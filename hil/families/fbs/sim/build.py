"""Build an emulator the way a bench profile describes it ([emulator], [rtc], and later the other areas)."""

from __future__ import annotations

import datetime as dt

from hil.bench.profile import Profile
from hil.families.fbs.address import parse
from hil.families.fbs.pid import PidConfig
from hil.families.fbs.sim.models.fun86 import Fun86Model
from hil.families.fbs.sim.models.plant import ThermalPlant
from hil.families.fbs.sim.models.rtc import RtcModel
from hil.families.fbs.sim.models.temperature import TemperatureModel
from hil.families.fbs.sim.plc import Emulator


def build_emulator(profile: Profile, epoch: dt.datetime) -> Emulator:
    """An FBs emulator for ``profile`` whose clock-related models start at ``epoch`` (the bench's "host time")."""
    emulator = Emulator(scan_time=profile.emulator.scan_time_ms / 1000, station=profile.station,
                        seed=profile.emulator.seed, timing=profile.emulator.timing_plan())
    if profile.scan_counter:
        emulator.scan_counter = parse(profile.scan_counter)
    rtc = profile.rtc
    emulator.add_model(RtcModel(chip=rtc.chip if rtc else 3, crystal_ppm=rtc.crystal_ppm if rtc else 0.0,
                                start=(rtc.start if rtc and rtc.start else epoch)))
    if "temperature" in profile.sections:
        emulator.add_model(TemperatureModel(profile.sections["temperature"], timing=emulator.timing))
    if "pid" in profile.sections or "plant" in profile.sections:
        add_pid_models(emulator, profile)
    return emulator


def add_pid_models(emulator: Emulator, profile: Profile) -> None:
    """FUN86 (the ladder's PID instances, [pid]) and the thermal plant ([plant]) after the temperature modules."""
    config = profile.sections.get("pid") or PidConfig(())
    temperature = emulator.model(TemperatureModel)
    fun86 = Fun86Model(config, temperature.config if temperature else None)
    fun86.phases = emulator.timing
    if temperature is not None:
        fun86.next_measurement = temperature.next_measurement
    emulator.add_model(fun86)
    if "plant" in profile.sections:
        heaters = {p: inst.yn.offset(p - inst.sn) for inst in config.instances if not inst.settable
                   for p in inst.points}
        emulator.add_model(ThermalPlant(profile.sections["plant"], heaters, seed=emulator.seed))
