"""Bench profiles: a TOML file that says which PLC, over which wire, what the harness may write, and the layout.

Every key is checked: an unknown key, a bad address, a bad range or a value of the wrong type is refused with an
error that names the file and the key.  Sections of areas that validate themselves ([temperature], [pid],
[plant], [faults.*]) are kept as tables here and checked by their own modules.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from hil.families.fbs.address import parse_range
from hil.core.errors import AddressError, ProfileError, TargetError
from hil.io.url import parse_target

RTC_CHIPS = {"none": 0, "HT1381": 1, "ISL1208": 2, "S-35390A": 3}
AREA_SECTIONS = ("temperature", "pid", "plant", "s7", "s7rtc")  # validated by their own modules
FAMILIES = ("fbs", "s7-200smart")  # [bench] family: which controller the profile describes
DEFAULT_VOLATILE = ["R4128-R4135"]  # the RTC read-out: the PLC rewrites it every scan


@dataclass(frozen=True)
class Safety:
    writable: tuple[str, ...] = ()
    volatile: tuple[str, ...] = tuple(DEFAULT_VOLATILE)
    allow_destructive: bool = False


@dataclass(frozen=True)
class EmulatorSettings:
    scan_time_ms: float = 10.0
    seed: int = 0


@dataclass(frozen=True)
class RtcSettings:
    chip: int = 3
    crystal_ppm: float = 0.0
    start: dt.datetime | None = None  # None: the bench's host time when the emulator is built


@dataclass(frozen=True)
class Profile:
    path: Path | None
    name: str
    target: str = "emulator"
    station: int = 1
    time_scale: float = 1.0
    settle_scans: int = 2
    timeout: float = 2.0
    safety: Safety = Safety()
    emulator: EmulatorSettings = EmulatorSettings()
    rtc: RtcSettings | None = None
    areas: dict[str, dict[str, Any]] = field(default_factory=dict)  # [temperature], [pid], [plant]
    faults: dict[str, dict[str, Any]] = field(default_factory=dict)  # [faults.<name>]
    digest: str = ""  # sha256 of the file, for reports
    wire_faults: dict[str, Any] = field(default_factory=dict)  # [wire_faults]: emulator wires only, see below
    family: str = "fbs"  # "fbs" or "s7-200smart": picks the device layer, emulator and suites

    def can_write(self, name: str) -> bool:
        from hil.families.fbs.transport.guard import expand
        try:
            wanted = expand([name])
        except AddressError:
            return False
        return wanted <= expand(self.safety.writable)


# -- reading -----------------------------------------------------------------------------------------------------
def load_profile(path: str | Path) -> Profile:
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ProfileError(f"cannot read bench profile {path}: {exc.strerror} — pass --bench with an existing "
                           f"file (see fixtures/benches/)") from None
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ProfileError(f"{path}: not valid TOML: {exc}") from None
    return profile_from_dict(data, path=path, digest=hashlib.sha256(raw).hexdigest())


def profile_from_dict(data: dict[str, Any], *, path: Path | None = None, digest: str = "") -> Profile:
    where = str(path) if path else "<profile>"
    known = {"bench", "safety", "emulator", "rtc", "faults", "wire_faults", *AREA_SECTIONS}
    for section in data:
        if section not in known:
            raise ProfileError(f"{where}: unknown section [{section}] (known: {', '.join(sorted(known))})")
    if "bench" not in data:
        raise ProfileError(f"{where}: missing the [bench] section (name, target, station, time_scale)")
    reader = _Reader(where)
    bench = reader.table(data, "bench")
    name = reader.take(bench, "bench", "name", str, required=True)
    target = reader.take(bench, "bench", "target", str, "emulator", check=_check_target)
    station = reader.take(bench, "bench", "station", int, 1, check=lambda v: 1 <= v <= 254 or "must be 1–254")
    time_scale = reader.take(bench, "bench", "time_scale", float, 1.0, check=lambda v: v > 0 or "must be > 0")
    settle = reader.take(bench, "bench", "settle_scans", int, 2, check=lambda v: v >= 1 or "must be ≥ 1")
    timeout = reader.take(bench, "bench", "timeout", float, 2.0, check=lambda v: v > 0 or "must be > 0")
    family = reader.take(bench, "bench", "family", str, "fbs",
                         check=lambda v: v in FAMILIES or f"must be one of {', '.join(FAMILIES)}")
    reader.done(bench, "bench")

    safety_t = reader.table(data, "safety")
    ranges = _check_ranges
    volatile_default = list(DEFAULT_VOLATILE)
    if family == "s7-200smart":  # S7 operand names (VB100-VB139), and no FBs read-out to skip
        from hil.families.s7smart.layout import check_s7_ranges
        ranges, volatile_default = check_s7_ranges, []
    safety = Safety(
        writable=tuple(reader.take(safety_t, "safety", "writable", list, [], check=ranges)),
        volatile=tuple(reader.take(safety_t, "safety", "volatile", list, volatile_default, check=ranges)),
        allow_destructive=reader.take(safety_t, "safety", "allow_destructive", bool, False))
    reader.done(safety_t, "safety")

    emu_t = reader.table(data, "emulator")
    emulator = EmulatorSettings(
        scan_time_ms=reader.take(emu_t, "emulator", "scan_time_ms", float, 10.0,
                                 check=lambda v: 0.1 <= v <= 1000 or "must be 0.1–1000 ms"),
        seed=reader.take(emu_t, "emulator", "seed", int, 0))
    reader.done(emu_t, "emulator")

    rtc = None
    if "rtc" in data:
        rtc_t = reader.table(data, "rtc")
        rtc = RtcSettings(
            chip=reader.take(rtc_t, "rtc", "chip", object, 3, convert=_chip),
            crystal_ppm=reader.take(rtc_t, "rtc", "crystal_ppm", float, 0.0,
                                    check=lambda v: abs(v) <= 500 or "must be within ±500 ppm"),
            start=reader.take(rtc_t, "rtc", "start", object, None, convert=_start))
        reader.done(rtc_t, "rtc")

    areas = {s: reader.table(data, s) for s in AREA_SECTIONS if s in data}
    if "temperature" in areas:  # refuse a bad [temperature] when the profile is read, not when a test runs
        from hil.families.fbs.temperature import parse_temperature
        parse_temperature(areas["temperature"], where)
    if "pid" in areas:  # FUN86 instances: addresses, ranges and overlaps refused with the reason
        from hil.families.fbs.pid import parse_pid
        parse_pid(areas["pid"], where)
    if "plant" in areas:
        from hil.families.fbs.sim.models.plant import parse_plant
        parse_plant(areas["plant"], where)
    if family == "s7-200smart":
        from hil.families.s7smart.layout import parse_s7_settings, parse_s7rtc
        parse_s7_settings(areas.get("s7", {}), where)
        if "s7rtc" in areas:
            parse_s7rtc(areas["s7rtc"], where)
    elif "s7" in areas or "s7rtc" in areas:
        raise ProfileError(f"{where}: [s7]/[s7rtc] describe an S7-200 SMART: set [bench] family = \"s7-200smart\"")
    faults_t = reader.table(data, "faults")
    faults = {}
    for fault, table in faults_t.items():
        if not isinstance(table, dict):
            raise ProfileError(f"{where}: [faults.{fault}] must be a table")
        faults[fault] = table
    if faults:
        from hil.families.fbs.faults import check_fault_configs
        check_fault_configs(faults, where)
    wire_faults = _wire_faults(reader, data) if "wire_faults" in data else {}
    return Profile(path, name, target, station, time_scale, settle, timeout, safety, emulator, rtc, areas,
                   faults, digest, wire_faults=wire_faults, family=family)


def _wire_faults(reader: "_Reader", data: dict[str, Any]) -> dict[str, Any]:
    """``[wire_faults]``: faults the emulator's servers put on the wire (emulator+… targets only).

    ``seed`` (int), ``delay_seconds`` (how long a "delay" holds a reply) and ``split_gap`` (seconds), ``script`` (list of kinds, "none" = no fault) and one
    probability (0–1) per kind (drop = 0.01, corrupt = 0.02 …) — see :mod:`hil.sim.wire_faults`."""
    from hil.sim.wire_faults import KINDS, check_rates
    table = reader.table(data, "wire_faults")
    out: dict[str, Any] = {
        "seed": reader.take(table, "wire_faults", "seed", int, 0),
        "delay_seconds": reader.take(table, "wire_faults", "delay_seconds", float, 1.0,
                                     check=lambda v: 0 <= v <= 60 or "must be 0–60 s"),
        "split_gap": reader.take(table, "wire_faults", "split_gap", float, 0.005,
                                 check=lambda v: 0 <= v <= 5 or "must be 0–5 s"),
        "script": reader.take(table, "wire_faults", "script", list, [],
                              check=lambda v: all(k in KINDS or k == "none" for k in v)
                              or f"must name kinds among {', '.join(KINDS)} (or 'none')"),
    }
    out["script"] = [None if k == "none" else k for k in out["script"]]
    for kind in KINDS:
        out[kind] = reader.take(table, "wire_faults", kind, float, 0.0,
                                check=lambda v: 0 <= v <= 1 or "must be a probability 0–1")
    reader.done(table, "wire_faults")
    try:
        check_rates({k: out[k] for k in KINDS})
    except ValueError as exc:
        raise ProfileError(f"{reader.where}: [wire_faults] {exc}") from None
    return out


class _Reader:
    """Takes keys out of a table one by one, so that whatever is left over is an unknown key."""

    def __init__(self, where: str) -> None:
        self.where = where

    def table(self, data: dict[str, Any], section: str) -> dict[str, Any]:
        table = data.get(section, {})
        if not isinstance(table, dict):
            raise ProfileError(f"{self.where}: [{section}] must be a table")
        return dict(table)

    def take(self, table: dict[str, Any], section: str, key: str, kind: type, default: Any = None, *,
             required: bool = False, check: Callable[[Any], Any] | None = None,
             convert: Callable[[Any], Any] | None = None) -> Any:
        label = f"{self.where}: [{section}] {key}"
        if key not in table:
            if required:
                raise ProfileError(f"{label} is required")
            return default
        value = table.pop(key)
        if kind is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if kind is not object and (not isinstance(value, kind) or (kind is int and isinstance(value, bool))):
            raise ProfileError(f"{label} must be a {kind.__name__}, not {value!r}")
        try:
            if convert:
                value = convert(value)
            verdict = check(value) if check else True
        except (ValueError, TypeError, AddressError, TargetError) as exc:
            raise ProfileError(f"{label}: {exc}") from None
        if verdict is not True:
            raise ProfileError(f"{label} = {value!r} {verdict}")
        return value

    def done(self, table: dict[str, Any], section: str) -> None:
        if table:
            raise ProfileError(f"{self.where}: unknown key(s) in [{section}]: {', '.join(sorted(table))}")


def _check_target(value: str) -> bool:
    parse_target(value)
    return True


def _check_ranges(value: list) -> bool:
    for item in value:
        if not isinstance(item, str):
            raise ValueError(f"{item!r} is not an address range like 'R4128-R4135'")
        parse_range(item)
    return True


def _chip(value: Any) -> int:
    if isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= 3:
        return value
    if isinstance(value, str) and value in RTC_CHIPS:
        return RTC_CHIPS[value]
    raise ValueError(f"chip must be 0–3 or one of {', '.join(RTC_CHIPS)}, not {value!r}")


def _start(value: Any) -> dt.datetime | None:
    if isinstance(value, dt.datetime):
        return value.replace(tzinfo=None)
    if value == "host":
        return None
    if isinstance(value, str):
        return dt.datetime.fromisoformat(value)
    raise ValueError(f"start must be 'host' or a date-time like '2024-02-29 12:00:00', not {value!r}")
