"""The installed controller families (the ``hil.families`` entry-point group), and what a profile needs of one.

Below both the profile (:mod:`hil.bench.profile`, which reads a family's sections) and the full plug-in protocol
(:class:`hil.bench.family.Family`, whose methods take a profile and give a bench): the profile reaches a family
through :class:`FamilySections` only, so neither module imports the other's importer.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable
from importlib.metadata import entry_points
from typing import Any, Protocol

from hil.bench.schema import Section
from hil.core.errors import ProfileError

GROUP = "hil.families"


class FamilySections(Protocol):
    """What a bench profile needs of a controller family: its names and the sections it reads and checks."""

    #: ``[bench] family = …`` in a profile
    name: str
    #: for people: "FATEK FBs", "S7-200 SMART"; with its article: "a FATEK FBs", "an S7-200 SMART"
    title: str
    a_title: str
    #: the profile sections this family reads (parsed by :meth:`parse_sections`)
    sections: tuple[str, ...]
    #: the declarations of those sections' keys (:class:`hil.bench.schema.Section`), for the JSON Schema, the
    #: template and the docs; a section not declared here is checked by its parser alone
    declarations: tuple[Section, ...]
    #: the family of a profile that names none (one installed family says True)
    default: bool
    #: ``[safety] volatile`` when a profile says nothing: values the PLC rewrites itself
    default_volatile: tuple[str, ...]

    def check_ranges(self, ranges: list[Any]) -> bool:
        """True if every item is an address range of this family; else raise ValueError/AddressError."""

    def elements(self, ranges: Iterable[str]) -> frozenset[Any]:
        """The single elements the ranges cover (the guard's unit of permission)."""

    def parse_sections(self, tables: dict[str, dict[str, Any]], where: str) -> dict[str, Any]:
        """This family's sections as typed records (refusing bad ones with the file and key named)."""

    def check_faults(self, faults: dict[str, dict[str, Any]], where: str) -> None:
        """Refuse ``[faults.*]`` tables this family cannot inject."""


# What an entry point loads is untyped (Any): each caller types it as what it needs of a family — the profile as
# FamilySections, everything above it as hil.bench.family.Family.
@functools.cache
def installed() -> dict[str, Any]:
    """Every installed family, by name."""
    found: dict[str, Any] = {}
    for entry in entry_points(group=GROUP):
        plugin = entry.load()
        found[plugin.name] = plugin
    return found


def named(name: str) -> Any:
    """The family registered as ``name``; a ProfileError listing the installed ones otherwise."""
    known = installed()
    if name not in known:
        raise ProfileError(f"unknown controller family {name!r} (installed: {', '.join(sorted(known)) or 'none'}; "
                           f"a family is registered under the {GROUP!r} entry-point group — reinstall hil if "
                           f"this list is empty)")
    return known[name]


def the_default() -> Any:
    """The family a profile without ``[bench] family`` and a bench test without a ``family`` marker are for: the
    one installed family that says ``default = True``."""
    chosen = [plugin for plugin in installed().values() if getattr(plugin, "default", False)]
    if len(chosen) != 1:
        raise ProfileError(f"{len(chosen)} installed controller families claim to be the default "
                           f"({', '.join(p.name for p in chosen) or 'none'}): give [bench] family in the profile")
    return chosen[0]


__all__ = ["GROUP", "FamilySections", "installed", "named", "the_default"]
