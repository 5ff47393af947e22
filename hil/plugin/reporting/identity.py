"""Who and what a run tested: the testsuite properties of the JUnit report, the console header and the HTML.

Read once per session, after the bench is open.  Nothing here may fail a run: an item that cannot be read is
recorded as "unavailable: why".
"""

from __future__ import annotations

import getpass
import os
import socket
import subprocess
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl, urlencode, urlsplit, urlunsplit

from hil import __version__

_SECRET_KEYS = ("password", "passwd", "pass", "secret", "token", "key", "auth")


def public_url(url: str) -> str:
    """``url`` without credentials: no user:password@, no password/token/… query parameters."""
    try:
        parts = urlsplit(url)
    except ValueError:
        return url
    if not parts.scheme:
        return url
    netloc = parts.netloc.rpartition("@")[2]
    query = [(k, v) for k, v in parse_qsl(parts.query, keep_blank_values=True)
             if not any(s in k.lower() for s in _SECRET_KEYS)]
    return urlunsplit((parts.scheme, netloc, parts.path, urlencode(query), parts.fragment))


def transport_name(url: str) -> str:
    scheme = url.split("://", 1)[0] if "://" in url else url
    return {"emulator": "in-process (no wire)"}.get(scheme, scheme)


def git_commit(where: Path) -> str:
    """``<sha>`` of the repository holding ``where``, ``+dirty`` when its tracked files there changed."""
    where = where if where.is_dir() else where.parent
    try:
        sha = subprocess.run(["git", "-C", str(where), "rev-parse", "HEAD"], capture_output=True, text=True,
                             timeout=5, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(where), "status", "--porcelain", "--untracked-files=no", "--",
                                "."], capture_output=True, text=True, timeout=5).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unavailable: not a git checkout"
    return sha + ("+dirty" if dirty else "")


def operator_and_station(operator: str | None, station: str | None) -> tuple[str, str]:
    """Options first, then HIL_OPERATOR / HIL_STATION, then the login name and the host name."""
    who = operator or os.environ.get("HIL_OPERATOR")
    if not who:
        try:
            who = getpass.getuser()
        except Exception:  # noqa: BLE001 - no login name in some containers
            who = "unknown"
    where = station or os.environ.get("HIL_STATION") or socket.gethostname()
    return who, where


def plc_identity(bench: Any) -> dict[str, str]:
    """What the wire says the PLC is (the family's ``wire_identity``, e.g. an FBs's command 53), or the emulator's
    version and seed, or whatever the wire's status says; plus what the family adds (``identity``)."""
    out: dict[str, str] = {}
    raw = getattr(bench, "raw", None)
    try:
        said = getattr(bench, "wire_identity", lambda: None)()
        if said is not None:
            out.update(said)
        else:
            status = bench.io.status()
            out.update({k: str(v) for k, v in status.identity.items() if k not in ("transport", "probe")})
    except Exception as exc:  # noqa: BLE001 - a PLC that will not say what it is still gets tested
        out["identity"] = f"unavailable: {exc}"
    emulator = getattr(raw, "emulator", None)
    if emulator is not None:
        out["emulator version"] = str(getattr(emulator, "version", "?"))
        out["emulator seed"] = str(getattr(emulator, "seed", "?"))
        timing = getattr(emulator, "timing", None)
        if timing is not None:  # (bench timing: the seed replays its phases)
            out["emulator timing"] = timing.describe()
        out.pop("version", None)
        out.pop("seed", None)
        out.pop("unit", None)
    out.update(bench.identity())  # what the family adds (an FBs: its RTC chip)
    return out


def suite_properties(*, profile: Any, target: str, bench: Any | None, bench_error: str | None, suites: Path | None,
                     operator: str | None, station: str | None) -> list[tuple[str, str]]:
    """The testsuite properties, in order: bench, target, transport, PLC identity, harness, suites, profile,
    operator and station."""
    url = public_url(target)
    who, where = operator_and_station(operator, station)
    props = [("hil.bench", profile.name), ("hil.target", url), ("hil.transport", transport_name(url))]
    lab = getattr(profile, "lab", None)
    if lab is not None:  # the labgrid place the target came from (hil.bench.lab.resolve.Lab)
        props += lab.properties()  # no credentials: a NetworkService's username/password never enter a URL
    if bench is not None:
        description = getattr(getattr(bench, "raw", None), "description", "")
        if description:
            props.append(("hil.wire", public_url(description)))
        props += [(f"hil.plc.{k.replace(' ', '_')}", v) for k, v in plc_identity(bench).items()]
    else:
        props.append(("hil.plc.identity", f"unavailable: {bench_error or 'no test used the bench'}"))
    props += [("hil.harness_version", __version__),
              ("hil.suites_commit", git_commit(suites) if suites else "unavailable: no suite files"),
              ("hil.profile", str(profile.path or "<profile>")),
              ("hil.profile_sha256", profile.digest or "unavailable"),
              ("hil.operator", who), ("hil.station", where)]
    return props
