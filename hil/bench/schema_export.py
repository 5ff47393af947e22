"""What is generated from the profile's declarations (:mod:`hil.bench.schema`): the JSON Schema editors read
(Even Better TOML, through a ``#:schema`` line), the docs' key tables (a page of the documentation site, written
when Sphinx starts: docs/_ext/hil_docs.py) and the sections of ``hil init``'s template.

``python -m hil.bench.schema_export`` rewrites the committed schema (tests/test_profile_schema.py fails while it
differs from what the declarations give).
"""

from __future__ import annotations

import json
import sys
import textwrap
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from hil.bench.family import families
from hil.bench.profile_keys import CORE
from hil.bench.schema import Key, Section, toml_value

SCHEMA_FILE = Path(__file__).with_name("profile.schema.json")
#: core sections whose keys a family declares (each family its own: [faults.<name>] names its injectors)
UNDECLARED = {"faults": "[faults.<name>]: how the bench injects a fault, declared by the family that injects it."}


def declared_sections() -> tuple[Section, ...]:
    """The core's sections, then each installed family's, by family name."""
    return CORE + tuple(s for name in sorted(families()) for s in families()[name].declarations)


def undeclared_sections() -> dict[str, str]:
    """Sections a family reads with its parser alone (no declaration yet), and [faults], with what they are."""
    declared = {s.name for s in declared_sections()}
    out = {name: why for name, why in UNDECLARED.items() if name not in declared}
    for name in sorted(families()):
        plugin = families()[name]
        declared = {s.name for s in plugin.declarations}
        out.update({s: f"read by the {plugin.title} family's parser (not declared key by key)"
                    for s in plugin.sections if s not in declared})
    return out


# -- JSON Schema ---------------------------------------------------------------------------------------------------
_JSON_TYPES = {str: "string", int: "integer", float: "number", bool: "boolean", list: "array", dict: "object"}


def json_schema() -> dict[str, Any]:
    properties: dict[str, Any] = {s.name: _section_schema(s) for s in declared_sections()}
    properties.update({name: {"type": "object", "description": why} for name, why in undeclared_sections().items()})
    return {"$schema": "http://json-schema.org/draft-07/schema#", "title": "hil bench profile",
            "description": "A bench profile of hil (README \"Bench profiles\"); generated from hil.bench.schema "
                           "declarations by `python -m hil.bench.schema_export`.",
            "type": "object", "properties": properties, "required": ["bench"], "additionalProperties": False}


def _section_schema(section: Section) -> dict[str, Any]:
    if section.named:  # [faults.sensor_break], [faults.heater_open]: each a table of the keys
        table = _section_schema(Section(section.name, section.doc, section.keys))
        return {"type": "object", "description": section.doc, "properties": dict.fromkeys(section.named, table),
                "additionalProperties": False}
    out: dict[str, Any] = {"type": "object", "description": section.doc,
                           "properties": {k.name: _key_schema(k) for k in section.keys},
                           "additionalProperties": False}
    required = [k.name for k in section.keys if k.required]
    if required:
        out["required"] = required
    return out


def _key_schema(key: Key) -> dict[str, Any]:
    out: dict[str, Any] = {"description": describe(key)}
    if key.kind in _JSON_TYPES:
        out["type"] = _JSON_TYPES[key.kind]
    if key.default is not None and key.kind is not object:
        out["default"] = list(key.default) if isinstance(key.default, tuple) else key.default
    bounds = {"minimum": key.low, "maximum": key.high, "exclusiveMinimum": key.above}
    out.update({name: value for name, value in bounds.items() if value is not None})
    values: dict[str, Any] = {}
    if key.allowed():
        values["enum"] = list(key.allowed())
    if key.pattern:
        values["pattern"] = f"^(?:{key.pattern})$"
    if key.kind is list:
        out["items"] = {**key.json.get("items", {}), **values}
    else:
        out.update(values)
    out.update({k: v for k, v in key.json.items() if k != "items"})
    out["x-hil-live"] = key.live
    return out


# -- the docs' tables ------------------------------------------------------------------------------------------
def describe(key: Key) -> str:
    """The key's description with its range and where it applies, as the docs, the schema and the template say."""
    limits = key.range_text() if key.kind in (int, float) else ""
    only = "; ".join(f"{other} = {' or '.join(map(toml_value, values))}" for other, values in key.when.items())
    return (key.doc + (f" Range: {limits}." if limits else "") + (f" Only with {only}." if only else "")
            + ("" if key.live else " Emulator only."))


def default_text(key: Key) -> str:
    if key.required:
        return "required"
    if key.default_doc is not None:
        return key.default_doc
    return "none" if key.default is None else toml_value(key.default)


def markdown() -> str:
    lines = ["# Bench profile keys", "",
             "Generated from the declarations (`hil/bench/profile_keys.py` and each family's) when this site was",
             "built.  Editors that read JSON Schema (Even Better TOML: a `#:schema` line at the top of the file, as",
             "`hil init` writes) check a profile against `hil/bench/profile.schema.json`, generated from the same",
             "declarations.  \"Real PLC\": whether the key changes anything on a real bench (no: only the emulator",
             "reads it).", ""]
    for section in declared_sections():
        owner = f" (the {families()[section.family].title} family)" if section.family else ""
        lines += [f"## [{section.name}]{owner}", "", section.doc, "",
                  "| Key | Type | Default | Values | Real PLC | Description |", "|---|---|---|---|---|---|"]
        lines += [_row(key) for key in section.keys] + [""]
    lines += ["## Sections without a declaration", ""]
    lines += [f"- `[{name}]`: {why}" for name, why in undeclared_sections().items()]
    return "\n".join(lines) + "\n"


def _row(key: Key) -> str:
    values = key.range_text() if key.kind in (int, float) else ""
    if key.allowed():
        values = ", ".join(f"`{v}`" for v in key.allowed())
    elif key.pattern:
        values = f"`{key.pattern}`"
    plain = key.required or key.default_doc is not None or key.default is None  # words, not a TOML value
    cells = [f"`{key.name}`", _JSON_TYPES.get(key.kind, "any"),
             default_text(key) if plain else f"`{default_text(key)}`", values,
             "yes" if key.live else "no", key.doc]
    return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"


# -- hil init's template -------------------------------------------------------------------------------------------
def render_section(section: Section, values: dict[str, Any] | None = None, notes: dict[str, str] | None = None,
                   *, active: bool = True, shown: dict[str, Any] | None = None) -> list[str]:
    """``[section]`` as TOML lines: each key's description as a comment, then the key — set to ``values``' value
    where given, else commented out with ``shown``'s value, its example or its default.  ``active=False``: the
    whole section commented out (one that a profile written for this PLC should not set without thought)."""
    values, notes, shown_values = values or {}, notes or {}, shown or {}
    off = "" if active else "# "
    header = f"{section.name}.{section.named[0]}" if section.named else section.name
    lines = [f"# {line}" for line in textwrap.wrap(section.doc, 114)] + [f"{off}[{header}]"]
    for key in section.keys:
        lines += [f"# {line}" for line in textwrap.wrap(describe(key), 114)]
        given = key.name in values
        text = toml_value(values[key.name] if given else shown_values.get(key.name, placeholder(key)))
        note = f"   # {notes[key.name]}" if key.name in notes else ""
        lines.append(f"{off if given else '# '}{key.name} = {text}{note}")
    return lines + [""]


def placeholder(key: Key) -> Any:
    """What the template shows for a key it does not set: an example, the default, or an empty value."""
    if key.example is not None:
        return key.example
    if key.default is not None and key.kind is not object:
        return list(key.default) if isinstance(key.default, tuple) else key.default
    return {str: "", int: 0, float: 0.0, bool: False, list: [], dict: {}}.get(key.kind, "")


def schema_line() -> str:
    """The first line of a generated profile: where Even Better TOML (taplo) finds the schema."""
    return f"#:schema {SCHEMA_FILE.resolve().as_uri()}"


def generated() -> dict[Path, str]:
    """The committed files and what they must hold."""
    return {SCHEMA_FILE: json.dumps(json_schema(), indent=2, ensure_ascii=False) + "\n"}


def main(argv: Iterable[str] = ()) -> int:
    for path, text in generated().items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
