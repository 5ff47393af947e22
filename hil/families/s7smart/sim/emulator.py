"""An S7-200 SMART in software, on the shared scan engine: byte memory (V, I, Q, SM), the CPU's clock with
READ_RTC / SET_RTC / SET_RTC_I, and the bench's clock test program (triggers, buffers and results in V memory).

The instructions' semantics live in :class:`S7Clock` (clock.py: one method each, so a test can break one); the
test program (:class:`RtcTestProgram`, clock.py too) only decides *when* they run — on rising edges of its trigger bits — and where
the results land, as configured by the profile's ``[s7rtc]``.
"""

from __future__ import annotations

import copy
import datetime as dt
from typing import TYPE_CHECKING

from hil.families.s7smart.address import AREA_BYTES, S7Address, parse_s7
from hil.families.s7smart.layout import S7Settings

# the clock model (what mutation testing judges: benchmarks/mutation.py), re-exported
from hil.families.s7smart.sim.clock import RtcTestProgram, S7Clock
from hil.sim.engine import Engine

if TYPE_CHECKING:
    from hil.bench.profile import Profile

class S7Memory:
    """Byte-addressed areas; bits are ``byte.bit`` (bit 0 = least significant), words big-endian."""

    def __init__(self) -> None:
        self.areas: dict[str, bytearray] = {a: bytearray(n) for a, n in AREA_BYTES.items()}

    @property
    def v(self) -> bytearray:
        return self.areas["V"]

    def read_bytes(self, area: str, first: int, count: int) -> bytes:
        return bytes(self.areas[area][first:first + count])

    def write_bytes(self, area: str, first: int, data: bytes) -> None:
        bank = self.areas[area]
        if first < 0 or first + len(data) > len(bank):
            raise IndexError(f"{area}B{first}…+{len(data)} is outside {area} memory")
        bank[first:first + len(data)] = data

    def get(self, name: str | S7Address) -> int:
        a = parse_s7(name)
        bank = self.areas[a.area]
        if a.is_bit:
            return bank[a.byte] >> a.bit & 1  # type: ignore[operator]
        return int.from_bytes(bank[a.byte:a.end], "big")

    def set(self, name: str | S7Address, value: int) -> None:
        a = parse_s7(name)
        bank = self.areas[a.area]
        if a.is_bit:
            mask = 1 << a.bit  # type: ignore[operator]
            bank[a.byte] = bank[a.byte] | mask if value else bank[a.byte] & ~mask
        else:
            bank[a.byte:a.end] = (int(value) & ((1 << 8 * a.size) - 1)).to_bytes(a.size, "big")

    def snapshot(self) -> dict[str, bytearray]:
        return copy.deepcopy(self.areas)


class S7Emulator(Engine):
    """The shared scan engine (service at a scan boundary, virtual time) with S7 memory instead of FBs memory."""

    family = "s7-200smart"

    def __init__(self, *, scan_time: float = 0.01, models=(), station: int = 1, seed: int = 0,  # noqa: ANN001
                 cpu: str = "ST40") -> None:
        super().__init__(S7Memory(), scan_time=scan_time, station=station, seed=seed)
        self.cpu = cpu
        self.version = f"{Engine.version} (S7-200 SMART {cpu})"
        for model in models:
            self.add_model(model)

    def power_cycle(self, *, backup_expired: bool = False) -> None:
        """Power off and on: the clock keeps time only while its back-up lasts (and never on a CR40/CR60);
        programs start again from their first scan."""
        with self.lock:
            for model in self.models:
                cycle = getattr(model, "power_cycle", None)
                if cycle is not None:
                    cycle(self, backup_expired=backup_expired)
                else:
                    model.power_on(self)


def build_s7_emulator(profile: Profile, epoch: dt.datetime) -> S7Emulator:
    """The emulator an S7 profile describes: CPU (with or without RTC), clock start, and the [s7rtc] program."""
    settings: S7Settings = profile.sections["s7"]
    emulator = S7Emulator(scan_time=profile.emulator.scan_time_ms / 1000, station=profile.station,
                          seed=profile.emulator.seed, cpu=settings.cpu)
    start = epoch if settings.start == "host" else None
    emulator.add_model(S7Clock(has_rtc=settings.has_rtc, start=start))
    if "s7rtc" in profile.sections:
        emulator.add_model(RtcTestProgram(profile.sections["s7rtc"]))
    return emulator
