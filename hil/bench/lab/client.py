"""labgrid's client, run as ``labgrid-client`` subprocesses, and what its output says.

Why a subprocess and not labgrid's Python API in this process: labgrid depends on ``pyserial-labgrid``, a fork
that installs into the same ``serial/`` package as pyserial (whichever is installed last wins, silently); run as
a program, labgrid can live in its own environment (``pipx install labgrid``, a venv of its own, a distribution
package) and hil's keeps the stock pyserial.  It also keeps labgrid's gRPC/asyncio stack (threads, an event loop,
fork-unsafe channels) out of a process that forks emulators and handles SIGTERM itself, and a child that waits
for a reservation can be killed cleanly.  ``labgrid-client`` is labgrid's documented interface (its man page);
its Python session class is not.  A call costs ≈ 0.3 s; a run makes about six.

The client is found at ``$HIL_LABGRID_CLIENT``, beside this Python (``pip install 'hil[labgrid]'``), or on PATH.
"""

from __future__ import annotations

import ast
import os
import queue
import re
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from textwrap import dedent
from typing import Any

from hil.core.errors import HilError


class LabError(HilError):
    """labgrid refused or failed: the coordinator, a place, a reservation, a resource."""


class LabWaitExpired(LabError):
    """The reservation was not allocated within the wait the run allowed."""


def find_client(environ: dict[str, str] | None = None) -> str:
    env = os.environ if environ is None else environ
    given = env.get("HIL_LABGRID_CLIENT")
    if given:
        if not os.access(given, os.X_OK):
            raise LabError(f"HIL_LABGRID_CLIENT={given} is not an executable labgrid-client")
        return given
    beside = Path(sys.executable).parent / "labgrid-client"  # hil[labgrid]: the same environment
    if os.access(beside, os.X_OK):
        return str(beside)
    found = shutil.which("labgrid-client")
    if found:
        return found
    raise LabError("labgrid-client not found: install labgrid (pipx install labgrid, or pip install "
                   "'hil[labgrid]'), or point HIL_LABGRID_CLIENT at its labgrid-client")


@dataclass(frozen=True)
class Resource:
    """One resource of a place, as ``labgrid-client show`` lists it."""

    name: str  # the name in the place (a match's rename, else the resource's own)
    exporter: str
    group: str
    cls: str
    resource: str  # the exporter's name for it
    params: dict[str, Any]

    @property
    def path(self) -> str:
        return f"{self.exporter}/{self.group}/{self.cls}/{self.resource}"

    @property
    def exporter_host(self) -> str:
        """The exporter's host (its FQDN, which labgrid publishes with every resource)."""
        return str(self.params.get("extra", {}).get("proxy") or self.exporter)

    @property
    def isolated(self) -> bool:
        """Its exporter runs --isolated: the resource is reachable only through an SSH proxy."""
        return bool(self.params.get("extra", {}).get("proxy_required"))


@dataclass(frozen=True)
class Place:
    name: str
    tags: dict[str, str] = field(default_factory=dict)
    acquired: str | None = None  # "host/user"
    reservation: str | None = None
    resources: tuple[Resource, ...] = ()


_PLACE = re.compile(r"^Place '(?P<name>.+)':$")
_RESOURCE = re.compile(r"^(?P<how>Acquired|Matching) resource '(?P<name>.+)' "
                       r"\((?P<exporter>[^/]+)/(?P<group>[^/]+)/(?P<cls>[^/]+)/(?P<res>[^)]+)\):$")
_FIELD = re.compile(r"^  (?P<key>[a-z ]+): (?P<value>.*)$")


def parse_places(text: str) -> list[Place]:
    """The places in ``labgrid-client -v places`` or ``-p NAME show`` output (a show adds each resource's
    parameters, printed as a Python literal, read here with :func:`ast.literal_eval`: no code runs)."""
    places: list[dict[str, Any]] = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        i += 1
        found = _PLACE.match(line)
        if found:
            places.append({"name": found["name"], "tags": {}, "acquired": None, "reservation": None,
                           "resources": []})
            continue
        found = _RESOURCE.match(line)
        if found and places:
            block = []
            while i < len(lines) and lines[i].startswith("  "):
                block.append(lines[i])
                i += 1
            try:
                data = ast.literal_eval(dedent("\n".join(block)))
            except (ValueError, SyntaxError) as exc:
                raise LabError(f"cannot read resource {found['name']} in labgrid-client's output: {exc}") from None
            places[-1]["resources"].append(Resource(found["name"], found["exporter"], found["group"],
                                                    data.get("cls", found["cls"]), found["res"],
                                                    dict(data.get("params", {}))))
            continue
        field_ = _FIELD.match(line)
        if field_ and places:
            key, value = field_["key"], field_["value"].strip()
            if key == "tags":
                places[-1]["tags"] = dict(item.partition("=")[::2] for item in value.split(", ") if item)
            elif key in ("acquired", "reservation"):
                places[-1][key] = None if value == "None" else value
    return [Place(p["name"], p["tags"], p["acquired"], p["reservation"], tuple(p["resources"])) for p in places]


class LabgridClient:
    """``labgrid-client -x COORDINATOR …``: one subprocess per call, each with a timeout."""

    def __init__(self, coordinator: str, executable: str | None = None, timeout: float = 60.0) -> None:
        self.coordinator = coordinator
        self.executable = executable or find_client()
        self.timeout = timeout

    def command(self, *args: str, place: str | None = None) -> list[str]:
        return [self.executable, "-x", self.coordinator, *(["-p", place] if place else []), *args]

    def call(self, *args: str, place: str | None = None) -> str:
        try:
            proc = subprocess.run(self.command(*args, place=place), capture_output=True, text=True,
                                  timeout=self.timeout, stdin=subprocess.DEVNULL)
        except subprocess.TimeoutExpired:
            raise LabError(f"labgrid-client {' '.join(args)} did not answer within {self.timeout:g} s "
                           f"(coordinator {self.coordinator})") from None
        except OSError as exc:
            raise LabError(f"cannot run {self.executable}: {exc}") from None
        if proc.returncode:
            raise LabError(f"labgrid-client {' '.join(args)}{f' on {place}' if place else ''} failed: "
                           f"{_last_line(proc.stderr or proc.stdout)} (coordinator {self.coordinator})")
        return proc.stdout

    def places(self) -> list[Place]:
        return parse_places(self.call("-v", "places"))

    def show(self, place: str) -> Place:
        found = parse_places(self.call("show", place=place))
        if not found:
            raise LabError(f"labgrid-client show {place} printed no place")
        return found[0]

    def reserve(self, filters: dict[str, str]) -> str:
        out = self.call("reserve", "--shell", *(f"{k}={v}" for k, v in sorted(filters.items())))
        found = re.search(r"LG_TOKEN=(\S+)", out)
        if not found:
            raise LabError(f"labgrid-client reserve printed no token: {out.strip()!r}")
        return found.group(1)

    def wait(self, token: str, progress: Callable[[str, float], None], limit: float | None = None) -> str:
        """Wait until the reservation is allocated, calling ``progress(state, waited)`` on each poll (labgrid's
        ``wait`` polls every second; polling is also what keeps a waiting reservation alive); returns the state.
        The child is killed however this ends (KeyboardInterrupt included)."""
        started = time.monotonic()
        proc = subprocess.Popen(self.command("wait", token), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, text=True)
        lines: queue.Queue[str | None] = queue.Queue()

        def pump() -> None:
            assert proc.stdout is not None
            for line in proc.stdout:
                lines.put(line)
            lines.put(None)
        threading.Thread(target=pump, daemon=True, name="labgrid-wait").start()
        state, said = "waiting", []
        try:
            while True:
                waited = time.monotonic() - started
                if limit is not None and waited > limit:
                    raise LabWaitExpired(f"no place was allocated to reservation {token} within {limit:g} s "
                                         f"(--lg-wait): `labgrid-client who` shows who holds the places")
                try:
                    line = lines.get(timeout=1.0)
                except queue.Empty:
                    progress(state, waited)
                    continue
                if line is None:
                    break
                said.append(line)
                found = re.match(r"^state: (\w+)", line.strip())
                if found:
                    state = found.group(1)
                    progress(state, waited)
        finally:
            if proc.poll() is None:
                proc.kill()
            proc.wait()
        if proc.returncode:
            raise LabError(f"waiting for reservation {token} failed: {_last_line(''.join(said))}")
        if state not in ("allocated", "acquired"):
            raise LabError(f"reservation {token} ended {state} instead of being allocated a place")
        return state

    def acquire(self, token: str) -> str:
        """Acquire the place the reservation was allocated (``-p +TOKEN``); returns its name."""
        out = self.call("acquire", place=f"+{token}")
        found = re.search(r"acquired place (\S+)", out)
        if not found:
            raise LabError(f"labgrid-client acquire printed {out.strip()!r}")
        return found.group(1)

    def release(self, place: str) -> None:
        self.call("release", place=place)

    def cancel(self, token: str) -> None:
        self.call("cancel-reservation", token)


def _last_line(text: str) -> str:
    lines = [line.strip() for line in text.strip().splitlines() if line.strip()]
    return lines[-1] if lines else "no message"


__all__ = ["LabgridClient", "LabError", "LabWaitExpired", "Place", "Resource", "parse_places", "find_client"]
