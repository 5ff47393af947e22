"""The durable write-ahead journal of one PLC: what must be put back if this run dies.

Before each write to an element, its original value *and the value about to be written* are on disk (written to a
temporary file, fsync'd, moved over the journal with :func:`os.replace`, and the directory fsync'd) — save before
mutate: the change is made to a copy, the copy saved, and only then the journal in memory (and the PLC) changed.  A
save that fails refuses that write and every later one of the session (:attr:`Journal.failed`): nothing goes out
unjournaled.  The same goes for a fault rig's coils, RUN/STOP, bits disabled by command 42, and the clock before a
test sets it (recorded as the PLC's time against the host's wall clock).  An entry leaves the journal only after
its restore was written *and read back equal*.

A run that dies leaves the file behind; the next run on the same PLC replays it before anything else
(:meth:`hil.bench.guard.Guard.recover`) — only as far as it can be proven — and ``hil restore`` does it by hand.

Where: beside the bench's locks, in the bench directory every user of the bench shares (:func:`journal_dir`,
:func:`hil.core.paths.bench_dir`), so the next run on the PLC finds a dead run's journal whoever started either.
Trust: that directory must be the bench group's and nobody else's (:func:`hil.core.paths.bench_dir_problem`), and
the journal a plain file nobody outside the group can write, of an owner who could have written it there
(:func:`hil.core.paths.bench_file_problem`); anything else is refused whole (:class:`JournalRefused`, one line, the
file kept).

The schema (version 2), one JSON object::

    {"version": 2,
     "bench": KEY,                # the PLC's key (:func:`hil.core.lock.plc_key`): must match the file's name
     "endpoint": "tcp://…:500",   # the wire the run wrote over
     "plc": {…} | null,           # the PLC's identity as the wire read it (FATEK command 53, the S7 identity)
     "created": ISO-8601 UTC,
     # one section per registered entry kind (:data:`KINDS`); each entry carries test, pid and at (ISO-8601 UTC)
     "elements": {NAME: {"original": int, "wrote": int | null, "earlier"?: int, …}},  # wrote null: the PLC's own
     "coils":    {KEY:  {"target": URL, "coil": int, "unit": int, "original": bool, "wrote": bool | null,
                         "earlier"?: bool, …}},
     "clock":    null | {"plc": ISO datetime, "host": seconds, "scale": float,      # the host's wall clock, and
                         "boot"?: id, "since_boot"?: seconds,                 # its boot clock read with it:
                         "width"?: seconds, "spread"?: seconds, …},           # how well each is known
     "run":      null | {"original": bool, "wrote": bool, "earlier"?: bool, …},  # RUN/STOP before command 41
     "disabled": [NAME, …],                                             # bits command 42 disabled
     "enable":   {NAME: {"disabled": bool, "wrote": bool, "earlier"?: bool, …}}}  # command 43 before 42, and
                                                                        # the state command 42 set

"wrote" is written (fsync'd) before the write goes out, so a run killed between the two leaves the PLC holding
what its previous write left: that value is kept as "earlier" (absent until an element is written twice), and
recovery treats either as the run's.

Each section is checked entry by entry by its kind's validator (:func:`register_kind`): a malformed entry is
named and kept, the others still replayed.  A kind may carry fields beyond those its validator checks (they are
its own business); an unknown *section*, another version or another bench refuses the whole file.

File: ``<bench dir>/journal-<sha256(key)[:16]>.json`` where the bench dir is ``$HIL_LOCK_DIR``, else
``/var/tmp/hil`` (mode 2770, the file 0660).  A journal an earlier hil left in the user's state directory
(``$HIL_STATE_DIR``, else ``$XDG_STATE_HOME/hil``, else ``~/.local/state/hil``) is not replayed from there: the run
refuses, saying where to move it.  A run with lanes
(:mod:`hil.plugin.lanes`) has one more per lane process beside it, ``journal-<…>.lane-<LANE>.json``, each written
only by its lane; recovery (and ``hil restore``) replays them with the run's own.
"""

from __future__ import annotations

import contextlib
import copy
import datetime as dt
import hashlib
import json
import math
import os
import re
import stat
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hil.core.errors import HilError
from hil.core.humantime import moment
from hil.core.paths import (
    BENCH_FILE_MODE,
    bench_dir_problem,
    bench_file_problem,
    bench_group,
    prepare_bench_dir,
    share_with_bench,
    user_name,
)

VERSION = 2
#: top-level fields that are not entry sections
META = ("version", "bench", "endpoint", "plc", "created")
FUTURE_SLACK = 120.0  # s: an entry stamped later than now + this was not written by a run on this host's clock


class JournalError(HilError):
    """The journal cannot be written or read (a run must not write to a PLC it cannot journal)."""


class JournalRefused(JournalError):
    """The journal on disk cannot be trusted as a whole (owner, mode, version, bench, not a journal): kept."""


# -- trust --------------------------------------------------------------------------------------------------------
def _private(path: Path) -> None:
    """Refuse the state directory ``path`` unless it is a directory of this user's that nobody else can write."""
    try:
        info = os.lstat(path)
    except OSError as exc:
        raise JournalRefused(f"cannot check the state directory {path}: {exc}") from None
    if not stat.S_ISDIR(info.st_mode):
        shown = "a symbolic link" if stat.S_ISLNK(info.st_mode) else "not a directory"
        raise JournalRefused(f"the state directory {path} is {shown} — refusing to trust it (check it by hand)")
    if info.st_uid != os.getuid():
        raise JournalRefused(f"the state directory {path} belongs to uid {info.st_uid}, not to you (uid "
                             f"{os.getuid()}) — refusing to trust it (check it by hand)")
    if info.st_mode & 0o022:
        raise JournalRefused(f"the state directory {path} is writable by others (mode "
                             f"{stat.S_IMODE(info.st_mode):04o}) — refusing to trust it (use a private directory, "
                             f"mode 0700)")


def _state_base() -> Path:
    given = os.environ.get("HIL_STATE_DIR")
    if given:
        return Path(given)
    xdg = os.environ.get("XDG_STATE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".local" / "state") / "hil"


def state_dir() -> Path:
    """This user's private state directory (the run history), created with mode 0700."""
    base = _state_base()
    try:
        base.mkdir(parents=True, exist_ok=True, mode=0o700)
    except OSError as exc:
        raise JournalError(f"cannot create the state directory {base}: {exc}") from None
    _private(base)
    return base


def journal_dir() -> Path:
    """Where journals are: the bench directory (created, checked), shared by every user of the bench."""
    try:
        return prepare_bench_dir()
    except JournalError:
        raise
    except HilError as exc:
        raise JournalRefused(str(exc)) from None


def _trusted_dir(directory: Path) -> None:
    if not os.path.lexists(directory):
        return  # no journal to trust (and none can be saved: the first save says so)
    problem = bench_dir_problem(directory, bench_group())
    if problem:
        raise JournalRefused(f"{problem} (its journals kept)")


def _trusted(path: Path) -> None:
    """Refuse the journal ``path`` unless anyone who could have written it is of the bench (absent: nothing)."""
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        return
    except OSError as exc:
        raise JournalRefused(f"cannot check the bench journal {path}: {exc}") from None
    problem = bench_file_problem(path, info)
    if problem:
        raise JournalRefused(f"the bench journal {problem}")


def _left_in_state_dir(path: Path) -> None:
    """Refuse to start over a journal an earlier hil left in this user's state directory: it is the PLC's
    originals, and only the bench directory's journal is replayed."""
    try:
        old = _state_base() / path.name
    except RuntimeError:  # no home directory to look in
        return
    if old.parent.resolve() != path.parent.resolve() and os.path.lexists(old):
        raise JournalRefused(f"a bench journal an earlier hil left is in your state directory: {old} — move it "
                             f"beside the bench's locks (mv {old} {path}) so recovery replays it, then run again")


def journal_path(key: str, directory: Path | None = None, lane: str | None = None) -> Path:
    """The journal file of the PLC ``key``: the run's, or that of one of its lanes (``lane``: a run with lanes,
    :mod:`hil.plugin.lanes`, has one journal per lane process, each written only by it)."""
    digest = hashlib.sha256(key.encode()).hexdigest()[:16]
    if lane is not None and not _LANE.fullmatch(lane):
        raise JournalError(f"lane name {lane!r}: letters, digits, '-' and '_' only")
    suffix = f".lane-{lane}" if lane is not None else ""
    return (Path(directory) if directory else journal_dir()) / f"journal-{digest}{suffix}.json"


def lane_of(path: Path) -> str | None:
    """The lane a journal file belongs to (None: a run's own journal, or not a journal's name)."""
    match = _LANE_FILE.fullmatch(path.name)
    return match.group(1) if match else None


_LANE = re.compile(r"[A-Za-z0-9_-]{1,64}")
_LANE_FILE = re.compile(r"journal-[0-9a-f]{16}\.lane-([A-Za-z0-9_-]{1,64})\.json")


# -- the entry kinds ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class EntryKind:
    """One section of the journal: ``keyed`` sections map names to entries, the others hold one entry or null."""

    section: str
    keyed: bool
    check: Callable[[Any], str | None]  # why an entry is malformed, None when well formed
    describe: Callable[[str, Any], str]  # one line for people: (name, entry)
    empty: Any = None  # the section's value when nothing is pending

    def present(self, value: Any) -> bool:
        return bool(value) if self.keyed or isinstance(self.empty, list) else value is not None


KINDS: dict[str, EntryKind] = {}


def register_kind(kind: EntryKind) -> EntryKind:
    KINDS[kind.section] = kind
    return kind


def _when(text: Any) -> dt.datetime | None:
    if not isinstance(text, str):
        return None
    try:
        when = dt.datetime.fromisoformat(text)
    except ValueError:
        return None
    return when if when.tzinfo is not None else when.replace(tzinfo=dt.UTC)


def _integer(value: Any, top: int = 0xFFFFFFFF) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= top


def _stamp_problem(entry: dict) -> str | None:
    if not isinstance(entry.get("test", ""), str) or not _integer(entry.get("pid", 0), 1 << 31):
        return "its test or pid is not a name and a process id"
    at = _when(entry.get("at"))
    if at is None:
        return f"its time stamp {entry.get('at')!r} is not an ISO-8601 time"
    if (at - dt.datetime.now(dt.UTC)).total_seconds() > FUTURE_SLACK:
        return f"it is stamped {at.isoformat()}, in the future"
    return None


def _fields(entry: Any, checks: dict[str, Callable[[Any], bool]], what: dict[str, str]) -> str | None:
    if not isinstance(entry, dict):
        return f"it is {json.dumps(entry)}, not an object"
    for name, ok in checks.items():
        if name not in entry or not ok(entry[name]):
            return f"its {name} is {json.dumps(entry.get(name)) if name in entry else 'missing'} (want {what[name]})"
    return _stamp_problem(entry)


def _bool(v: Any) -> bool:
    return isinstance(v, bool)


def _earlier_problem(entry: dict, ok: Callable[[Any], bool], want: str) -> str | None:
    if "earlier" in entry and not ok(entry["earlier"]):
        return f"its earlier is {json.dumps(entry['earlier'])} (want {want})"
    return None


def run_left(entry: dict) -> list:
    """The values the run may have left an element (or coil) holding: what it last wrote, or — when it died with
    that write journaled but not yet sent — what its write before left.  Empty when the PLC rewrote it itself."""
    if entry.get("wrote") is None:
        return []
    return [entry["wrote"]] + ([entry["earlier"]] if entry.get("earlier") is not None else [])


def _check_element(entry: Any) -> str | None:
    return _fields(entry, {"original": _integer, "wrote": lambda v: v is None or _integer(v)},
                   {"original": "an integer 0…0xFFFFFFFF", "wrote": "an integer 0…0xFFFFFFFF or null"}) \
        or _earlier_problem(entry, _integer, "an integer 0…0xFFFFFFFF")


def _check_coil(entry: Any) -> str | None:
    return _fields(entry, {"target": lambda v: isinstance(v, str) and "://" in v, "coil": lambda v: _integer(v, 65535),
                           "unit": lambda v: _integer(v, 255), "original": _bool,
                           "wrote": lambda v: v is None or _bool(v)},
                   {"target": "a Modbus URL", "coil": "0…65535", "unit": "0…255", "original": "true or false",
                    "wrote": "true, false or null"}) or _earlier_problem(entry, _bool, "true or false")


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _check_clock(entry: Any) -> str | None:
    return _fields(entry, {"plc": lambda v: isinstance(v, str) and _when(v) is not None,
                           "host": lambda v: _finite(v) and v > 0, "scale": lambda v: _finite(v) and v > 0},
                   {"plc": "an ISO-8601 time", "host": "host seconds > 0", "scale": "a time scale > 0"})


def _check_run(entry: Any) -> str | None:
    return (_fields(entry, {"original": _bool, "wrote": _bool}, {"original": "true or false", "wrote": "true or false"})
            or _earlier_problem(entry, _bool, "true or false"))


def _check_disabled(entry: Any) -> str | None:
    if not isinstance(entry, list) or not all(isinstance(n, str) and n for n in entry):
        return f"it is {json.dumps(entry)}, not a list of bit names"
    return None


def _check_enable(entry: Any) -> str | None:
    return _fields(entry, {"disabled": _bool, "wrote": _bool},
                   {"disabled": "true or false", "wrote": "true or false (the state command 42 set)"}) \
        or _earlier_problem(entry, _bool, "true or false")


def _who(entry: Any) -> str:
    if not isinstance(entry, dict):
        return ""
    user = f", user {entry['user']}" if isinstance(entry.get("user"), str) else ""
    return f" — by {entry.get('test') or '?'} (pid {entry.get('pid')}{user})"


def _show_element(name: str, e: Any) -> str:
    wrote = e.get("wrote")
    earlier = f" (before it: {e['earlier']})" if wrote is not None and e.get("earlier") is not None else ""
    return (f"{name} = {e['original']} (0x{e['original']:04X}), the run wrote "
            f"{'(the PLC itself)' if wrote is None else wrote}{earlier}{_who(e)}")


def _show_coil(name: str, e: Any) -> str:
    return f"rig coil {name} = {int(e['original'])}, the run wrote {e.get('wrote')}{_who(e)}"


def _show_clock(name: str, e: Any) -> str:
    return f"clock: was {e['plc']} at host time {moment(e['host'])} (scale {e['scale']}){_who(e)}"


def _show_run(name: str, e: Any) -> str:
    def state(v: bool) -> str:
        return "RUN" if v else "STOP"
    return f"RUN/STOP: was {state(e['original'])}, the run set {state(e['wrote'])}{_who(e)}"


def _show_disabled(name: str, e: Any) -> str:
    return f"{', '.join(e)} disabled by command 42 (to be re-enabled)"


def _enabled(disabled: bool) -> str:
    return "disabled" if disabled else "enabled"


def _show_enable(name: str, e: Any) -> str:
    return f"{name} {_enabled(e['disabled'])} (command 43) before the run {_enabled(e['wrote'])} it{_who(e)}"


ELEMENTS = register_kind(EntryKind("elements", True, _check_element, _show_element, {}))
COILS = register_kind(EntryKind("coils", True, _check_coil, _show_coil, {}))
CLOCK = register_kind(EntryKind("clock", False, _check_clock, _show_clock))
RUN = register_kind(EntryKind("run", False, _check_run, _show_run))
DISABLED = register_kind(EntryKind("disabled", False, _check_disabled, _show_disabled, []))
#: a bit's enable state (FATEK command 43: disabled = forced) before a test first enabled or disabled it
ENABLE = register_kind(EntryKind("enable", True, _check_enable, _show_enable, {}))


def earlier_of(old: dict) -> dict[str, Any]:
    """The field that keeps what the previous write left, for an entry about to record a new ``wrote``."""
    return {"earlier": old["wrote"]} if old.get("wrote") is not None else {}


def entry_id(section: str, name: str | None = None) -> str:
    """How an entry is named in reports: ``elements R1000``, ``coils tcp://…/coil3``, ``clock``."""
    return f"{section} {name}" if name is not None else section


def _empty(key: str) -> dict[str, Any]:
    return {"version": VERSION, "bench": key, "endpoint": None, "plc": None, "created": None,
            **{k.section: copy.deepcopy(k.empty) for k in KINDS.values()}}


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number a journal may hold")


def parse(raw: bytes | str, key: str, path: Path) -> dict[str, Any]:
    """The journal's data once its file-level fields are right (JournalRefused otherwise, one line)."""
    where = f"the bench journal {path}"
    keep = "kept; check it by hand with `hil restore --show`, then delete it"
    try:
        data = json.loads(raw, parse_constant=_reject_constant)
    except (ValueError, RecursionError) as exc:
        raise JournalRefused(f"{where} is damaged (not JSON: {exc}) — {keep}") from None
    if not isinstance(data, dict):
        raise JournalRefused(f"{where} holds {json.dumps(data)[:40]}, not a journal (a JSON object) — {keep}")
    if data.get("version") != VERSION:
        raise JournalRefused(f"{where} is version {json.dumps(data.get('version'))}, this hil reads version "
                             f"{VERSION} only — {keep}")
    if data.get("bench") != key:
        raise JournalRefused(f"{where} belongs to bench {json.dumps(data.get('bench'))}, not to {key} (whose name "
                             f"it has) — {keep}")
    unknown = sorted(set(data) - set(META) - set(KINDS))
    if unknown:
        raise JournalRefused(f"{where} has unknown section(s) {', '.join(unknown)} — {keep}")
    if not (data.get("endpoint") is None or isinstance(data["endpoint"], str)) or not (
            data.get("plc") is None or (isinstance(data["plc"], dict)
                                        and all(isinstance(v, str) for v in data["plc"].values()))):
        raise JournalRefused(f"{where}: its endpoint or PLC identity is malformed — {keep}")
    for kind in KINDS.values():
        value = data.setdefault(kind.section, copy.deepcopy(kind.empty))
        if kind.keyed and not isinstance(value, dict):
            raise JournalRefused(f"{where}: section {kind.section} is {json.dumps(value)[:40]}, not an object "
                                 f"— {keep}")
    for name in META:
        data.setdefault(name, None)
    return data


def _pending(data: dict[str, Any]) -> bool:
    return any(kind.present(data.get(kind.section)) for kind in KINDS.values())


def inspect(path: Path) -> tuple[str | None, Journal | None, str | None]:
    """A journal file found in the bench directory, for ``hil restore --show``: (its bench key, the journal, why
    it is refused as a whole) — the key None when the file does not say one."""
    try:
        _trusted(path)
        key = json.loads(path.read_bytes(), parse_constant=_reject_constant).get("bench")
    except JournalRefused as exc:
        return None, None, str(exc)
    except (OSError, ValueError, AttributeError, RecursionError):
        key = None
    if not isinstance(key, str) or journal_path(key, path.parent, lane_of(path)) != path:
        try:
            parse(path.read_bytes(), f"<the bench whose journal is {path.name}>", path)
        except JournalRefused as exc:
            return None, None, str(exc)
        return None, None, f"the bench journal {path} is refused (unreadable)"
    try:
        journal = Journal(key, path.parent, lane=lane_of(path))
    except JournalError as exc:
        return key, None, str(exc)
    return (key, None, journal.refused) if journal.refused else (key, journal, None)


class Journal:
    """One PLC's journal file.  Every mutation is on disk (fsync'd) before it shows in :attr:`data`.

    ``endpoint`` and ``plc`` (the PLC's identity as the wire reads it) go into a new journal's file."""

    def __init__(self, key: str, directory: Path | None = None, *, endpoint: str | None = None,
                 plc: dict[str, str] | None = None, lane: str | None = None) -> None:
        self.key = key
        self.lane = lane
        self.path = journal_path(key, directory, lane)
        self.endpoint = endpoint
        self.plc = plc
        self.test = ""  # the test now running (its node id), written with each entry
        self.failed: str | None = None  # why a save failed: no write may go out after it (this session)
        # why the file on disk cannot be trusted (damaged, another version or bench, not ours): it is kept as it is
        # — nothing may change it, so no write goes out — and recovery names it while it replays the others (the
        # lanes' journals beside it); an untrusted bench directory still refuses everything at once
        self.refused: str | None = None
        _trusted_dir(self.path.parent)
        try:
            self.data = self.load()
        except JournalRefused as exc:
            self.refused, self.data = str(exc), _empty(key)

    # -- reading ----------------------------------------------------------------------------------------------------
    def load(self) -> dict[str, Any]:
        """The file's data (an empty journal when there is none); JournalRefused when it cannot be trusted."""
        _trusted_dir(self.path.parent)
        _trusted(self.path)
        try:
            fd = os.open(self.path, os.O_RDONLY | os.O_NOFOLLOW)
        except FileNotFoundError:
            _left_in_state_dir(self.path)
            return _empty(self.key)
        except OSError as exc:
            raise JournalError(f"cannot read the bench journal {self.path}: {exc}") from None
        try:
            raw = b""
            while chunk := os.read(fd, 1 << 16):
                raw += chunk
        finally:
            os.close(fd)
        return parse(raw, self.key, self.path)

    @property
    def pending(self) -> bool:
        """Whether anything may be left to put back: entries, or a file that cannot be read (:attr:`refused`)."""
        return self.refused is not None or _pending(self.data)

    def lane_names(self) -> list[str]:
        """The lanes whose journals a run on this PLC left beside this one (each lane process writes its own):
        recovery replays them with it, each on its own (a damaged one is named, the others still replayed).
        Empty for a lane's own journal."""
        if self.lane is not None:
            return []
        stem = journal_path(self.key, self.path.parent).name.removesuffix(".json")
        return sorted(lane for p in self.path.parent.glob(f"{stem}.lane-*.json") if (lane := lane_of(p)) is not None)

    def lane_journal(self, name: str) -> Journal:
        """The journal lane ``name`` left beside this one (JournalError when it cannot be read or trusted)."""
        return Journal(self.key, self.path.parent, endpoint=self.endpoint, plc=self.plc, lane=name)

    def entries(self, *kinds: EntryKind) -> Iterable[tuple[EntryKind, str | None, Any]]:
        """Every pending entry (of ``kinds``, when given): (kind, name or None, entry), malformed ones included."""
        for kind in kinds or KINDS.values():
            value = self.data.get(kind.section)
            if kind.keyed:
                for name, entry in (value or {}).items():
                    yield kind, name, entry
            elif kind.present(value):
                yield kind, None, value

    def left_by(self) -> str:
        """Whose run left the pending entries, for the user who finds them: ``user alice, pid 1234`` (each run's)."""
        runs = sorted({(e.get("user"), e.get("pid")) for _, _, e in self.entries() if isinstance(e, dict)},
                      key=str)
        return "; ".join(", ".join(part for part in (f"user {u}" if isinstance(u, str) else "",
                                                      f"pid {p}" if p is not None else "") if part)
                         for u, p in runs if u is not None or p is not None) or "a run that left no name"

    def problem(self, kind: EntryKind, entry: Any) -> str | None:
        """Why ``entry`` of ``kind`` is malformed (None when well formed)."""
        return kind.check(entry)

    def extra(self, name: str, default: Any = None) -> Any:
        """``run`` (RUN/STOP before a command 41) or ``disabled`` (bits a command 42 disabled)."""
        value = self.data.get(name)
        return default if value is None else value

    def elements(self) -> dict[str, int]:
        """Each well-formed element entry's original."""
        return {n: e["original"] for n, e in self.data["elements"].items() if _check_element(e) is None}

    def coils(self) -> dict[str, dict[str, Any]]:
        return dict(self.data["coils"])

    def clock(self) -> dict[str, Any] | None:
        return self.data["clock"]

    def describe(self, *kinds: EntryKind) -> list[str]:
        """What is pending (of ``kinds``, when given), for people: one line per entry (a malformed one says what is
        wrong with it)."""
        lines = []
        for kind, name, entry in self.entries(*kinds):
            problem = kind.check(entry)
            if problem:
                lines.append(f"{entry_id(kind.section, name)}: malformed, {problem}")
            else:
                lines.append(kind.describe(name or kind.section, entry))
        return lines

    # -- writing (save before mutate: each change durable before it shows) ---------------------------------------
    def _stamp(self) -> dict[str, Any]:
        return {"test": self.test, "pid": os.getpid(), "user": user_name(os.getuid()),  # whose run, for the next user
                "at": dt.datetime.now(dt.UTC).isoformat()}

    def _change(self, apply: Callable[[dict[str, Any]], bool], *, adds: bool = True) -> None:
        """Apply ``apply`` to a copy of the data, save the copy, and only then take it.  ``apply`` returns False
        when nothing changed.  Once a save has failed, nothing more may be added (``adds``); nothing at all while
        the file on disk cannot be trusted (:attr:`refused`: saving would replace it)."""
        if self.refused:
            raise JournalRefused(f"{self.refused} — refusing every write to the PLC until it is dealt with")
        if adds and self.failed:
            raise JournalError(f"the bench journal {self.path} could not be written earlier in this run "
                               f"({self.failed}) — refusing every later write to the PLC")
        data = copy.deepcopy(self.data)
        fresh = not _pending(data)
        if not apply(data):
            return
        if adds and fresh:  # a new journal: where and what it is about
            data.update(endpoint=self.endpoint, plc=self.plc,
                        created=dt.datetime.now(dt.UTC).isoformat())
        try:
            self._save(data)
        except JournalError as exc:
            if adds:
                self.failed = str(exc)
            raise
        self.data = data

    def set_extra(self, name: str, value: Any) -> None:
        if name not in KINDS or KINDS[name].keyed:
            raise JournalError(f"no journal entry kind {name!r} (register it: hil.core.journal.register_kind)")

        def apply(data: dict[str, Any]) -> bool:
            new = copy.deepcopy(KINDS[name].empty) if value is None else value
            if isinstance(new, dict) and "at" not in new:
                new = {**new, **self._stamp()}
            if data.get(name) == new:
                return False
            data[name] = new
            return True
        self._change(apply, adds=value is not None and value != KINDS[name].empty)

    def add_elements(self, originals: dict[str, int], wrote: dict[str, int | None] | None = None) -> None:
        """Record originals (an element already journaled keeps its first, older, one) and the values about to be
        written (``wrote``; None for what the PLC rewrites itself)."""
        wrote = wrote or {}

        def apply(data: dict[str, Any]) -> bool:
            entries, changed, stamp = data["elements"], False, self._stamp()
            for name, value in originals.items():
                if name not in entries:
                    entries[name] = {"original": int(value), "wrote": wrote.get(name), **stamp}
                    changed = True
            for name, written in wrote.items():
                old = entries.get(name)
                if old is not None and written is not None and old.get("wrote") != written:
                    entries[name] = {**old, "wrote": int(written), **earlier_of(old)}
                    changed = True
            return changed
        self._change(apply)

    def drop_elements(self, names: Iterable[str]) -> None:
        names = list(names)

        def apply(data: dict[str, Any]) -> bool:
            gone = [n for n in names if n in data["elements"]]
            for name in gone:
                del data["elements"][name]
            return bool(gone)
        self._change(apply, adds=False)

    def set_clock(self, plc_time: dt.datetime, host: float, scale: float, **more: Any) -> None:
        """The clock before a test set it: ``plc_time`` read when the host's wall clock said ``host`` (``more``:
        fields of the clock's own, e.g. what tells a host clock stepped before recovery)."""
        def apply(data: dict[str, Any]) -> bool:
            if data["clock"] is not None:
                return False
            data["clock"] = {"plc": plc_time.isoformat(), "host": host, "scale": scale, **more, **self._stamp()}
            return True
        self._change(apply)

    def enable_states(self) -> dict[str, bool]:
        """Bit → whether it was disabled (forced) before a test first enabled or disabled it (well-formed ones)."""
        return {n: bool(e["disabled"]) for n, e in self.data["enable"].items() if _check_enable(e) is None}

    def add_enable_states(self, states: dict[str, bool], wrote: dict[str, bool]) -> None:
        """Bits' enable states (True: disabled) before a first command 42 enable/disable — a bit already journaled
        keeps its first (older) state — and the state the command about to go out sets (``wrote``), the one
        before it kept as "earlier", as for elements: recovery puts back only a bit still as the run left it."""
        def apply(data: dict[str, Any]) -> bool:
            entries, changed, stamp = data["enable"], False, self._stamp()
            for name, value in states.items():
                if name not in entries:
                    entries[name] = {"disabled": bool(value), "wrote": bool(wrote[name]), **stamp}
                    changed = True
            for name, value in wrote.items():
                old = entries.get(name)
                if old is not None and old.get("wrote") != bool(value):
                    entries[name] = {**old, "wrote": bool(value), **earlier_of(old)}
                    changed = True
            return changed
        self._change(apply)

    def drop_enable_states(self, names: Iterable[str]) -> None:
        names = set(names)

        def apply(data: dict[str, Any]) -> bool:
            gone = [n for n in data["enable"] if n in names]
            for name in gone:
                del data["enable"][name]
            return bool(gone)
        self._change(apply, adds=False)

    def drop_clock(self) -> None:
        def apply(data: dict[str, Any]) -> bool:
            if data["clock"] is None:
                return False
            data["clock"] = None
            return True
        self._change(apply, adds=False)

    def add_coil(self, key: str, target: str, coil: int, unit: int, value: bool, wrote: bool | None = None) -> None:
        """A rig coil's original (kept from its first record) and the state about to be written (``wrote``)."""
        def apply(data: dict[str, Any]) -> bool:
            old = data["coils"].get(key)
            if old is None:
                data["coils"][key] = {"target": target, "coil": coil, "unit": unit, "original": bool(value),
                                      "wrote": wrote, **self._stamp()}
                return True
            if wrote is None or old.get("wrote") == wrote:
                return False
            data["coils"][key] = {**old, "wrote": bool(wrote), **earlier_of(old)}
            return True
        self._change(apply)

    def drop_coil(self, key: str) -> None:
        def apply(data: dict[str, Any]) -> bool:
            return data["coils"].pop(key, None) is not None
        self._change(apply, adds=False)

    def _save(self, data: dict[str, Any]) -> None:
        directory = self.path.parent
        try:
            if not _pending(data):
                try:
                    os.unlink(self.path)
                except FileNotFoundError:
                    return
            else:
                data["bench"] = self.key
                tmp = directory / f".{self.path.name}.{os.getpid()}.tmp"
                fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW, BENCH_FILE_MODE)
                try:
                    share_with_bench(fd, directory)  # whoever runs next on this PLC must be able to recover it
                    raw = json.dumps(data, indent=1, sort_keys=True, allow_nan=False).encode()
                    written = os.write(fd, raw)
                    if written != len(raw):
                        raise OSError(f"short write ({written} of {len(raw)} bytes)")
                    os.fsync(fd)
                    os.close(fd)
                    os.replace(tmp, self.path)
                except BaseException:
                    with contextlib.suppress(OSError):
                        os.close(fd)
                    with contextlib.suppress(OSError):
                        os.unlink(tmp)  # the journal on disk stays as it was
                    raise
            dfd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY)
            try:
                os.fsync(dfd)
            finally:
                os.close(dfd)
        except (OSError, ValueError) as exc:
            raise JournalError(f"cannot write the bench journal {self.path}: {exc} — refusing to write to the PLC "
                               f"without its originals on disk") from None


__all__ = ["CLOCK", "COILS", "DISABLED", "ELEMENTS", "ENABLE", "KINDS", "RUN", "VERSION", "EntryKind", "Journal",
           "JournalError", "JournalRefused", "entry_id", "inspect", "journal_dir", "journal_path", "lane_of", "parse",
           "register_kind", "run_left", "state_dir"]
