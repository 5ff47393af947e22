"""Bench profiles: a TOML file that says which PLC, over which wire, what the harness may write, and the layout.

Every key is checked: an unknown key, a bad address, a bad range or a value of the wrong type is refused with an
error that names the file and the key.  The core reads [bench], [safety], [emulator], [rtc] and [wire_faults];
the controller family named by ``[bench] family`` (a plug-in, :mod:`hil.bench.family`) reads its own sections
([temperature], [pid], [plant] for an FBs; [s7], [s7rtc] for an S7-200 SMART) into typed records, once, and
checks [faults.*] and the address ranges of [safety].
"""

from __future__ import annotations

import hashlib
import tomllib
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

from hil.bench.family_registry import FamilySections, installed, named, the_default
from hil.bench.lab.resolve import Lab
from hil.bench.lab.spec import LabSpec
from hil.bench.lab.spec import parse_section as parse_lab_section
from hil.bench.profile_keys import BENCH, EMULATOR, HISTORY, SAFETY, WIRE_FAULTS
from hil.bench.schema import located, with_line
from hil.core.errors import AddressError, ProfileError
from hil.core.lock import lock_key
from hil.core.paths import bench_path
from hil.core.registry import PROTOCOLS, SCHEMES
from hil.io.url import Target, parse_target
from hil.sim.timing import Timing
from hil.sim.wire_faults import KINDS, check_rates

CORE_SECTIONS = ("bench", "safety", "emulator", "faults", "wire_faults", "labgrid", "history")


@dataclass(frozen=True)
class Safety:
    writable: tuple[str, ...] = SAFETY.default("writable")
    volatile: tuple[str, ...] = ()  # a profile always sets it: its family's default_volatile unless it says
    allow_destructive: bool = SAFETY.default("allow_destructive")


@dataclass(frozen=True)
class EmulatorSettings:
    """``[emulator]`` (:data:`hil.bench.profile_keys.EMULATOR` describes each key)."""

    scan_time_ms: float = EMULATOR.default("scan_time_ms")
    seed: int = EMULATOR.default("seed")
    #: a hil.sim.pacing.LineRate; None: unpaced
    line: Any = EMULATOR.default("line")
    #: "bench": publish what the manual lets happen later, later, at phases drawn from ``seed`` (hil.sim.timing)
    timing: str = EMULATOR.default("timing")
    #: (MIN, MAX) ms, bench timing only; None: every scan ``scan_time_ms`` long
    scan_time_range_ms: tuple[float, float] | None = EMULATOR.default("scan_time_range")

    def timing_plan(self) -> Timing:
        """The emulator's :class:`~hil.sim.timing.Timing` (the same ``seed`` as the plant's noise: one number
        replays the whole emulated PLC)."""
        scans = self.scan_time_range_ms
        return Timing(self.timing, self.seed, None if scans is None else (scans[0] / 1000, scans[1] / 1000))


@dataclass(frozen=True)
class Profile:
    path: Path | None
    name: str
    target: str = BENCH.default("target")
    station: int = 1  # (the profile's [bench] station, else its target's, else 1: _one_station)
    time_scale: float = BENCH.default("time_scale")
    settle_scans: int = BENCH.default("settle_scans")
    timeout: float = BENCH.default("timeout")
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
    scan_counter: str | None = BENCH.default("scan_counter")
    #: [bench] answers_at_scan_end: the wire reaches a port that services each request at the end of a scan (FBs
    #: ports 0, 1, 3, 4): a settle trusts that rule rather than prove each scan with the scan counter
    answers_at_scan_end: bool = BENCH.default("answers_at_scan_end")
    #: [bench] scratch: element ranges nobody else uses ("R1000-R1099", "M1000-M1015"), for the smoke suite
    scratch: tuple[str, ...] = BENCH.default("scratch")
    #: [bench] offers: capabilities the bench's owner vouches for (hil.bench.capabilities.DECLARABLE)
    offers: tuple[str, ...] = BENCH.default("offers")
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
    def plugin(self) -> FamilySections:
        return named(self.family)

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
    be a bundled profile's short name (``s7-200smart``, :func:`hil.core.paths.bench_path`).  An error names the
    line of the key it is about (``<file>:<line>: [section] key …``)."""
    path = bench_path(path)
    raw, data = _read(path)
    try:
        return profile_from_dict(data, path=Path(path), digest=hashlib.sha256(raw).hexdigest(), lab=lab)
    except ProfileError as exc:
        raise with_line(exc, raw.decode("utf-8"), str(path)) from None


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
    raw, data = _read(path)
    try:
        spec = parse_lab_section(data, str(path)) if "labgrid" in data else None
    except ProfileError as exc:
        raise with_line(exc, raw.decode("utf-8"), str(path)) from None
    if spec is None and not (place or tags):
        return None
    return (spec or LabSpec()).overridden(place=place, tags=tags, coordinator=coordinator, wait=wait)


def check_profile(path: str | Path, spec: LabSpec | None) -> Profile:
    """The profile, checked before its labgrid place is reserved (``spec``; stand-in URLs where the place's will
    go), so a bad key costs no wait in the queue; without a place, just the profile."""
    return load_profile(path, lab=Lab.pending(spec) if spec is not None else None)


def profile_from_dict(data: dict[str, Any], *, path: Path | None = None, digest: str = "",
                      lab: Any = None) -> Profile:
    """The profile ``data`` describes, every key checked against its declaration (:mod:`hil.bench.profile_keys`
    and the family's own)."""
    where = str(path) if path else "<profile>"
    data = _placed(data, where, lab)
    owner = _section_owners(data, where)
    if "bench" not in data:
        raise ProfileError(f"{where}: missing the [bench] section (name, target, station, time_scale)")
    bench = BENCH.read(data["bench"], where, defaults={"family": the_default().name})
    bench["station"] = _one_station(where, parse_target(bench["target"]), bench["station"])
    plugin = named(bench["family"])
    _refuse_other_family(data, owner, plugin, where)
    areas = {s: _table(data, s, where) for s in plugin.sections if s in data}
    return Profile(
        path=path, digest=digest, lab=lab, **bench, safety=_safety(data, plugin, where),
        emulator=_emulator(data, where), areas=areas,
        sections=plugin.parse_sections(areas, where),  # refused when the profile is read, not when a test runs
        faults=_faults(data, plugin, where),
        wire_faults=_wire_faults(data, where) if "wire_faults" in data else {},
        **HISTORY.read(data.get("history", {}), where))


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


def _check_overlap(plugin: FamilySections, safety: Safety, where: str) -> None:
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


def _placed(data: dict[str, Any], where: str, lab: Any) -> dict[str, Any]:
    """``data`` with the labgrid place's URLs in (``lab``); a ``[labgrid]`` profile needs a place to load."""
    if "labgrid" in data:
        spec = parse_lab_section(data, where)
        if "target" in data.get("bench", {}):
            raise located(ProfileError(f"{where}: [bench] target and [labgrid] both say where the PLC is: keep one"),
                          "bench", "target")
        if lab is None:
            raise ProfileError(f"{where} takes its PLC from {spec.describe()}: `hil run --bench {where}` (or pytest "
                               f"--bench) reserves it; other commands need its URL")
    return data if lab is None else lab.apply(data, where)


def _section_owners(data: dict[str, Any], where: str) -> dict[str, FamilySections]:
    """Which installed family reads each family section, refusing a section nobody reads."""
    owner = {section: plugin for plugin in installed().values() for section in plugin.sections}
    for section in data:
        if section not in CORE_SECTIONS and section not in owner:
            known = sorted({*CORE_SECTIONS, *owner})
            raise located(ProfileError(f"{where}: unknown section [{section}] (known: {', '.join(known)})"), section)
    return owner


def _refuse_other_family(data: dict[str, Any], owner: dict[str, FamilySections], plugin: FamilySections,
                         where: str) -> None:
    for section in data:
        if section in owner and owner[section] is not plugin:
            other = owner[section]
            raise located(ProfileError(f"{where}: [{section}] describes {other.a_title}, not {plugin.a_title}: set "
                                       f"[bench] family = \"{other.name}\" (or remove the section)"), section)


def _table(data: dict[str, Any], section: str, where: str) -> dict[str, Any]:
    table = data.get(section, {})
    if not isinstance(table, dict):
        raise located(ProfileError(f"{where}: [{section}] must be a table"), section)
    return dict(table)


def _safety(data: dict[str, Any], plugin: FamilySections, where: str) -> Safety:
    """``[safety]``, its ranges in the family's addresses (its clock read-out volatile unless the profile says)."""
    ranges = {"writable": plugin.check_ranges, "volatile": plugin.check_ranges}
    safety = Safety(**SAFETY.read(data.get("safety", {}), where, checks=ranges,
                                  defaults={"volatile": tuple(plugin.default_volatile)}))
    _check_overlap(plugin, safety, where)
    return safety


def _emulator(data: dict[str, Any], where: str) -> EmulatorSettings:
    emulator = EmulatorSettings(**EMULATOR.read(data.get("emulator", {}), where))
    if emulator.scan_time_range_ms is not None and emulator.timing != "bench":
        raise located(ProfileError(f"{where}: [emulator] scan_time_range varies the scans in bench timing only: "
                                   f"add timing = \"bench\" or remove it"), "emulator", "scan_time_range")
    return emulator


def _faults(data: dict[str, Any], plugin: FamilySections, where: str) -> dict[str, dict[str, Any]]:
    """``[faults.<name>]`` tables, checked by the family that injects them."""
    faults = {}
    for fault, table in _table(data, "faults", where).items():
        if not isinstance(table, dict):
            raise located(ProfileError(f"{where}: [faults.{fault}] must be a table"), f"faults.{fault}")
        faults[fault] = table
    if faults:
        plugin.check_faults(faults, where)
    return faults


def _wire_faults(data: dict[str, Any], where: str) -> dict[str, Any]:
    """``[wire_faults]``: faults the emulator's servers put on the wire (emulator+… targets only) —
    see :mod:`hil.sim.wire_faults`."""
    out = WIRE_FAULTS.read(data["wire_faults"], where)
    try:
        check_rates({k: out[k] for k in KINDS})
    except ValueError as exc:
        raise located(ProfileError(f"{where}: [wire_faults] {exc}"), "wire_faults") from None
    return out


