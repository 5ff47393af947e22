"""Fault injectors: how a bench breaks a sensor on purpose, and puts it right after the test.

A profile names one injector per fault, e.g. ``[faults.sensor_break]``:

=================  ==============================================================================================
``kind``           what opens point *p*'s sensor circuit
=================  ==============================================================================================
``"emulator"``     a direct call into the in-process emulator (every ``emulator…`` target)
``"modbus-coil"``  a relay module on a Modbus target: coil ``first_coil + p`` = 1 opens the circuit, 0 closes it
                   (``target = "modbus+tcp://10.0.0.9:502?unit=1"``; also what ``hil emulate --rig-modbus-tcp``
                   serves)
``"plc-bit"``      a bit on the PLC itself, ``first = "Y40"``, one per point, written through the bench's guard
                   (so the bits must be in ``[safety] writable``)
``"manual"``       the operator is asked to open/close the circuit; unavailable when stdin is not a terminal
=================  ==============================================================================================

Suites reach injectors as ``bench.faults.sensor_break`` (``.open(point)``, ``.repair(point)``); every fault a
test injected is undone by the bench when the test ends, pass or fail.  ``[faults.heater_open]`` and
``[faults.ssr_short]`` take the same kinds and act on a point's heater circuit (``bench.faults.heater_open
.inject(point)`` / ``.clear(point)``; with kind = "emulator" the emulator's thermal plant, ``[plant]``).

This module is the bench's set of injectors (:class:`Faults`); each kind lives in :mod:`hil.families.fbs.injectors`
(the relay module on Modbus in :mod:`~hil.families.fbs.injectors.modbus_coil`), re-exported here.
"""

from __future__ import annotations

import sys
from typing import Any, Protocol

from hil.bench.profile import Profile
from hil.families.fbs.address import parse
from hil.families.fbs.injectors.config import KNOWN_FAULTS, PLANT_FAULTS
from hil.families.fbs.injectors.emulator import EmulatorPlantFault, EmulatorSensorBreak
from hil.families.fbs.injectors.injector import FaultError, SensorBreakInjector
from hil.families.fbs.injectors.manual import ManualSensorBreak
from hil.families.fbs.injectors.modbus_coil import ModbusCoilSensorBreak
from hil.families.fbs.injectors.plc_bit import PlcBitSensorBreak
from hil.families.fbs.rig_identity import rig_refusal
from hil.families.fbs.sim.models.plant import ThermalPlant
from hil.families.fbs.sim.models.temperature import TemperatureModel
from hil.families.fbs.transport.base import Transport
from hil.io.url import Target


class _HasIO(Protocol):
    @property
    def io(self) -> Any: ...  # the guarded I/O a plc-bit injector drives its bits through


class FaultBench(Protocol):
    """What the fault injectors use of the FBs bench (:class:`hil.families.fbs.bench.Bench`, which builds them)."""

    @property
    def profile(self) -> Profile: ...

    @property
    def target(self) -> Target: ...

    @property
    def raw(self) -> Transport: ...

    @property
    def plc(self) -> _HasIO: ...

    @property
    def is_emulator(self) -> bool: ...

    @property
    def allow_destructive(self) -> bool: ...

    def cannot_reach(self, *names: str) -> str | None: ...


class Faults:
    """The bench's fault injectors, built on first use from the profile's ``[faults.*]``."""

    #: the faults a suite reaches by name (``bench.faults.sensor_break``; hil.bench.view.faults_view)
    names = KNOWN_FAULTS

    def __init__(self, bench: FaultBench) -> None:
        self.bench = bench
        self._made: dict[str, SensorBreakInjector] = {}

    def unavailable(self, name: str) -> str | None:
        """Why this bench cannot inject fault ``name`` (a reason for a skip), or None."""
        spec = self.bench.profile.faults.get(name)
        if spec is None:
            return f"the bench profile has no [faults.{name}] injector"
        kind = spec["kind"]
        if kind == "emulator":
            if not self.bench.is_emulator:
                return (f"[faults.{name}] kind = \"emulator\" needs the in-process emulator, not target "
                        f"{self.bench.target}; use a relay (modbus-coil / plc-bit) or manual injector")
            if name in PLANT_FAULTS:
                if self._plant() is None:
                    return "the emulator has no thermal plant (no [plant] section in the profile)"
            elif self._temperature_model() is None:
                return "the emulator has no temperature modules (no [temperature] section in the profile)"
        if kind == "manual" and not sys.stdin.isatty():
            return f"[faults.{name}] kind = \"manual\" needs an operator, and stdin is not a terminal"
        if kind == "plc-bit":
            first = parse(spec["first"])
            if first.kind == "Y" and not self.bench.allow_destructive:
                # DESIGN: driving outputs of somebody's machine needs an explicit opt-in.
                return (f"[faults.{name}] drives outputs from {first}: pass --hil-allow-destructive (or set "
                        f"[safety] allow_destructive) to let the harness switch them")
            return self.bench.cannot_reach(str(first))
        return None

    @property
    def sensor_break(self) -> SensorBreakInjector | None:
        return self.get("sensor_break")

    def get(self, name: str) -> SensorBreakInjector | None:
        """The injector for ``name``, or None when the bench cannot provide it (see :meth:`unavailable`)."""
        if name in self._made:
            return self._made[name]
        if self.unavailable(name):
            return None
        spec = self.bench.profile.faults[name]
        kind = spec["kind"]
        if kind == "emulator":
            injector: SensorBreakInjector = (
                EmulatorPlantFault(self.bench.raw.emulator, self._plant(), name) if name in PLANT_FAULTS
                else EmulatorSensorBreak(self.bench.raw.emulator, self._temperature_model()))
        elif kind == "modbus-coil":
            why = self.not_the_plc(str(spec["target"]))
            if why:
                raise FaultError(f"[faults.{name}] target {why} — refused: a fault rig must be a separate device")
            injector = ModbusCoilSensorBreak(spec["target"], spec.get("first_coil", 0),
                                             float(spec.get("timeout", self.bench.profile.timeout)),
                                             journal=getattr(self.bench, "journal", None), coils=spec.get("coils"))
        elif kind == "plc-bit":
            injector = PlcBitSensorBreak(self.bench.plc.io, spec["first"])  # the guarded I/O
        else:
            injector = ManualSensorBreak(fault=name)
        self._made[name] = injector
        return injector

    def not_the_plc(self, target: str) -> str | None:
        """Why the rig at ``target`` may not be switched: it is the PLC under test, or that cannot be told (None
        once it is proven a separate device: :func:`~hil.families.fbs.rig_identity.rig_refusal`, the decision
        recovery takes too).  Asked once per target."""
        cache = self.__dict__.setdefault("_not_the_plc", {})
        if target not in cache:
            cache[target] = rig_refusal(target, str(self.bench.target), self.bench.raw, self.bench.profile.timeout)
        return cache[target]

    @property
    def heater_open(self) -> SensorBreakInjector | None:
        """``.inject(point)`` opens the point's heater circuit (no heating); ``.clear(point)`` closes it."""
        return self.get("heater_open")

    @property
    def ssr_short(self) -> SensorBreakInjector | None:
        """``.inject(point)`` shorts the point's SSR (full heating); ``.clear(point)`` removes the short."""
        return self.get("ssr_short")

    def _plant(self) -> Any:
        emulator = self.bench.raw.emulator
        return emulator.model(ThermalPlant) if emulator is not None else None

    def _temperature_model(self) -> Any:
        emulator = self.bench.raw.emulator
        return emulator.model(TemperatureModel) if emulator is not None else None

    def undo_all(self) -> None:
        """Undo every injected fault; raises FaultError listing what could not be undone."""
        errors = []
        for injector in self._made.values():
            try:
                injector.undo()
            except Exception as exc:  # noqa: BLE001 - undo every injector, then report them all
                errors.append(str(exc))
        if errors:
            raise FaultError("; ".join(errors))

    def close(self) -> None:
        for injector in self._made.values():
            injector.close()
