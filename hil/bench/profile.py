"""Bench profiles: a TOML file that says which PLC, over which wire, what the harness may write, and the layout.

Every key is checked: an unknown key, a bad address, a bad range or a value of the wrong type is refused with an
error that names the file and the key.  The core reads [bench], [safety], [emulator], [rtc] and [wire_faults];
the controller family named by ``[bench] family`` (a plug-in, :mod:`hil.bench.family`) reads its own sections
([temperature], [pid], [plant] for an FBs; [s7], [s7rtc] for an S7-200 SMART) into typed records, once, and
checks [faults.*] and the address ranges of [safety].
"""

from __future__ import annotations

import re

import hashlib
import tomllib
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any, Callable

from hil.bench.capabilities import DECLARABLE
from hil.bench.family import Family, default_family, families, family as family_named
from hil.bench.lab.spec import LabSpec, parse_section as parse_lab_section
from hil.core.paths import bench_path
from hil.core.errors import AddressError, ProfileError, TargetError
from hil.core.lock import lock_key
from hil.core.registry import PROTOCOLS, SCHEMES
from hil.io.url import Target, parse_target
from hil.bench.lab.resolve import Lab
from hil.sim.wire_faults import KINDS, check_rates
from hil.sim.pacing import LineRate
from hil.sim.timing import MODES as TIMING_MODES, Timing

CORE_SECTIONS = ("bench", "safety", "emulator", "faults", "wire_faults", "labgrid", "history")


@dataclass(frozen=True)
class Safety:
    writable: tuple[str, ...] = ()
    volatile: tuple[str, ...] = ()  # a profile always sets it: its family's default_volatile unless it says
    allow_destructive: bool = False


@dataclass(frozen=True)
class EmulatorSettings:
    scan_time_ms: float = 10.0
    seed: int = 0
    #: ``line = "9600 7E1"``: the pace of the emulator's pty wires (hil.sim.pacing.LineRate); None: unpaced
    line: Any = None
    #: ``timing = "bench"``: publish what the manual lets happen later, later, at phases drawn from ``seed``
    #: (hil.sim.timing); "instant" (the default): at once
    timing: str = "instant"
    #: ``scan_time_range = [MIN, MAX]`` (ms, bench timing only): each scan's length drawn from it; None: every
    #: scan ``scan_time_ms`` long
    scan_time_range_ms: tuple[float, float] | None = None

    def timing_plan(self) -> Timing:
        """The emulator's :class:`~hil.sim.timing.Timing` (the same ``seed`` as the plant's noise: one number
        replays the whole emulated PLC)."""
        scans = self.scan_time_range_ms
        return Timing(self.timing, self.seed, None if scans is None else (scans[0] / 1000, scans[1] / 1000))


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
    #: the family's sections as written ([temperature], [pid], …), for composing new profiles from this one
    areas: dict[str, dict[str, Any]] = field(default_factory=dict)
    faults: dict[str, dict[str, Any]] = field(default_factory=dict)  # [faults.<name>]
    digest: str = ""  # sha256 of the file, for reports
    wire_faults: dict[str, Any] = field(default_factory=dict)  # [wire_faults]: emulator wires only, see below
    family: str = ""  # the controller family plug-in: picks the device layer, emulator and suites
    #: the family's sections parsed once into typed records (e.g. "temperature" → TemperatureConfig)
    sections: dict[str, Any] = field(default_factory=dict)
    #: [bench] scan_counter: a word the bench ladder adds 1 to every scan (fixtures/ladder.md), or None
    scan_counter: str | None = None
    #: [bench] answers_at_scan_end: the wire reaches a port that services each request at the end of a scan (FBs
    #: ports 0, 1, 3, 4): a settle trusts that rule rather than prove each scan with the scan counter
    answers_at_scan_end: bool = False
    #: [bench] scratch: element ranges nobody else uses ("R1000-R1099", "M1000-M1015"), for the smoke suite
    scratch: tuple[str, ...] = ()
    #: [bench] offers: capabilities the bench's owner vouches for (hil.bench.capabilities.DECLARABLE)
    offers: tuple[str, ...] = ()
    #: the labgrid place this run holds (hil.bench.lab.resolve.Lab) when the target came from one, else None
    lab: Any = None
    #: [bench] plc_id: the PLC's name on this site — one lock and one journal for it whatever wire reaches it
    #: (hil.core.lock.plc_key), and the key recovery trusts where the wire reads no identity (Modbus)
    plc_id: str | None = None
    #: [history] url: the run-history store this bench records to (hil.history.config), None for the default
    history_url: str | None = None

    @property
    def rtc(self) -> Any:
        """The FBs family's ``[rtc]`` record (chip, crystal_ppm, start), None without that section."""
        return self.sections.get("rtc")

    @property
    def plugin(self) -> Family:
        return family_named(self.family)

    def can_write(self, name: str) -> bool:
        try:
            wanted = self.plugin.elements([name])
        except (AddressError, ValueError):
            return False
        return wanted <= self._writable_elements

    @cached_property
    def _writable_elements(self) -> Any:
        """``[safety] writable`` expanded once (a suite may ask about thousands of elements)."""
        return self.plugin.elements(self.safety.writable)


# -- reading -----------------------------------------------------------------------------------------------------
def load_profile(path: str | Path, *, lab: Any = None) -> Profile:
    """``lab``: the labgrid place the run holds (:class:`hil.bench.lab.resolve.Lab`), whose URLs replace the
    profile's target and fill its rig (a profile with ``[labgrid]`` cannot be loaded without one).  ``path`` may
    be a bundled profile's short name (``s7-200smart``, :func:`hil.core.paths.bench_path`)."""
    path = bench_path(path)
    raw, data = _read(path)
    return profile_from_dict(data, path=Path(path), digest=hashlib.sha256(raw).hexdigest(), lab=lab)


def _read(path: Path) -> tuple[bytes, dict[str, Any]]:
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ProfileError(f"cannot read bench profile {path}: {exc.strerror} — pass --bench with an existing "
                           f"file or a bundled profile's name (hil list shows them)") from None
    try:
        return raw, tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ProfileError(f"{path}: not valid TOML: {exc}") from None


def lab_request(path: str | Path, *, place: str | None = None, tags: str | None = None,
                coordinator: str | None = None, wait: float | None = None) -> LabSpec | None:
    """The labgrid place a run on this profile asks for: the profile's ``[labgrid]`` with the command line's
    ``--lg-place`` / ``--lg-reserve`` / ``--lg-coordinator`` / ``--lg-wait`` over it; None when neither names one."""
    path = bench_path(path)
    where = str(path)
    data = _read(path)[1]
    spec = parse_lab_section(Reader(where), data) if "labgrid" in data else None
    if spec is None and not (place or tags):
        return None
    return (spec or LabSpec()).overridden(place=place, tags=tags, coordinator=coordinator, wait=wait)


def check_profile(path: str | Path, spec: LabSpec | None) -> Profile:
    """The profile, checked before its labgrid place is reserved (``spec``; stand-in URLs where the place's will
    go), so a bad key costs no wait in the queue; without a place, just the profile."""
    return load_profile(path, lab=Lab.pending(spec) if spec is not None else None)


def profile_from_dict(data: dict[str, Any], *, path: Path | None = None, digest: str = "",
                      lab: Any = None) -> Profile:
    where = str(path) if path else "<profile>"
    if "labgrid" in data:
        spec = parse_lab_section(Reader(where), data)
        if "target" in data.get("bench", {}):
            raise ProfileError(f"{where}: [bench] target and [labgrid] both say where the PLC is: keep one")
        if lab is None:
            raise ProfileError(f"{where} takes its PLC from {spec.describe()}: `hil run --bench {where}` (or pytest "
                               f"--bench) reserves it; other commands need its URL")
    if lab is not None:
        data = lab.apply(data, where)
    installed = families()
    owner = {section: plugin for plugin in installed.values() for section in plugin.sections}
    for section in data:
        if section not in CORE_SECTIONS and section not in owner:
            known = sorted({*CORE_SECTIONS, *owner})
            raise ProfileError(f"{where}: unknown section [{section}] (known: {', '.join(known)})")
    if "bench" not in data:
        raise ProfileError(f"{where}: missing the [bench] section (name, target, station, time_scale)")
    reader = Reader(where)
    bench = reader.table(data, "bench")
    name = reader.take(bench, "bench", "name", str, required=True)
    target = reader.take(bench, "bench", "target", str, "emulator", check=_check_target)
    stated = reader.take(bench, "bench", "station", int, None, check=_check_station)
    station = _one_station(where, parse_target(target), stated)
    time_scale = reader.take(bench, "bench", "time_scale", float, 1.0, check=lambda v: v > 0 or "must be > 0")
    settle = reader.take(bench, "bench", "settle_scans", int, 2, check=lambda v: v >= 1 or "must be ≥ 1")
    timeout = reader.take(bench, "bench", "timeout", float, 2.0, check=lambda v: v > 0 or "must be > 0")
    family = reader.take(bench, "bench", "family", str, default_family().name,
                         check=lambda v: v in installed or f"must be one of {', '.join(sorted(installed))}")
    scan_counter = reader.take(bench, "bench", "scan_counter", str, None,
                               check=lambda v: bool(re.fullmatch(r"[A-Z]+[0-9]+", v))
                               or "must name one word register (letters, then digits)")
    at_scan_end = reader.take(bench, "bench", "answers_at_scan_end", bool, False)
    scratch = reader.take(bench, "bench", "scratch", list, [],
                          check=lambda v: all(isinstance(x, str) and re.fullmatch(r"[A-Z]+[0-9]+(-[A-Z]+[0-9]+)?", x)
                                              for x in v) or "must be a list of element ranges (FIRST-LAST)")
    offers = reader.take(bench, "bench", "offers", list, [],
                         check=lambda v: all(x in DECLARABLE for x in v)
                         or f"may list only {', '.join(DECLARABLE)}, not {', '.join(map(str, v))}")
    plc_id = reader.take(bench, "bench", "plc_id", str, None,
                         check=lambda v: bool(re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9._:/-]{0,63}", v))
                         or "must be a name of 1–64 letters, digits and . _ : / - (e.g. \"line-3-plc-2\")")
    reader.done(bench, "bench")
    plugin = installed[family]

    safety_t = reader.table(data, "safety")
    ranges = plugin.check_ranges
    volatile_default = list(plugin.default_volatile)
    safety = Safety(
        writable=tuple(reader.take(safety_t, "safety", "writable", list, [], check=ranges)),
        volatile=tuple(reader.take(safety_t, "safety", "volatile", list, volatile_default, check=ranges)),
        allow_destructive=reader.take(safety_t, "safety", "allow_destructive", bool, False))
    reader.done(safety_t, "safety")
    _check_overlap(plugin, safety, where)

    emu_t = reader.table(data, "emulator")
    emulator = EmulatorSettings(
        scan_time_ms=reader.take(emu_t, "emulator", "scan_time_ms", float, 10.0,
                                 check=lambda v: 0.1 <= v <= 1000 or "must be 0.1–1000 ms"),
        seed=reader.take(emu_t, "emulator", "seed", int, 0),
        line=reader.take(emu_t, "emulator", "line", str, None, convert=_line_rate),
        timing=reader.take(emu_t, "emulator", "timing", str, "instant",
                           check=lambda v: v in TIMING_MODES or f"must be one of {', '.join(TIMING_MODES)}"),
        scan_time_range_ms=reader.take(emu_t, "emulator", "scan_time_range", list, None, check=_scan_range,
                                       convert=tuple))
    reader.done(emu_t, "emulator")
    if emulator.scan_time_range_ms is not None and emulator.timing != "bench":
        raise ProfileError(f"{where}: [emulator] scan_time_range varies the scans in bench timing only: add "
                           f"timing = \"bench\" or remove it")


    for section in data:
        if section in owner and owner[section] is not plugin:
            other = owner[section]
            raise ProfileError(f"{where}: [{section}] describes {other.a_title}, not {plugin.a_title}: set "
                               f"[bench] family = \"{other.name}\" (or remove the section)")
    areas = {s: reader.table(data, s) for s in plugin.sections if s in data}
    # refused when the profile is read, not when a test runs; parsed once, here
    sections = plugin.parse_sections(areas, where)
    faults_t = reader.table(data, "faults")
    faults = {}
    for fault, table in faults_t.items():
        if not isinstance(table, dict):
            raise ProfileError(f"{where}: [faults.{fault}] must be a table")
        faults[fault] = table
    if faults:
        plugin.check_faults(faults, where)
    wire_faults = _wire_faults(reader, data) if "wire_faults" in data else {}
    history_t = reader.table(data, "history")
    history_url = reader.take(history_t, "history", "url", str, None,
                              check=lambda v: bool(v.strip()) or "must be a URL (sqlite:///PATH, postgresql://…) or 'off'")
    reader.done(history_t, "history")
    return Profile(path, name, target, station, time_scale, settle, timeout, safety, emulator, areas,
                   faults, digest, wire_faults=wire_faults, family=family, sections=sections,
                   scan_counter=scan_counter, answers_at_scan_end=at_scan_end, scratch=tuple(scratch), offers=tuple(offers), lab=lab, plc_id=plc_id,
                   history_url=history_url)


def _check_station(value: int) -> bool | str:
    return 1 <= value <= 254 or "must be 1–254"


def address_param(target: Target) -> str | None:
    """The query parameter that names the PLC on ``target``'s wire (FATEK ``station``, Modbus ``unit``), None where
    the URL takes none (an ``emulator…`` target: its emulator answers as the profile's station; S7's rack/slot)."""
    protocol = PROTOCOLS.get(target.protocol)
    param = protocol.address_param if protocol is not None else None
    return param if param in SCHEMES[target.scheme].params else None


def _one_station(where: str, target: Target, stated: int | None) -> int:
    """The PLC's station: ``[bench] station``, else the one ``[bench] target`` names (``?station=``/``?unit=``),
    else 1.  Both, and different: the profile names two PLCs."""
    param = address_param(target)
    in_url = url_station(target)
    if in_url is None:
        return stated if stated is not None else 1
    if _check_station(in_url) is not True:
        raise ProfileError(f"{where}: [bench] target {target}: {param}={in_url} must be 1–254")
    if stated is not None:
        _agree(where, stated, f"[bench] target says {param}={in_url}", in_url)
    return in_url


def url_station(target: Target) -> int | None:
    """The station (or unit) ``target``'s URL names itself, None when it names none."""
    param = address_param(target)
    given = target.params.get(param) if param is not None else None
    return int(given) if given is not None else None  # type: ignore[call-overload]


def _agree(where: str, station: int, said: str, other: int) -> None:
    if other != station:
        raise ProfileError(f"{where}: [bench] station = {station}, but {said}: one PLC has one station — make them "
                           f"agree (or leave it out of the URL: the profile's station is used on every wire)")


def plc_target(profile: Profile, url: str | None = None) -> Target:
    """The PLC a run or a command on ``profile`` reaches, for every wire and command alike: ``url`` (default: the
    profile's target) addressed at the profile's station (FATEK ``station``, Modbus ``unit``) — on a multidrop
    line station 1 is somebody else's PLC.  A URL naming a PLC must be one the profile names (its allow-list and
    switches are that bench's), and a URL naming a station must name the profile's."""
    target = parse_target(url if url is not None else profile.target)
    if url is not None and not target.in_process:
        _refuse_unnamed(profile, target)
    param, given = address_param(target), url_station(target)
    if param is None:
        return target
    if given is not None:
        _agree(_where(profile), profile.station, f"target {target} says {param}={given}", given)
    return replace(target, params={**target.params, param: profile.station})


def _refuse_unnamed(profile: Profile, target: Target) -> None:
    """A PLC only ever with a profile that names it: not the emulator's (RUN/STOP allowed, broad writable ranges),
    nor another bench's (its allow-list is for another machine)."""
    own = parse_target(profile.target)
    if own.in_process:
        raise ProfileError(f"target {target} names a PLC, and the profile {_where(profile)} is for the emulator "
                           f"(target = {profile.target!r}): its allow-list and switches are not that PLC's — pass "
                           f"--bench with a profile whose [bench] target is that PLC (`hil init {target}` writes one)")
    if lock_key(str(own)) != lock_key(str(target)):
        raise ProfileError(f"target {target} is not the PLC the profile {_where(profile)} names ({profile.target}): "
                           f"its allow-list and switches are that bench's — pass --bench with a profile whose [bench] "
                           f"target is {target} (`hil init {target}` writes one)")


def _where(profile: Profile) -> str:
    return str(profile.path) if profile.path is not None else repr(profile.name)


def refuse_default_for_a_plc(target: str | None, bench: str | None, default: Path | str) -> None:
    """No --bench and a --target naming a PLC (not an ``emulator…`` target): refuse the default profile, which is
    the emulator's (RUN/STOP allowed, broad writable ranges), rather than let it loose on somebody's machine."""
    if target and not bench and not parse_target(target).in_process:
        raise ProfileError(f"--target {target} names a PLC, and no --bench profile was given: the default profile "
                           f"({default}) is the emulator's (RUN/STOP allowed, broad writable ranges) — pass --bench "
                           f"with a profile for this PLC (`hil init {target}` writes one)")


def _check_overlap(plugin: Family, safety: Safety, where: str) -> None:
    """Refuse an element both ``writable`` and ``volatile``: a volatile element is never journaled, so a test's
    write to it would stay on the PLC.  The family's clock elements may be both: the clock restore puts them back."""
    both = (plugin.elements(safety.writable) & plugin.elements(safety.volatile)) - plugin.elements(
        getattr(plugin, "clock_elements", ()))
    if both:
        shown = sorted(both, key=lambda e: (getattr(e, "kind", ""), getattr(e, "index", 0), str(e)))
        names = ", ".join(str(e) for e in shown[:6]) + ("…" if len(shown) > 6 else "")
        raise ProfileError(f"{where}: [safety] volatile and writable overlap at {names}: a volatile element is never "
                           f"journaled, so a test's write to it would be left on the PLC — keep each element in one "
                           f"of the two lists")


def _wire_faults(reader: "Reader", data: dict[str, Any]) -> dict[str, Any]:
    """``[wire_faults]``: faults the emulator's servers put on the wire (emulator+… targets only).

    ``seed`` (int), ``delay_seconds`` (how long a "delay" holds a reply) and ``split_gap`` (seconds), ``script`` (list of kinds, "none" = no fault) and one
    probability (0–1) per kind (drop = 0.01, corrupt = 0.02 …) — see :mod:`hil.sim.wire_faults`."""
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


class Reader:
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


def _scan_range(value: tuple) -> bool | str:
    """``[MIN, MAX]`` in ms, 0.1 ≤ MIN ≤ MAX ≤ 1000 (the range of ``scan_time_ms``)."""
    if len(value) != 2 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        return "must be [MIN, MAX], two numbers of milliseconds"
    low, high = value
    return (0.1 <= low <= high <= 1000) or "must have 0.1 ≤ MIN ≤ MAX ≤ 1000 ms"


def _line_rate(value: str) -> Any:
    return LineRate.parse(value)


def _check_target(value: str) -> bool:
    parse_target(value)
    return True
