"""A fault rig for the emulator: a Modbus/TCP relay module whose coils put faults into the emulated machine.

``hil emulate --rig-modbus-tcp HOST:PORT`` serves it beside the PLC's own wires, so a bench with no back door
into the emulator (a separate process, reached only over the wire) exercises the same ``modbus-coil`` injector a
real bench with a relay module uses.  Three banks of 32 coils, one coil per temperature point, 1 = fault on:

* ``first_coil + point``: the point's sensor circuit open (``[faults.sensor_break]``, ``first_coil = FIRST``);
* ``first_coil + 32 + point``: its heater circuit open (``[faults.heater_open]``, ``first_coil = FIRST + 32``);
* ``first_coil + 64 + point``: its SSR shorted, heater full on (``[faults.ssr_short]``, ``first_coil = FIRST + 64``).

The heater banks need the emulator's thermal plant (``[plant]``); a coil of a point the plant does not heat is
refused with ILLEGAL_ADDRESS, as is any heater coil when there is no plant.  Coils read back as written.
The rig answers coil functions only (01, 05, 15: a relay module has nothing else); any unit id (a module alone on
its wire).  It is served by the one engine-over-Modbus server (:mod:`hil.sim.modbus_engine`), so its requests are
handled at scan boundaries, in order, with strict quantities, and its replies can go through a wire-fault plan.
"""

from __future__ import annotations

from collections.abc import Callable

from pymodbus.constants import ExcCodes
from pymodbus.simulator import SimDevice

from hil.core.errors import InvalidValue
from hil.families.fbs.registers import MAX_POINTS
from hil.families.fbs.sim.models.plant import ThermalPlant
from hil.families.fbs.sim.models.temperature import TemperatureModel
from hil.families.fbs.sim.plc import Emulator
from hil.sim.modbus_engine import Request, Tables, Values, build_device, nothing, start_tcp
from hil.sim.runtime import ServerHandle
from hil.sim.wire_faults import WireFaults

POINTS = MAX_POINTS  # one coil per temperature point, in each bank
#: the rig's banks in coil order, each POINTS coils long: the fault each coil of the bank switches
BANKS = ("sensor_break", "heater_open", "ssr_short")


class RigMap:
    """The rig's coils from ``first_coil``, switching faults in ``emulator``'s temperature model and plant."""

    functions = frozenset({1, 5, 15})

    def __init__(self, emulator: Emulator, first_coil: int = 0) -> None:
        model = emulator.model(TemperatureModel)
        if model is None:
            raise InvalidValue("the emulator has no temperature modules to break: give hil emulate a --bench "
                               "profile with a [temperature] section")
        self.model, self.plant = model, emulator.model(ThermalPlant)
        self.first_coil = first_coil
        self.tables = Tables(coils=((first_coil, first_coil + POINTS * len(BANKS)),))

    def request(self, function_code: int, start_address: int, address: int, count: int, registers: list[int],
                set_values: Values) -> Request | ExcCodes | None:
        if set_values is None:
            return None  # a read: the coils as last written, from the staging table
        changes = []
        for n, value in enumerate(set_values):
            bank, point = divmod(address + n - self.first_coil, POINTS)
            if BANKS[bank] != "sensor_break" and (self.plant is None or point not in self.plant.heaters):
                return ExcCodes.ILLEGAL_ADDRESS  # no heater to open or short there: nothing is switched
            changes.append((BANKS[bank], point, bool(value)))

        def switch(_memory: object) -> Callable[[], None]:
            for bank, point, on in changes:
                if bank == "sensor_break":
                    (self.model.open if on else self.model.repair)(point)
                else:
                    self.plant.set_fault(bank, point, on)  # type: ignore[union-attr]  # checked above
            return nothing
        return switch


def build_rig_device(emulator: Emulator, first_coil: int = 0) -> SimDevice:
    return build_device(emulator, RigMap(emulator, first_coil), None)


def start_rig_modbus_tcp(emulator: Emulator, host: str = "127.0.0.1", port: int = 0, first_coil: int = 0, *,
                         faults: WireFaults | None = None) -> ServerHandle:
    """Serve the rig of ``emulator`` on Modbus/TCP; port 0 picks a free port; ``faults``: the wire-fault plan
    every reply goes through."""
    return start_tcp(emulator, RigMap(emulator, first_coil), host, port, None, faults=faults,
                     kind="rig-modbus-tcp", stats="rig_modbus")
