"""An S7-200 SMART bench: the profile made live — the CPU behind its guard, the bench's time, per-test restore.

The same shape as :class:`hil.families.fbs.bench.Bench` (``plc``, ``wait``, ``settle``, ``begin_test``/``end_test``,
``recover``, ``is_emulator``) and the same guard, journal and recovery (:mod:`hil.bench.guard`), so the pytest
plugin — the bench lock, recovery first, the per-test restore — timebase and reports serve both families.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable
from typing import Any

from hil.bench.base import BenchBase
from hil.bench.profile import Profile, plc_target
from hil.bench.view import guarded_io
from hil.core.errors import HilError, TargetError
from hil.core.timebase import Timebase, timebase_for
from hil.families.s7smart import faces
from hil.families.s7smart.address import parse_s7_range
from hil.families.s7smart.device.plc import S7Plc
from hil.families.s7smart.layout import S7RtcLayout, S7Settings
from hil.families.s7smart.protocol.modbus_map import S7ModbusMap
from hil.families.s7smart.sim.emulator import S7Emulator, build_s7_emulator
from hil.families.s7smart.sim.serve_modbus import start_s7_modbus_tcp
from hil.families.s7smart.sim.serve_s7 import start_s7_server
from hil.families.s7smart.transport.io import GuardedS7Io, LocalS7Io, ModbusS7Io, S7Io
from hil.families.s7smart.transport.s7wire import DEFAULT_PORT, SnapS7Io
from hil.io.url import Target

S7EmulatorBuilder = Callable[[Profile, dt.datetime], S7Emulator]
#: Emulator wires an S7 bench can use (the S7-200 SMART has no FATEK protocol).
S7_EMULATOR_TARGETS = ("emulator", "emulator+s7-tcp", "emulator+modbus-tcp")
#: the protocols an S7-200 SMART answers here ("local": the in-process emulator)
SPEAKS = ("s7", "modbus", "local")


def open_s7_io(target: Target, settings: S7Settings, *, station: int, timeout: float,
               emulator_factory: Callable[[], S7Emulator]) -> S7Io:
    modbus_map = S7ModbusMap(settings.hold_start, settings.max_hold)
    if target.protocol not in SPEAKS or (target.in_process and target.scheme not in S7_EMULATOR_TARGETS):
        raise TargetError(f"target {target} cannot reach an S7-200 SMART: use s7+tcp://HOST:102?rack=0&slot=1 (its "
                          f"own protocol), one of {', '.join(S7_EMULATOR_TARGETS)}, modbus+tcp://HOST:502?unit=1 "
                          f"or modbus+rtu:///dev/ttyUSB0?unit=1")
    if target.scheme == "emulator":
        return LocalS7Io(emulator_factory())
    if target.protocol == "s7":
        return _open_s7_wire(target, timeout, emulator_factory)
    if target.scheme == "emulator+modbus-tcp":
        emulator = emulator_factory()
        server = start_s7_modbus_tcp(emulator, modbus_map, unit=station)
        try:
            host, _, port = server.address.rpartition(":")
            io = ModbusS7Io.tcp(host, int(port), unit=station, timeout=timeout, modbus_map=modbus_map)
        except BaseException:
            server.stop()
            raise
        io.emulator = emulator
        io.description = f"emulator+modbus-tcp ({io.description})"
        io.on_close(server.stop)
        return io
    params: dict[str, Any] = dict(target.params)  # (converted by hil.io.url to the scheme's registered types)
    params.setdefault("timeout", timeout)
    params.setdefault("unit", station)
    if target.scheme == "modbus+tcp":
        return ModbusS7Io.tcp(target.host, target.port, modbus_map=modbus_map, **params)
    return ModbusS7Io.rtu(target.serial_port, modbus_map=modbus_map, **params)


def _open_s7_wire(target: Target, timeout: float, emulator_factory: Callable[[], S7Emulator]) -> S7Io:
    """``s7+tcp://`` (python-snap7's client), or ``emulator+s7-tcp``: the emulator served over the S7 protocol on
    loopback and reached by that same client."""
    params: dict[str, Any] = dict(target.params)  # (converted by hil.io.url to the scheme's registered types)
    params.setdefault("timeout", timeout)
    if not target.in_process:
        return SnapS7Io(target.host, target.port or DEFAULT_PORT, **params)
    emulator = emulator_factory()
    server = start_s7_server(emulator)
    try:
        host, _, port = server.address.rpartition(":")
        io = SnapS7Io(host, int(port), timeout=timeout, description=f"emulator+s7-tcp (s7+tcp://{server.address})")
    except BaseException:
        server.stop()
        raise
    io.emulator = emulator
    io.on_close(server.stop)
    return io


class S7Bench(BenchBase[S7Plc, S7Io]):
    #: what a suite sees of it (hil.bench.view.suite_view)
    FACE = faces.S7Bench

    family = "s7-200smart"

    def __init__(self, profile: Profile, *, target: str | None = None,
                 emulator_builder: S7EmulatorBuilder | None = None, allow_destructive: bool = False,
                 lane: str | None = None) -> None:
        self.profile = profile
        self.lane = lane  # one lane of a run with lanes (hil.plugin.lanes): its own journal
        self.settings: S7Settings = profile.sections["s7"]
        self.layout: S7RtcLayout | None = profile.sections.get("s7rtc")
        self.target: Target = plc_target(profile, target or None)  # at the profile's unit, on every wire
        self.allow_destructive = allow_destructive or profile.safety.allow_destructive
        epoch = dt.datetime.now().replace(microsecond=0)
        if emulator_builder is None:
            emulator_builder = build_s7_emulator
        self.raw: S7Io = open_s7_io(self.target, self.settings, station=profile.station, timeout=profile.timeout,
                                    emulator_factory=lambda: _checked(emulator_builder(profile, epoch)))
        self.io = GuardedS7Io(self.raw, profile.safety.writable)
        self.time: Timebase = timebase_for(self.raw.emulator, epoch, profile.time_scale)
        # the PLC object suites hold reaches the CPU only through the guarded operations (no .inner, no _write_*)
        self.plc = S7Plc(guarded_io(self.io), self.time, layout=self.layout, settle_scans=profile.settle_scans)
        # Safety (issue 15), as on every bench: the test program's results journaled with the triggers that make
        # it write them, the CPU clock restored to its original offset, originals on disk before each first write.
        if self.plc.rtc is not None:
            self.io.side_effects = self.plc.rtc.side_effects
        self.io.clock = self.plc.clock()
        self.journal = self.attach_journal()

    def plc_identity(self) -> dict[str, str] | None:
        """The CPU's identity over the S7 protocol (Modbus reads none)."""
        ask = getattr(self.raw, "plc_identity", None)
        return ask() if ask is not None else None

    def cannot_reach(self, *names: str) -> str | None:
        """Why this bench cannot read and write ``names`` (S7 operands or ranges such as ``"VB110-VB117"``)."""
        for name in names:
            for a in parse_s7_range(name):
                reason = self.raw.unreachable_reason(a)
                if reason:
                    return reason
                if any(u not in self.io.writable for u in self.io.split(a)):
                    return f"{name} not in the bench's [safety] writable list"
        return None

    def power_cycle(self, *, backup_expired: bool = False) -> None:
        """Emulator only: switch the CPU off and on (``backup_expired``: the clock's back-up ran out)."""
        emulator = self.raw.emulator
        if emulator is None:
            raise HilError("power_cycle needs the in-process emulator (mark the test needs('power_cycle'))")
        # the clock may lose its time: the guard journals it first and puts it back after the test
        self.io.setting_clock(lambda: emulator.power_cycle(backup_expired=backup_expired))

    def close(self) -> None:
        self.io.close()


def _checked(emulator: object) -> S7Emulator:
    if not isinstance(emulator, S7Emulator):
        raise HilError(f"an S7-200 SMART bench needs an S7 emulator, got {type(emulator).__name__} "
                       f"(a pytest_hil_make_emulator hook built the wrong family?)")
    return emulator
