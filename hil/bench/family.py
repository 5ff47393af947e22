"""Controller families as plug-ins: each registers an object under the ``hil.families`` entry-point group.

A family brings what the core does not know: its address names (for ``[safety]`` ranges), its profile sections
(parsed once, into typed records), its fault injectors, its emulator and its bench.  The core finds families only
here, by name, so it imports none of them; adding a family is one package plus one entry point::

    [project.entry-points."hil.families"]
    fbs = "hil.families.fbs.plugin:FAMILY"
"""

from __future__ import annotations

import datetime as dt
import functools
from collections.abc import Iterable
from importlib.metadata import entry_points
from typing import TYPE_CHECKING, Any, Protocol

from hil.core.errors import InvalidValue, ProfileError

if TYPE_CHECKING:
    from hil.bench.base import BenchBase
    from hil.bench.profile import Profile
    from hil.bench.schema import Section
    from hil.sim.engine import Engine
    from hil.sim.runtime import ServerHandle

GROUP = "hil.families"


class Family(Protocol):
    """What a controller family plug-in provides (see :mod:`hil.families.fbs.plugin` for one)."""

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

    def check_ranges(self, ranges: list) -> bool:
        """True if every item is an address range of this family; else raise ValueError/AddressError."""

    def elements(self, ranges: Iterable[str]) -> frozenset:
        """The single elements the ranges cover (the guard's unit of permission)."""

    def parse_sections(self, tables: dict[str, dict[str, Any]], where: str) -> dict[str, Any]:
        """This family's sections as typed records (refusing bad ones with the file and key named)."""

    def check_faults(self, faults: dict[str, dict[str, Any]], where: str) -> None:
        """Refuse ``[faults.*]`` tables this family cannot inject."""

    def build_emulator(self, profile: Profile, epoch: dt.datetime) -> Engine:
        """The emulator the profile describes, its clocks starting at ``epoch``."""

    def open_bench(self, profile: Profile, **kwargs: Any) -> BenchBase:
        """The bench for ``profile`` (its PLC behind the guard, its time, its per-test restore)."""

    def serve(self, profile: Profile, emulator: Engine, wire: str, host: str, port: int) -> ServerHandle:
        """Serve ``emulator`` on ``wire`` (one of :attr:`wires`) for other programs (``hil emulate``)."""

    #: the wires :meth:`serve` offers ("fatek-tcp", "modbus-tcp", "s7-tcp", …)
    wires: tuple[str, ...]


@functools.cache
def families() -> dict[str, Family]:
    """Every installed family, by name."""
    found: dict[str, Family] = {}
    for entry in entry_points(group=GROUP):
        plugin = entry.load()
        found[plugin.name] = plugin
    return found


def default_family() -> Family:
    """The family a profile without ``[bench] family`` and a bench test without a ``family`` marker are for: the
    one installed family that says ``default = True``."""
    chosen = [plugin for plugin in families().values() if getattr(plugin, "default", False)]
    if len(chosen) != 1:
        raise ProfileError(f"{len(chosen)} installed controller families claim to be the default "
                           f"({', '.join(p.name for p in chosen) or 'none'}): give [bench] family in the profile")
    return chosen[0]


def open_bench(profile: Profile, **kwargs: Any) -> BenchBase:
    """The bench for the profile's controller family."""
    return family(profile.family).open_bench(profile, **kwargs)


def build_emulator(profile: Profile, epoch: dt.datetime) -> Engine:
    """The emulator of the profile's controller family, as the profile describes it."""
    return family(profile.family).build_emulator(profile, epoch)


def check_wire(plugin: Family, wire: str) -> None:
    """Refuse a wire the family's emulator is not served over, naming the ones it is."""
    if wire not in plugin.wires:
        raise InvalidValue(f"{plugin.a_title} emulator is not served over {wire} (it offers "
                           f"{', '.join(plugin.wires)}; the profile's [bench] family picks the controller)")


def family(name: str) -> Family:
    """The family registered as ``name``; a ProfileError listing the installed ones otherwise."""
    known = families()
    if name not in known:
        raise ProfileError(f"unknown controller family {name!r} (installed: {', '.join(sorted(known)) or 'none'}; "
                           f"a family is registered under the {GROUP!r} entry-point group — reinstall hil if "
                           f"this list is empty)")
    return known[name]
