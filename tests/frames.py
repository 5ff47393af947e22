"""Recorded FATEK frames of the device procedures (``fixtures/frames/*.txt``) and the scenarios that made them.

``python -m tests.frames`` re-records every scenario against the emulator over FATEK/TCP (the default bench at a
fixed epoch); tests/test_replay.py replays each recording through ``replay+fatek://…`` and checks that the device
layer sends the very same frames and decodes the recorded replies to the values stated here.  A change to a
procedure's frames (another command, an extra round trip) fails those tests until it is re-recorded on purpose.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hil.core.timebase import HostTimebase
from hil.families.fbs.device.plc import FbsPlc
from hil.families.fbs.rtc_time import RtcTime
from tests.conftest import EMULATOR_BENCH, REPO

FRAMES = REPO / "fixtures" / "frames"
EPOCH = dt.datetime(2024, 2, 28, 12, 0, 0)  # a Wednesday, the day before a leap day


def _temperature(plc: FbsPlc) -> Any:
    from hil.bench.profile import load_profile
    from hil.families.fbs.temperature import parse_temperature
    plc.temperature.config = parse_temperature(load_profile(EMULATOR_BENCH).areas["temperature"], "<frames>")
    work = plc.temperature.read_work()
    return work.execution_code, work.total_points, work.break_points, plc.temperature.readings()[:2]


#: scenario → (what it does with the PLC, what it must return)
SCENARIOS: dict[str, tuple[Callable[[FbsPlc], Any], Any]] = {
    # R4128–R4135 and M1952–M1955 in one mixed read (command 48)
    "rtc-read-all": (lambda plc: _snapshot(plc.rtc.read_all()),
                     (RtcTime(0, 1, 12, 28, 2, 24, 3), (False, False, True, False))),
    # M1952 := 1, R4128–R4134, M1952 := 0, settle, read back: the leap day is accepted
    "rtc-set-leap-day": (lambda plc: (plc.rtc.set(dt.datetime(2024, 2, 29, 23, 59, 30)).refused, plc.rtc.read()),
                         (False, RtcTime(30, 59, 23, 29, 2, 24, 4))),
    # 29 Feb 2023 does not exist: M1955 = 1 and the clock keeps running from where it was
    "rtc-set-invalid": (lambda plc: (plc.rtc.set(RtcTime(0, 0, 8, 29, 2, 23, 3)).refused, plc.rtc.read().day),
                        (True, 28)),
    # D4053 and D4054 together; the manual's worked example code 56E5H written and read back
    "rtc-rate-code": (lambda plc: (plc.rtc.read_chip_and_rate_code()[0].code, _write_code(plc, 0x56E5)),
                      (3, 0x56E5)),
    # the work block (TW…) and the first readings of the default bench's two 16TC modules
    "temperature-work": (_temperature, (0x56, 32, [], [250, 250])),
}


def _snapshot(snapshot: Any) -> tuple:
    flags = snapshot.flags
    return snapshot.time, (flags.hold, flags.adjust_30s, flags.installed, flags.set_error)


def _write_code(plc: FbsPlc, code: int) -> int:
    plc.rtc.rate_code = code
    return plc.rtc.rate_code


def plc_on(transport: Any) -> FbsPlc:
    return FbsPlc(transport, HostTimebase())


def record(names: list[str] | None = None) -> list[Path]:
    """Run each scenario against the emulator over FATEK/TCP and save its frames as a wire trace."""
    from hil.bench.profile import load_profile
    from hil.families.fbs.sim.build import build_emulator
    from hil.families.fbs.transport.factory import open_transport
    from hil.io.trace import WireTrace, format_trace
    written = []
    for name in names or list(SCENARIOS):
        emulator = build_emulator(load_profile(EMULATOR_BENCH), EPOCH)
        emulator.advance(60.0)  # every temperature point measured (the clock reads 12:01:00)
        with open_transport("emulator+fatek-tcp", emulator_factory=lambda emulator=emulator: emulator) as transport:
            trace = WireTrace().attach(transport)
            trace.start()
            run, expected = SCENARIOS[name]
            got = run(plc_on(transport))
            entries = trace.stop()
        if got != expected:
            raise AssertionError(f"{name}: the emulator gave {got!r}, the scenario states {expected!r}")
        path = FRAMES / f"{name}.txt"
        path.write_text(f"# {name}: recorded by tests/frames.py from the emulator over FATEK/TCP\n"
                        + format_trace(entries, kind=trace.kind), encoding="utf-8")
        written.append(path)
    return written


if __name__ == "__main__":
    for p in record():
        print(p.relative_to(REPO))
