"""A fault rig for the emulator: a Modbus/TCP relay module whose coils open the emulator's temperature sensors.

``hil emulate --rig-modbus-tcp HOST:PORT`` serves it beside the PLC's own wires, so a bench with no back door
into the emulator (a separate process, reached only over the wire) exercises the same ``modbus-coil`` injector a
real bench with a relay module uses: coil ``first_coil + point`` = 1 opens the point's sensor, 0 closes it.
Coils read back as written.  Unit ids: any (pymodbus device id 0 answers for all).
"""

from __future__ import annotations

from pymodbus.simulator import DataType, SimData, SimDevice
from pymodbus.server import ModbusTcpServer

from hil.emulator.core import Emulator
from hil.emulator.serve.runtime import LoopThread, ServerHandle

POINTS = 32
_WRITE_COILS = (5, 15)


def build_rig_device(emulator: Emulator, first_coil: int = 0) -> SimDevice:
    from hil.emulator.models.temperature import TemperatureModel
    model = emulator.model(TemperatureModel)
    if model is None:
        raise ValueError("the emulator has no temperature modules to break: give hil emulate a --bench profile "
                         "with a [temperature] section")

    async def action(function_code: int, start_address: int, address: int, count: int,
                     current_registers: list[int], set_values: list[int] | list[bool] | None) -> None:
        if function_code not in _WRITE_COILS or set_values is None:
            return None
        with emulator.lock:
            for n, value in enumerate(set_values):
                point = address + n - first_coil
                (model.open if value else model.repair)(point)
        return None

    coils = [SimData(first_coil, count=POINTS, values=False, datatype=DataType.BITS)]
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
