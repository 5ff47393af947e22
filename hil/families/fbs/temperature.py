"""FBs temperature modules (manual ch. 20.1–20.4): module and sensor kinds, the table at SR, the work block at TW,
and the ``[temperature]`` section of a bench profile.

Names and layouts only — what the device helper reads and what the emulator writes.  Suites state their
expectations (A556H, 56H, 28767) literally; they never take them from here.

The numeric codes of sensor kinds and module names inside the table are not in the manual: they are
**[our choice]** and defined here only (``MODULES[...].code``, ``SENSORS[...].code``).  The module codes follow
the order in which the manual lists the modules in 20.3 (①6TC ②6RTD ③16TC ④16RTD ⑤2TC ⑥6NTC).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TypeVar

from hil.bench.schema import Key, Section, located
from hil.core.errors import AddressError, InvalidValue, ProfileError
from hil.families.fbs.address import WORD_BANKS, Address, parse
from hil.families.fbs.registers import MAX_POINTS

if TYPE_CHECKING:
    import numpy as np

#: how a section's parser says a key is wrong: ``raise fail(key, why)`` (the error names the file and the line)
Fail = Callable[[str, str], ProfileError]
#: a temperature: one value, or an array of them (the emulator converts measurements in batches)
Degrees = TypeVar("Degrees", float, "np.ndarray")

TABLE_MARKER = 0xA556  # SR+0: the table is valid only with this value
BREAK_VALUE = 28767  # reading of a fitted point whose sensor is open
MAX_MODULES = 8

# Execution code, high byte of TW+0
EXEC_IDLE = 0x00
EXEC_TOO_MANY_POINTS = 0xFF
EXEC_BAD_MODULE_COUNT = 0xFE
EXEC_MEASURING = 0x56

UNITS = ("C", "F")
AVERAGING = (1, 2, 4, 8)
RATES = ("normal", "fast")


@dataclass(frozen=True)
class SensorKind:
    name: str
    code: int  # [our choice]
    family: str  # "TC", "RTD", "NTC"
    low_c: float  # measuring range, °C
    high_c: float


@dataclass(frozen=True)
class ModuleType:
    name: str
    code: int  # [our choice], see the module docstring
    points: int
    family: str
    update_s: dict[str, float]  # rate → seconds for every point of the module to be measured once


# Ranges from 20.1.  NTC ranges are not in the manual: [our choice] −50…150 °C (typical NTC thermistors).
SENSORS: dict[str, SensorKind] = {s.name: s for s in (
    SensorKind("J", 0x01, "TC", -200, 900), SensorKind("K", 0x02, "TC", -190, 1300),
    SensorKind("T", 0x03, "TC", -190, 380), SensorKind("E", 0x04, "TC", -190, 1000),
    SensorKind("N", 0x05, "TC", -200, 1000), SensorKind("B", 0x06, "TC", 350, 1800),
    SensorKind("R", 0x07, "TC", 0, 1800), SensorKind("S", 0x08, "TC", 0, 1700),
    SensorKind("PT100", 0x10, "RTD", -200, 850), SensorKind("PT1000", 0x11, "RTD", -200, 600),
    SensorKind("NTC2K", 0x20, "NTC", -50, 150), SensorKind("NTC5K", 0x21, "NTC", -50, 150),
    SensorKind("NTC10K", 0x22, "NTC", -50, 150), SensorKind("NTC20K", 0x23, "NTC", -50, 150),
)}
_SENSOR_ALIASES = {"PT-100": "PT100", "PT-1000": "PT1000", "2K": "NTC2K", "5K": "NTC5K", "10K": "NTC10K",
                   "20K": "NTC20K"}

# Update times from 20.1; "fast" is the shorter one (the chapter's introduction: normal 4 s / 0.1°, fast 2 s / 1°).
MODULES: dict[str, ModuleType] = {m.name: m for m in (
    ModuleType("6TC", 1, 6, "TC", {"normal": 4.0, "fast": 2.0}),
    ModuleType("6RTD", 2, 6, "RTD", {"normal": 2.0, "fast": 1.0}),
    ModuleType("16TC", 3, 16, "TC", {"normal": 6.0, "fast": 3.0}),
    ModuleType("16RTD", 4, 16, "RTD", {"normal": 4.0, "fast": 2.0}),
    ModuleType("2TC", 5, 2, "TC", {"normal": 2.0, "fast": 1.0}),
    ModuleType("6NTC", 6, 6, "NTC", {"normal": 2.0, "fast": 1.0}),
)}
MODULE_BY_CODE = {m.code: m for m in MODULES.values()}
SENSOR_BY_CODE = {s.code: s for s in SENSORS.values()}


def sensor_kind(name: str) -> SensorKind:
    key = name.strip().upper()
    key = _SENSOR_ALIASES.get(key, key)
    if key not in SENSORS:
        raise InvalidValue(f"unknown sensor {name!r} (known: {', '.join(SENSORS)})")
    return SENSORS[key]


def module_type(name: str) -> ModuleType:
    key = name.strip().upper().removeprefix("FBS-")
    if key not in MODULES:
        raise InvalidValue(f"unknown module {name!r} (known: {', '.join(MODULES)})")
    return MODULES[key]


def to_unit(celsius: Degrees, unit: str) -> Degrees:
    return celsius if unit == "C" else celsius * 9 / 5 + 32


# -- register-number encoding in SR+2/SR+3 -------------------------------------------------------------------------
# [our choice]: the manual does not say how "R5000" or "D0" is stored in one word.  We borrow R4004's encoding
# (10000 + n → Rn, 20000 + n → Dn) so that one word names either bank.
def encode_start(address: Address) -> int:
    if address.kind == "R":
        return 10000 + address.index
    if address.kind == "D":
        return 20000 + address.index
    raise InvalidValue(f"{address} is neither an R nor a D register")


def decode_start(word: int) -> Address | None:
    """The register a table word names, or None when the word names none."""
    try:
        if 10000 <= word < 20000:
            return parse(f"R{word - 10000}")
        if 20000 <= word < 30000:
            return parse(f"D{word - 20000}")
    except AddressError:
        return None
    return None


# -- the [temperature] profile section ----------------------------------------------------------------------------
def _start_register(value: str) -> Address:
    address = parse(value)
    encode_start(address)  # an R or D register: the table names it in one word
    return address


def _unit(value: str) -> str:
    return value.upper().removeprefix("°")


_REGISTER = "an R or D register such as 'R3000'"
TEMPERATURE = Section("temperature", "Where the ladder keeps the temperature table (SR, 4 + N words), the readings "
                      "(one word per point, 0.1°) and the work block (TW, 4 + 4N words), and the modules fitted, in "
                      "expansion order (at most 8 modules / 32 points). Add \"R4010-R4011\" to [safety] writable "
                      "for the mask checks, the table's SR…SR+11 for the FEH/FFH/mismatch checks.", (
    Key("table", str, f"The table's first register SR, {_REGISTER}.", required=True, convert=_start_register,
        example="R3000"),
    Key("readings", str, f"The first reading's register, {_REGISTER}.", required=True, convert=_start_register,
        example="R3020"),
    Key("work", str, f"The work block's first register TW, {_REGISTER}.", required=True, convert=_start_register,
        example="R3060"),
    Key("modules", list, "The modules fitted, in expansion order: [{type = \"16TC\", sensor = \"K\"}, …] "
        f"(types {' '.join(MODULES)}; sensors {' '.join(SENSORS)}).", required=True,
        example=[{"type": "16TC", "sensor": "K"}], json={"items": {"type": "object", "properties": {
            "type": {"type": "string"}, "sensor": {"type": "string"}}, "required": ["type", "sensor"]}}),
    Key("unit", str, "\"C\" or \"F\", as configured in WinProladder (not readable from the PLC).", "C",
        check=lambda v: _unit(v) in UNITS or "must be \"C\" or \"F\"", convert=_unit),
    Key("averaging", int, "Readings averaged: 1, 2, 4 or 8.", 1, choices=AVERAGING, hint="must be 1, 2, 4 or 8"),
    Key("rate", str, "\"normal\" (0.1°) or \"fast\" (1° resolution): how long the suites wait for an update.",
        "normal", choices=RATES, hint="must be \"normal\" or \"fast\""),
    Key("sources", dict, "What the emulator's points read: {\"0\" = {kind = \"fixed\", celsius = 25.0}, "
        "\"3\" = {kind = \"ramp\", start = 20, per_s = 0.5}}.", {}, live=False),
    Key("reference", dict, "Points a calibrator or ice point holds at a known °C, checked within the module's "
        "accuracy: {\"5\" = 0.0}.", {}),
    Key("reference_tolerance", float, "The reference's own uncertainty.", 0.0, low=0, unit="°C",
        hint="must be a number of °C ≥ 0"),
), family="fbs")


@dataclass(frozen=True)
class ModuleConfig:
    type: ModuleType
    sensor: SensorKind


@dataclass(frozen=True)
class TemperatureConfig:
    """Where the table, readings and work block live, and which modules are fitted, from ``[temperature]``."""

    table: Address
    readings: Address
    work: Address
    modules: tuple[ModuleConfig, ...]
    unit: str = TEMPERATURE.default("unit")
    averaging: int = TEMPERATURE.default("averaging")
    rate: str = TEMPERATURE.default("rate")
    sources: dict[int, dict[str, Any]] = field(default_factory=dict)  # emulator only: point → source spec
    #: point → °C a reference holds it at on this bench (a calibrator, an ice point, a stable bath): the readings
    #: suite checks those points within the module's accuracy (the emulator holds them there too)
    reference: dict[int, float] = field(default_factory=dict)
    #: °C: the reference's own uncertainty, added to the module's accuracy
    reference_tolerance: float = TEMPERATURE.default("reference_tolerance")

    @property
    def points(self) -> int:
        return sum(m.type.points for m in self.modules)

    def point_module(self, point: int) -> tuple[int, ModuleConfig]:
        """(module index, module) that measures ``point``."""
        first = 0
        for k, module in enumerate(self.modules):
            if point < first + module.type.points:
                return k, module
            first += module.type.points
        raise IndexError(f"point {point} is not configured (the modules give {self.points} points)")

    def update_period(self) -> float:
        """Seconds after which every point has been measured again (the slowest module at this rate)."""
        return max(m.type.update_s[self.rate] for m in self.modules)

    def table_words(self) -> list[int]:
        """SR+0 … SR+3+N as WinProladder (or the ladder) writes them."""
        return [TABLE_MARKER, len(self.modules), encode_start(self.readings), encode_start(self.work)] + [
            m.sensor.code << 8 | m.type.code for m in self.modules]


def parse_temperature(section: dict[str, Any], where: str = "<profile>") -> TemperatureConfig:
    """Validate a ``[temperature]`` table (:data:`TEMPERATURE`, then what spans keys: the modules, the blocks'
    overlaps, the points named); ProfileError names the key and the reason."""
    def fail(key: str, why: str) -> ProfileError:
        return located(ProfileError(f"{where}: [temperature] {key}: {why}"), "temperature", key.split(".")[0])

    values = TEMPERATURE.read(section, where)
    modules = _parse_modules(values.pop("modules"), fail)
    points = sum(m.type.points for m in modules)
    starts = {key: values[key] for key in ("table", "readings", "work")}
    _check_blocks(starts, {"table": 4 + len(modules), "readings": points, "work": 4 + 4 * len(modules)}, fail)
    values["sources"] = _parse_sources(values["sources"], points, fail)
    values["reference"] = _parse_reference(values["reference"], points, fail)
    return TemperatureConfig(modules=modules, **values)


def _parse_modules(raw: list, fail: Fail) -> tuple[ModuleConfig, ...]:
    if not raw:
        raise fail("modules", "must be a non-empty list like [{type = \"6TC\", sensor = \"K\"}]")
    if len(raw) > MAX_MODULES:
        raise fail("modules", f"{len(raw)} modules; an FBs takes at most {MAX_MODULES}")
    modules = []
    for i, item in enumerate(raw):
        label = f"modules[{i}]"
        if not isinstance(item, dict) or set(item) - {"type", "sensor"} or "type" not in item or "sensor" not in item:
            raise fail(label, f"must be {{type = \"6TC\", sensor = \"K\"}}, not {item!r}")
        try:
            mtype = module_type(str(item["type"]))
            sensor = sensor_kind(str(item["sensor"]))
        except ValueError as exc:
            raise fail(label, str(exc)) from None
        if sensor.family != mtype.family:
            raise fail(label, f"sensor {sensor.name} ({sensor.family}) is not valid for an FBs-{mtype.name} "
                              f"(takes {mtype.family} sensors)")
        modules.append(ModuleConfig(mtype, sensor))
    points = sum(m.type.points for m in modules)
    if points > MAX_POINTS:
        raise fail("modules", f"{points} points; an FBs measures at most {MAX_POINTS}")
    return tuple(modules)


def _check_blocks(starts: dict[str, Address], sizes: dict[str, int], fail: Fail) -> None:
    """The table, readings and work blocks neither overlap nor run past their bank."""
    names = list(sizes)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            sa, sb = starts[a], starts[b]
            if sa.kind == sb.kind and sa.index < sb.index + sizes[b] and sb.index < sa.index + sizes[a]:
                raise fail(b, f"the {b} block {sb}+{sizes[b]} overlaps the {a} block {sa}+{sizes[a]}")
    for key, start in starts.items():
        if start.index + sizes[key] > _bank_size(start.kind):
            raise fail(key, f"the {key} block {start}+{sizes[key]} runs past the end of the {start.kind} bank")


def _point_table(raw: Any, points: int, fail: Fail, name: str, shape: str) -> list[tuple[str, Any]]:
    """A profile table keyed by configured point ("0" … points − 1): its (key, value) pairs, or the key that is not
    one, named."""
    if not isinstance(raw, dict):
        raise fail(name, f"must be a table of point → {shape}")
    for key in raw:
        if not str(key).isdigit() or int(key) >= points:
            raise fail(f"{name}.{key}", f"is not a configured point (0–{points - 1})")
    return list(raw.items())


def _parse_reference(raw: Any, points: int, fail: Fail) -> dict[int, float]:
    """``reference = {"10" = 28.0, "11" = 28.3}``: point → °C."""
    out = {}
    for key, celsius in _point_table(raw, points, fail, "reference", "°C, like {\"10\" = 25.0}"):
        if isinstance(celsius, bool) or not isinstance(celsius, (int, float)):
            raise fail(f"reference.{key}", f"must be a temperature in °C, not {celsius!r}")
        out[int(key)] = float(celsius)
    return out


def _bank_size(kind: str) -> int:
    return WORD_BANKS[kind]


def _parse_sources(raw: Any, points: int, fail: Fail) -> dict[int, dict[str, Any]]:
    """``sources = {"0" = {kind = "fixed", celsius = 25.0}, "3" = {kind = "ramp", start = 20, per_s = 0.5}}``."""
    out = {}
    for key, spec in _point_table(raw, points, fail, "sources", "{kind = \"fixed\" | \"ramp\", …}"):
        if not isinstance(spec, dict) or spec.get("kind") not in ("fixed", "ramp"):
            raise fail(f"sources.{key}", "must be {kind = \"fixed\", celsius = …} or "
                                         "{kind = \"ramp\", start = …, per_s = …}")
        out[int(key)] = dict(spec)
    return out
