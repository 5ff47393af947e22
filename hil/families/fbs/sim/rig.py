"""A fault rig for the emulator: a Modbus/TCP relay module whose coils put faults into the emulated machine.

``hil emulate --rig-modbus-tcp HOST:PORT`` serves it beside the PLC's own wires, so a bench with no back door
into the emulator (a separate process, reached only over the wire) exercises the same ``modbus-coil`` injector a
real bench with a relay module uses.  Three banks of 32 coils, one coil per temperature point, 1 = fault on:

* ``first_coil + point``: the point's sensor circuit open (``[faults.sensor_break]``, ``first_coil = FIRST``);
* ``first_coil + 32 + point``: its heater circuit open (``[faults.heater_open]``, ``first_coil = FIRST + 32``);
* ``first_coil + 64 + point``: its SSR shorted, heater full on (``[faults.ssr_short]``, ``first_coil = FIRST + 64``).

The heater banks need the emulator's thermal plant (``[plant]``); a coil of a point the plant does not heat is
refused with ILLEGAL_ADDRESS, as is any heater coil when there is no plant.  Coils read back as written.
Unit ids: any (pymodbus device id 0 answers for all).
"""

from __future__ import annotations

from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from hil.core.errors import InvalidValue
from hil.families.fbs.registers import MAX_POINTS
from hil.families.fbs.sim.plc import Emulator
from hil.sim.runtime import LoopThread, ServerHandle
from hil.families.fbs.sim.models.plant import ThermalPlant
from hil.families.fbs.sim.models.temperature import TemperatureModel

POINTS = MAX_POINTS  # one coil per temperature point, in each bank
#: the rig's banks in coil order, each POINTS coils long: the fault each coil of the bank switches
BANKS = ("sensor_break", "heater_open", "ssr_short")
_WRITE_COILS = (5, 15)


def build_rig_device(emulator: Emulator, first_coil: int = 0) -> SimDevice:
    model = emulator.model(TemperatureModel)
    if model is None:
        raise InvalidValue("the emulator has no temperature modules to break: give hil emulate a --bench profile "
                         "with a [temperature] section")
    plant = emulator.model(ThermalPlant)

    def switch(bank: str, point: int, on: bool) -> None:
        if bank == "sensor_break":
            (model.open if on else model.repair)(point)
        else:
            plant.set_fault(bank, point, on)

    async def action(function_code: int, start_address: int, address: int, count: int,
                     current_registers: list[int], set_values: list[int] | list[bool] | None) -> ExcCodes | None:
        if function_code not in _WRITE_COILS or set_values is None:
            return None
        changes = []
        for n, value in enumerate(set_values):
            bank, point = divmod(address + n - first_coil, POINTS)
            if BANKS[bank] != "sensor_break" and (plant is None or point not in plant.heaters):
                return ExcCodes.ILLEGAL_ADDRESS  # no heater to open or short there: nothing is switched
            changes.append((BANKS[bank], point, bool(value)))
        with emulator.lock:
            for bank, point, on in changes:
                switch(bank, point, on)
        return None

    coils = [SimData(first_coil, count=POINTS * len(BANKS), values=False, datatype=DataType.BITS)]
    unused = [SimData(0, count=1, values=False, datatype=DataType.BITS)]
    return SimDevice(0, simdata=(coils, unused, [SimData(0, count=1)], [SimData(0, count=1)]), action=action)


def start_rig_modbus_tcp(emulator: Emulator, host: str = "127.0.0.1", port: int = 0,
                         first_coil: int = 0) -> ServerHandle:
    runtime = LoopThread.shared()
    device = build_rig_device(emulator, first_coil)

    async def start() -> ModbusTcpServer:
        server = ModbusTcpServer(device, address=(host, port))
        await server.serve_forever(background=True)
        return server

    server = runtime.run(start())
    actual = server.transport.sockets[0].getsockname()[1]

    def stop() -> None:
        if runtime.loop.is_running():
            runtime.run(server.shutdown())

    return ServerHandle("rig-modbus-tcp", f"{host}:{actual}", stop)
