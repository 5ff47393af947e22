"""The relay module on Modbus as a sensor-break (or heater-circuit) injector: coil ``first_coil + point`` = 1 opens
the point's circuit.  It is reached through the one Modbus client (:class:`~hil.io.modbus_client.ModbusWire`, under
the request policy) with plain coil numbers, not through the FBs Modbus transport: that speaks *FBs names* mapped onto
Modbus tables, whereas a relay module's coils have no FBs meaning."""

from __future__ import annotations

from typing import Any

from hil.core.errors import HilError, PlcErrorReply, ProfileError, TransportError
from hil.core.lock import lock_key
from hil.families.fbs.injectors.injector import FaultError, SensorBreakInjector
from hil.families.fbs.registers import MAX_POINTS
from hil.families.fbs.rig import GuardedRig, RigLink, rig_unit, rig_wire
from hil.io.url import parse_target


class ModbusCoilSensorBreak(SensorBreakInjector):
    """A relay module on Modbus: coil ``first_coil + point`` = 1 opens the point's circuit.  The coils are switched
    through the guard (:class:`~hil.families.fbs.rig.GuardedRig`: each coil's original journaled, on disk first,
    before its first switch; :meth:`undo` restores them, read back) over the one Modbus client."""

    kind = "modbus-coil"

    def __init__(self, target: str, first_coil: int = 0, timeout: float = 2.0, *, journal: Any = None,
                 coils: str | None = None, retries: int = 2) -> None:
        super().__init__()
        self.target = parse_target(target)
        self.first_coil = first_coil
        self.unit = rig_unit(self.target)
        self.timeout = timeout
        self.retries = retries
        self.journal = journal  # hil.core.journal.Journal: each coil's original is on disk before it is switched
        self.allowed = parse_coils(coils) if coils is not None else None  # the rig's own allow-list
        self._guard: GuardedRig | None = None

    @property
    def writable(self) -> frozenset[int]:
        """The coils this injector may switch: ``first_coil`` + a point, within the rig's allow-list (``coils``) —
        what its guard allows, and what recovery may put back on this rig."""
        coils = range(self.first_coil, self.first_coil + MAX_POINTS)
        return frozenset(c for c in coils if self.allowed is None or c in self.allowed)

    def coil_key(self, point: int) -> str:
        return f"{lock_key(str(self.target))}#unit{self.unit}/coil{self.first_coil + point}"

    @property
    def originals(self) -> dict[int, bool]:
        """point → what its coil held before the first switch (until restored)."""
        if self._guard is None:
            return {}
        return {e.coil - self.first_coil: bool(v) for e, v in self._guard.journal.items()}

    def guard(self) -> GuardedRig:
        """The guard round the rig's coils, over the one Modbus client; connected on first use."""
        if self._guard is None:
            try:
                wire = rig_wire(self.target, self.timeout, self.retries)
            except TransportError as exc:
                raise FaultError(f"cannot reach the sensor-break relay module at {self.target}: is it powered and "
                                 f"wired, and is the URL in [faults.sensor_break] target right? ({exc})") from None
            self._guard = GuardedRig(self.target, RigLink(wire), self.writable, self.journal)
        return self._guard

    def read_registers(self, address: int, count: int) -> list[int]:
        """Holding registers of the module (a HilError when it has none there)."""
        return self.guard().inner.read_registers(address, count)

    def openable(self, points: list[int]) -> list[int]:
        """The points whose coils are in the rig's allow-list (all, without one)."""
        return [p for p in points if self.allowed is None or self.first_coil + p in self.allowed]

    def _allowed(self, point: int) -> None:
        coil = self.first_coil + point
        if self.allowed is not None and coil not in self.allowed:
            raise FaultError(f"coil {coil} of the rig {self.target} is not in [faults] coils — refused before "
                             f"anything was sent")

    def _set(self, point: int, open_circuit: bool) -> None:
        self._allowed(point)
        coil = self.first_coil + point
        try:
            self.guard().switch(coil, open_circuit)
        except PlcErrorReply as exc:
            raise FaultError(f"relay module {self.target} refused coil {coil} (point {point}): exception {exc.code} "
                             f"— check first_coil and the module's size") from None
        except TransportError as exc:
            raise FaultError(f"relay module {self.target}: switching coil {coil} (point {point}) failed: {exc}") \
                from None

    def open(self, point: int) -> None:
        self._check(point)
        self._allowed(point)
        self.guard()  # the rig answers before the point counts as opened
        super().open(point)

    def undo(self) -> None:
        """Put every coil this injector switched back to what it held before (read back to verify)."""
        if self._guard is None:
            return
        try:
            self._guard.end()
        except HilError as exc:
            raise FaultError(f"relay module {self.target}: {exc}") from None
        finally:
            self.opened = {e.coil - self.first_coil for e in self._guard.journal}

    def close(self) -> None:
        if self._guard is not None:
            self._guard.close()
            self._guard = None


def parse_coils(text: str) -> frozenset[int]:
    """``"0-15, 20"`` → the coil numbers a rig's injector may switch."""
    out: set[int] = set()
    for part in str(text).split(","):
        part = part.strip()
        if not part:
            continue
        low, _, high = part.partition("-")
        try:
            first, last = int(low), int(high or low)
        except ValueError:
            raise ProfileError(f"[faults] coils: {part!r} is not a coil number or range like 0-15") from None
        out.update(range(first, last + 1))
    return frozenset(out)
