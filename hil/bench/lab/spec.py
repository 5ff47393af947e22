"""What a run asks labgrid for: a place by name or by tags, the coordinator, and which resources are what.

A profile's ``[labgrid]`` section (instead of ``[bench] target``)::

    [labgrid]
    place = "fbs-bench-3"                       # or: tags = {family = "fbs", rtc = "s35390a"}
    coordinator = "lab.example.com:20408"       # default $LG_COORDINATOR, else labgrid's 127.0.0.1:20408
    wire = "plc-ethernet"                       # the resource that is the PLC's wire (default: the place's only
                                                # NetworkService, else its only NetworkSerialPort)
    protocol = "fatek"                          # what the wire speaks: fatek | modbus | s7 (default: from a
                                                # NetworkService's port — 502 Modbus, 102 S7 — else fatek)
    params = {parity = "E", bytesize = 7}       # more query parameters for the wire's URL
    rig = "relay-*"                             # the ModbusTCPCoil resources that make the fault rig (default all)

``hil run --lg-place NAME`` / ``--lg-reserve "family=fbs rtc=s35390a"`` / ``--lg-coordinator`` override it (and
work with a profile that has no ``[labgrid]``: its ``target`` is then replaced by the place's).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, replace
from typing import Any

from hil.bench.schema import Key, Section, located
from hil.core.errors import InvalidValue, ProfileError
from hil.core.registry import PROTOCOLS

#: labgrid's own default when neither -x nor LG_COORDINATOR says
DEFAULT_COORDINATOR = "127.0.0.1:20408"
#: a lab's tags, for the errors' examples
TAGS_EXAMPLE = "family=NAME board=ID"
_TAG_KEY = re.compile(r"[a-z][a-z0-9_]+")  # labgrid's rule for tag keys (labgrid.remote.common.TAG_KEY)
_TAG_VALUE = re.compile(r"[^\s=,]+")


@dataclass(frozen=True)
class LabSpec:
    place: str | None = None
    tags: tuple[tuple[str, str], ...] = ()
    coordinator: str | None = None
    wire: str | None = None
    protocol: str | None = None
    params: tuple[tuple[str, Any], ...] = ()
    rig: str = "*"
    #: longest wait for the reservation, in seconds (None: as long as it takes — a CI job's own timeout bounds it)
    wait: float | None = None

    @property
    def filters(self) -> dict[str, str]:
        """The reservation's filter: labgrid matches a place's name as the tag ``name``."""
        return {"name": self.place} if self.place else dict(self.tags)

    @property
    def address(self) -> str:
        """The coordinator, HOST:PORT (the port labgrid defaults to filled in)."""
        given = self.coordinator or os.environ.get("LG_COORDINATOR") or DEFAULT_COORDINATOR
        return given if re.search(r":\d+$", given) else f"{given}:20408"

    def describe(self) -> str:
        if self.place:
            return f"labgrid place {self.place}"
        if not self.tags:
            return "a labgrid place (named by --lg-place or --lg-reserve)"
        return "a labgrid place tagged " + self.asked.removeprefix("tags ")

    @property
    def asked(self) -> str:
        """What the run reserves by: "place NAME" or "tags k=v …"."""
        return f"place {self.place}" if self.place else "tags " + " ".join(f"{k}={v}" for k, v in self.tags)

    def overridden(self, *, place: str | None = None, tags: str | None = None, coordinator: str | None = None,
                   wait: float | None = None) -> LabSpec:
        """The command line's choice over the profile's: a place given replaces tags, and tags a place."""
        spec = self
        if place:
            spec = replace(spec, place=place, tags=())
        if tags:
            spec = replace(spec, place=None, tags=parse_tags(tags))
        if coordinator:
            spec = replace(spec, coordinator=coordinator)
        if wait is not None:
            spec = replace(spec, wait=wait if wait > 0 else None)
        if not spec.place and not spec.tags:
            raise ProfileError("labgrid: name a place (--lg-place NAME, [labgrid] place) or the tags of one "
                               f"(--lg-reserve \"{TAGS_EXAMPLE}\", [labgrid] tags)")
        return spec


def parse_tags(text: str | dict[str, Any]) -> tuple[tuple[str, str], ...]:
    """``"family=fbs rtc=s35390a"`` (spaces or commas) or ``{family = "fbs"}`` → sorted (key, value) pairs."""
    pairs = list(text.items()) if isinstance(text, dict) else \
        [item.partition("=")[::2] if "=" in item else (item, "") for item in re.split(r"[\s,]+", text.strip()) if item]
    out = []
    for key, value in pairs:
        value = str(value)
        if not _TAG_KEY.fullmatch(key) or not _TAG_VALUE.fullmatch(value):
            raise InvalidValue(f"labgrid tag {key}={value!r}: tags are KEY=VALUE, the key lower-case letters, "
                               f"digits and _ (e.g. {TAGS_EXAMPLE})")
        out.append((key, value))
    if not out:
        raise InvalidValue(f"labgrid: no tags given (e.g. --lg-reserve \"{TAGS_EXAMPLE}\")")
    return tuple(sorted(out))


LABGRID = Section("labgrid", "The labgrid place that holds the PLC, its wire and the fault rig (instead of "
                  "[bench] target; README \"A lab of benches\").", (
    Key("place", str, "The place's name.", pattern=r".*\S.*", hint="must not be empty",
        example="bench-3"),
    Key("tags", dict, "Reserve any place with these tags, e.g. {room = \"lab-2\"} (instead of place).",
        convert=parse_tags, example={"room": "lab-2"}),
    Key("coordinator", str, "HOST[:PORT] of the coordinator; default $LG_COORDINATOR, else labgrid's own.",
        pattern=r"[\w.\-\[\]:]+", hint="must be HOST[:PORT]",
        example="lab.example.com:20408"),
    Key("wire", str, "The resource that is the PLC's wire (default: the place's only NetworkService, else its "
        "only NetworkSerialPort).", example="plc-ethernet"),
    Key("protocol", str, "What the wire speaks (default: from a NetworkService's port).",
        choices=lambda: tuple(PROTOCOLS)),
    Key("params", dict, "More query parameters for the wire's URL, e.g. {parity = \"E\"}.", {}),
    Key("rig", str, "The ModbusTCPCoil resources that make the fault rig (a glob).", "*"),
    Key("wait", float, "Seconds to wait for the place.", above=0, unit="s", hint="must be > 0 s",
        example=600.0),
))


def parse_section(data: dict[str, Any], where: str) -> LabSpec:
    """``[labgrid]`` of a profile (refusing unknown keys and bad values, :data:`LABGRID`)."""
    values = LABGRID.read(data.get("labgrid", {}), where)
    if values["place"] and values["tags"]:
        raise located(ProfileError(f"{where}: [labgrid] gives both place and tags: reserve by one of them"),
                      "labgrid", "tags")
    return LabSpec(**{**values, "tags": values["tags"] or (), "params": tuple(values["params"].items())})


__all__ = ["LabSpec", "parse_tags", "parse_section", "DEFAULT_COORDINATOR"]
