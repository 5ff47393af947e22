"""Controller families as plug-ins: each registers an object under the ``hil.families`` entry-point group.

A family brings what the core does not know: its address names (for ``[safety]`` ranges), its profile sections
(parsed once, into typed records), its fault injectors, its emulator and its bench.  The core finds families only
here, by name, so it imports none of them; adding a family is one package plus one entry point::

    [project.entry-points."hil.families"]
    fbs = "hil.families.fbs.plugin:FAMILY"
"""

from __future__ import annotations

import datetime as dt
from typing import TYPE_CHECKING, Any, Protocol

from hil.bench.family_registry import GROUP, FamilySections, installed, named, the_default
from hil.core.errors import InvalidValue

if TYPE_CHECKING:
    from hil.bench.base import BenchBase
    from hil.bench.profile import Profile
    from hil.sim.engine import Engine
    from hil.sim.runtime import ServerHandle


class Family(FamilySections, Protocol):
    """What a controller family plug-in provides (see :mod:`hil.families.fbs.plugin` for one): what a profile
    needs of it (:class:`~hil.bench.family_registry.FamilySections`), and its emulator, bench and servers."""

    def build_emulator(self, profile: Profile, epoch: dt.datetime) -> Engine:
        """The emulator the profile describes, its clocks starting at ``epoch``."""

    def open_bench(self, profile: Profile, **kwargs: Any) -> BenchBase[Any, Any]:
        """The bench for ``profile`` (its PLC behind the guard, its time, its per-test restore)."""

    def serve(self, profile: Profile, emulator: Engine, wire: str, host: str, port: int) -> ServerHandle:
        """Serve ``emulator`` on ``wire`` (one of :attr:`wires`) for other programs (``hil emulate``)."""

    #: the wires :meth:`serve` offers ("fatek-tcp", "modbus-tcp", "s7-tcp", …)
    wires: tuple[str, ...]


def families() -> dict[str, Family]:
    """Every installed family, by name."""
    return installed()


def default_family() -> Family:
    """The family a profile without ``[bench] family`` and a bench test without a ``family`` marker are for: the
    one installed family that says ``default = True``."""
    return the_default()


def family(name: str) -> Family:
    """The family registered as ``name``; a ProfileError listing the installed ones otherwise."""
    return named(name)


def open_bench(profile: Profile, **kwargs: Any) -> BenchBase[Any, Any]:
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


__all__ = ["GROUP", "Family", "build_emulator", "check_wire", "default_family", "families", "family", "open_bench"]
