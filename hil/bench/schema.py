"""The profile's keys, declared once: each :class:`Key` says its type, default, range, description and whether it
reaches a real PLC; a :class:`Section` reads a TOML table against its keys.

Everything else is derived from these declarations: the loader's checks and errors (here), the JSON Schema for
editors, ``hil init``'s template and the docs' key tables (:mod:`hil.bench.schema_export`).  The core declares its
sections in :mod:`hil.bench.profile_keys`; a family declares its own beside its parser and lists them in its
plug-in's ``declarations``.

Why not pydantic: the errors are the product here ("<file>: [bench] station = 300 must be 1–254"), several checks
depend on the bench's family (its address ranges, its default ``volatile``), and the JSON Schema of flat tables of
scalars is a few lines; a model class per section plus a translation of pydantic's error types back into this
wording would be more code than the declarations it replaces, and one more compiled dependency on bench hosts.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from hil.core.errors import AddressError, ProfileError, TargetError

#: what a check may raise to refuse a value; the message follows "<file>: [section] key: "
REFUSALS = (ValueError, TypeError, AddressError, TargetError)

#: what the errors call a type, in TOML's words where Python's differ
_TOML_NAMES: dict[type, str] = {dict: "table", list: "list"}

Verdict = Callable[[Any], "bool | str"]


@dataclass(frozen=True)
class Key:
    """One key of a profile section.  ``check`` (True or the reason, after "<key> = <value>") and ``convert`` (may
    raise ValueError) cover what the declarative limits below cannot say."""

    name: str
    kind: type  # str, int, float (ints accepted), bool, list, dict; object: any TOML value (``convert`` decides)
    doc: str
    default: Any = None
    required: bool = False
    #: False: only the emulator reads it (on a real PLC it changes nothing)
    live: bool = True
    low: float | None = None  # inclusive bounds of a number
    high: float | None = None
    above: float | None = None  # exclusive lower bound
    unit: str = ""  # after the range in messages and docs: "ms", "s"
    #: allowed values (of each item, for a list); a callable when the set is registered at run time
    choices: tuple[Any, ...] | Callable[[], Iterable[Any]] = ()
    pattern: str | None = None  # a string (each item, for a list) matches it in full
    hint: str | None = None  # the reason given when a limit above refuses the value
    check: Verdict | None = None
    convert: Callable[[Any], Any] | None = None
    #: the record's field, when not the key's name
    attr: str | None = None
    #: what ``hil init`` writes as a commented placeholder when the default says nothing ("R3999")
    example: Any = None
    #: the default in words, when it depends on the bench ("the family's clock read-out")
    default_doc: str | None = None
    #: given only beside these values of another key: {"kind": ("modbus-coil",)}
    when: dict[str, tuple[Any, ...]] = field(default_factory=dict)
    #: more JSON Schema for editors (e.g. the items of a list), beside what the limits above give
    json: dict[str, Any] = field(default_factory=dict)

    def allowed(self) -> tuple[Any, ...]:
        return tuple(self.choices() if callable(self.choices) else self.choices)

    def limits(self, value: Any) -> bool | str:
        """True, or why ``value`` is outside the declared limits."""
        items = value if self.kind is list else [value]
        allowed = self.allowed()
        if allowed and not all(v in allowed for v in items):
            if self.kind is list:
                return self.hint or f"may list only {', '.join(map(str, allowed))}, not {', '.join(map(str, value))}"
            return self.hint or f"must be one of {', '.join(map(str, allowed))}"
        if self.pattern and not all(isinstance(v, str) and re.fullmatch(self.pattern, v) for v in items):
            return self.hint or f"must match {self.pattern}"
        if self.kind in (int, float) and not self._in_range(value):
            return self.hint or f"must be {self.range_text()}"
        return True

    def _in_range(self, value: float) -> bool:
        return ((self.low is None or value >= self.low) and (self.high is None or value <= self.high)
                and (self.above is None or value > self.above))

    def range_text(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        if self.low is not None and self.high is not None:
            return f"{self.low:g}–{self.high:g}{unit}"
        if self.above is not None:
            return f"> {self.above:g}{unit}"
        if self.low is not None:
            return f"≥ {self.low:g}{unit}"
        return f"≤ {self.high:g}{unit}" if self.high is not None else ""


@dataclass(frozen=True)
class Section:
    """A profile table and its keys.  ``family``: the family plug-in that reads it (None: the core)."""

    name: str
    doc: str
    keys: tuple[Key, ...]
    family: str | None = None
    #: a TOML array of tables (``[[pid.instances]]``) rather than one table
    array: bool = False
    #: a table of tables, one per name ([faults.sensor_break], [faults.heater_open]), each with these keys
    named: tuple[str, ...] = ()

    def key(self, name: str) -> Key:
        return next(k for k in self.keys if k.name == name)

    def default(self, name: str) -> Any:
        """The value a record holds when the key is not given: the declared default, converted as a given value
        would be (so a record's field defaults come from here, not from a second copy)."""
        key = self.key(name)
        return _converted(key, key.default)

    def read(self, table: Any, where: str, *, checks: Mapping[str, Verdict] | None = None,
             defaults: dict[str, Any] | None = None, label: str | None = None, nth: int = 0) -> dict[str, Any]:
        """The table's values by record field (every declared key, its default where the table has none), refusing
        an unknown key, a missing required one and a bad value with "<file>: [section] key …".  ``checks`` and
        ``defaults`` add what depends on the bench (its family's address ranges and defaults); ``label`` and
        ``nth`` name the table of an array ("[pid] instances[2]", the third [[pid.instances]])."""
        at = Place(where, label or f"[{self.name}]", self.name, nth)
        if not isinstance(table, dict):
            raise at.error(None, "must be a table")
        unknown = sorted(set(table) - {k.name for k in self.keys})
        if unknown:
            raise located(ProfileError(f"{where}: unknown key(s) in {at.label}: {', '.join(unknown)}"),
                          self.name, unknown[0], nth)
        checks, defaults = checks or {}, defaults or {}
        out = {}
        for key in self.keys:
            if key.name in table:
                value = _value(key, table[key.name], at, checks.get(key.name))
            elif key.required:
                such = f" (such as {key.name} = {toml_value(key.example)})" if key.example is not None else ""
                raise at.error(None, f"{key.name} is required{such}")
            else:
                value = _converted(key, defaults.get(key.name, key.default))
            out[key.attr or key.name] = value
        _refuse_out_of_place(self.keys, table, at)  # after the keys it depends on are checked
        return out


def _refuse_out_of_place(keys: tuple[Key, ...], table: dict[str, Any], at: Place) -> None:
    """Refuse keys given beside a value of another key they do not go with (``Key.when``)."""
    for key in keys:
        for other, values in key.when.items():
            if key.name in table and table.get(other) not in values:
                known = sorted(k.name for k in keys if all(table.get(o) in v for o, v in k.when.items()))
                wrong = sorted(k.name for k in keys if k.name in table and k.name not in known)
                raise located(ProfileError(f"{at.where}: {at.label}: unknown key(s) for {other} = "
                                           f"{table.get(other)!r}: {', '.join(wrong)} (known: {', '.join(known)})"),
                              at.section, wrong[0], at.nth)


@dataclass(frozen=True)
class Place:
    """Where a value is: the file, the table as the errors name it, and the table's header in the file."""

    where: str
    label: str
    section: str
    nth: int = 0

    def error(self, key: str | None, text: str) -> ProfileError:
        """"<file>: <table> <text>" (``text`` begins with the key where it is about one)."""
        return located(ProfileError(f"{self.where}: {self.label} {text}"), self.section, key, self.nth)


def _value(key: Key, value: Any, at: Place, extra: Verdict | None) -> Any:
    """``value`` checked against ``key``'s declaration (and ``extra``), converted."""
    if key.kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if key.kind is not object and (not isinstance(value, key.kind) or (key.kind is int and isinstance(value, bool))):
        raise at.error(key.name, f"{key.name} must be a {_TOML_NAMES.get(key.kind, key.kind.__name__)}, not {value!r}")
    try:
        verdict = key.limits(value)
        for check in (key.check, extra):
            if verdict is True and check is not None:
                verdict = check(value)
        if verdict is True and key.convert is not None:
            value = key.convert(value)
    except REFUSALS as exc:
        raise at.error(key.name, f"{key.name}: {exc}") from None
    if verdict is not True:
        raise at.error(key.name, f"{key.name} = {value!r} {verdict}")
    return value


def _converted(key: Key, value: Any) -> Any:
    return key.convert(value) if value is not None and key.convert is not None else value


def located(error: ProfileError, section: str, key: str | None = None, nth: int = 0) -> ProfileError:
    """Mark where in the file ``error`` is: ``key`` of the ``nth`` table headed ``[section]`` (the loader, which has
    the text, adds the line: :func:`with_line`)."""
    error.place = (section, key, nth)  # type: ignore[attr-defined]
    return error


def with_line(error: ProfileError, text: str, where: str) -> ProfileError:
    """``error`` with "<file>:<line>:" in front where the key (or its section) is found in the file's ``text``."""
    place: tuple[str, str | None, int] | None = getattr(error, "place", None)
    message = str(error)
    line = line_of(text, *place) if place else None
    if place is None or line is None or not message.startswith(f"{where}: "):
        return error
    return located(ProfileError(f"{where}:{line}: {message[len(where) + 2:]}"), *place)


_HEADER = re.compile(r"\s*\[\[?\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")


def line_of(text: str, section: str, key: str | None = None, nth: int = 0) -> int | None:
    """The 1-based line of ``key`` in the ``nth`` table headed ``[section]`` (of that header when ``key`` is None or
    not found): enough TOML to point an editor at the line, not a parser (tomllib has read the file already)."""
    inside, seen, header = False, -1, None
    assignment = re.compile(rf"\s*(\"?){re.escape(key)}\1\s*=") if key else None
    for number, line in enumerate(text.splitlines(), 1):
        match = _HEADER.match(line)
        if match:
            inside = match.group(1).replace('"', "") == section and (seen := seen + 1) == nth
            header = number if inside else header
        elif inside and assignment is not None and assignment.match(line):
            return number
    return header


def toml_value(value: Any) -> str:
    """``value`` written as TOML (the scalars, lists and inline tables a profile holds)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return f"{value!r}"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(map(toml_value, value)) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(f"no TOML for {value!r}")
