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

One module each: the profile's tables (:mod:`.config`), what an injector is (:mod:`.injector`), the kinds
(:mod:`.emulator`, :mod:`.modbus_coil`, :mod:`.plc_bit`, :mod:`.manual`), the bench's set (:mod:`.bench_faults`).
"""

from __future__ import annotations

from hil.families.fbs.faults.bench_faults import Faults
from hil.families.fbs.faults.config import (FAULT_ACTIONS, KINDS, KNOWN_FAULTS, PLANT_FAULTS, check_fault_configs,
                                            parse_coils)
from hil.families.fbs.faults.emulator import EmulatorPlantFault, EmulatorSensorBreak
from hil.families.fbs.faults.injector import FaultError, SensorBreakInjector
from hil.families.fbs.faults.manual import ManualSensorBreak
from hil.families.fbs.faults.modbus_coil import ModbusCoilSensorBreak
from hil.families.fbs.faults.plc_bit import PlcBitSensorBreak

__all__ = ["EmulatorPlantFault", "EmulatorSensorBreak", "FAULT_ACTIONS", "FaultError", "Faults", "KINDS", "KNOWN_FAULTS",
           "ManualSensorBreak", "ModbusCoilSensorBreak", "PLANT_FAULTS", "PlcBitSensorBreak", "SensorBreakInjector",
           "check_fault_configs", "parse_coils"]
