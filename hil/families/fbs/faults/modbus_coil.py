"""A relay module on Modbus: coil ``first_coil + point`` switches the point's circuit (also what ``hil emulate
--rig-modbus-tcp`` serves).

The relay module is reached with pymodbus's client directly, not through :class:`~hil.families.fbs.transport.modbus.
ModbusTransport`: that transport speaks *FBs names* mapped onto Modbus tables, whereas a relay module has plain
coil numbers with no FBs meaning.
"""

from __future__ import annotations

from typing import Any

from hil.core.lock import lock_key
from hil.families.fbs.faults.config import parse_coils
from hil.families.fbs.faults.injector import FaultError, SensorBreakInjector
from hil.io.modbus_client import SerialClient
from hil.io.url import parse_target


class ModbusCoilSensorBreak(SensorBreakInjector):
    """A relay module on Modbus: coil ``first_coil + point`` = 1 opens the point's circuit."""

    kind = "modbus-coil"

    def __init__(self, target: str, first_coil: int = 0, timeout: float = 2.0, *, journal: Any = None,
                 coils: str | None = None) -> None:
        super().__init__()
        self.target = parse_target(target)
        self.first_coil = first_coil
        self.unit = int(self.target.params.get("unit", 1))
        self.timeout = timeout
        self.journal = journal  # hil.core.journal.Journal: each coil's original is on disk before it is switched
        self.allowed = parse_coils(coils) if coils is not None else None  # the rig's own allow-list
        self.originals: dict[int, bool] = {}  # point → what its coil held before the first injection
        self._client: Any = None

    def coil_key(self, point: int) -> str:
        return f"{lock_key(str(self.target))}#unit{self.unit}/coil{self.first_coil + point}"

    def _original(self, point: int) -> None:
        """Read and journal the coil's state before the first switch (restore writes back *that*, not 0)."""
        if point in self.originals:
            return
        coil = self.first_coil + point
        value = self._read(coil)
        if self.journal is not None:
            self.journal.add_coil(self.coil_key(point), str(self.target), coil, self.unit, value)
        self.originals[point] = value

    def _read(self, coil: int) -> bool:
        from pymodbus.exceptions import ModbusException
        try:
            reply = self._connect().read_coils(coil, count=1, device_id=self.unit)
        except ModbusException as exc:
            self.close()
            raise FaultError(f"relay module {self.target}: reading coil {coil} failed: {exc}") from None
        if reply.isError():
            raise FaultError(f"relay module {self.target} refused to read coil {coil}")
        return bool(reply.bits[0])

    def open(self, point: int) -> None:
        self._check(point)
        self._allowed(point)
        self._original(point)
        super().open(point)

    def repair(self, point: int) -> None:
        self._check(point)
        self._allowed(point)
        self._original(point)
        super().repair(point)

    def openable(self, points: list[int]) -> list[int]:
        """The points whose coils are in the rig's allow-list (all, without one)."""
        return [p for p in points if self.allowed is None or self.first_coil + p in self.allowed]

    def _allowed(self, point: int) -> None:
        coil = self.first_coil + point
        if self.allowed is not None and coil not in self.allowed:
            raise FaultError(f"coil {coil} of the rig {self.target} is not in [faults] coils — refused before "
                             f"anything was sent")

    def undo(self) -> None:
        """Put every coil this injector switched back to what it held before (read back to verify)."""
        errors = []
        for point, value in sorted(self.originals.items()):
            coil = self.first_coil + point
            try:
                self._write(point, value)
                if self._read(coil) != value:
                    raise FaultError(f"coil {coil} does not read back {int(value)}")
            except Exception as exc:  # noqa: BLE001 - try every coil, then report them all
                errors.append(f"coil {coil} (original {int(value)}): {exc}")
                continue
            self.opened.discard(point)
            del self.originals[point]
            if self.journal is not None:
                self.journal.drop_coil(self.coil_key(point))
        if errors:
            raise FaultError(f"relay module {self.target}: could not restore {'; '.join(errors)}")

    def _connect(self) -> Any:
        if self._client is None:
            from pymodbus.client import ModbusTcpClient
            from pymodbus.framer import FramerType
            t = self.target
            if t.scheme == "modbus+tcp":
                # retries=0: pymodbus re-sends a request that timed out, a coil write included (a write is never
                # repeated: its first copy may have landed)
                client = ModbusTcpClient(t.host, port=t.port, timeout=self.timeout, retries=0)
            else:
                p = t.params
                client = SerialClient(t.serial_port, framer=FramerType.RTU, baudrate=int(p.get("baudrate", 9600)),
                                      parity=str(p.get("parity", "E")), bytesize=int(p.get("bytesize", 8)),
                                      stopbits=int(p.get("stopbits", 1)), timeout=self.timeout, retries=0)
            if not client.connect():
                raise FaultError(f"cannot reach the sensor-break relay module at {t}: is it powered and wired, "
                                 f"and is the URL in [faults.sensor_break] target right?")
            self._client = client
        return self._client

    def _set(self, point: int, open_circuit: bool) -> None:
        if self.journal is not None:  # what the coil is about to hold, on disk before it is switched
            coil = self.first_coil + point
            self.journal.add_coil(self.coil_key(point), str(self.target), coil, self.unit, self.originals[point],
                                  wrote=bool(open_circuit))
        self._write(point, open_circuit)

    def _write(self, point: int, open_circuit: bool) -> None:
        from pymodbus.exceptions import ModbusException
        coil = self.first_coil + point
        try:
            reply = self._connect().write_coil(coil, open_circuit, device_id=self.unit)
        except ModbusException as exc:
            self.close()
            raise FaultError(f"relay module {self.target}: writing coil {coil} (point {point}) failed: {exc}") \
                from None
        if reply.isError():
            raise FaultError(f"relay module {self.target} refused coil {coil} (point {point}): exception "
                             f"{getattr(reply, 'exception_code', '?')} — check first_coil and the module's size")

    def close(self) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None
