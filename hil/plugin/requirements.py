"""Requirement IDs: the catalogue of manual statements (``hil/requirements.toml``) and the ``spec(...)`` marker.

A test names what it checks: ``@pytest.mark.spec("RTC-SET-1", "RTC-READ-1")`` (on a function, a class, a module's
``pytestmark`` or one ``pytest.param(..., marks=...)``).  At collection an ID the catalogue does not hold is a usage
error naming the test; a test naming an **[our choice]** requirement needs the ``spec_choices`` capability (the
bench plugin then skips it, with the reason, on a bench that does not claim it).  Each testcase carries its IDs as
the JUnit property ``hil.requirements``; the HTML report's requirement table is built from them
(:mod:`hil.plugin.reporting.requirements`), and ``hil spec`` prints the whole matrix (:mod:`hil.cli.spec`).

PYTEST_DONT_REWRITE (no asserts here: see ``pytest_plugins`` in :mod:`hil.plugin.pytest_plugin`)."""

from __future__ import annotations

import functools
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pytest

from hil.core.errors import HilError
from hil.plugin.usage import usage_error

#: the catalogue shipped in the package
REQUIREMENTS_FILE = Path(__file__).resolve().parent.parent / "requirements.toml"

#: why a requirement has no test (``untested.kind``)
UNTESTED_KINDS: dict[str, str] = {
    "not_observable": "no bench can see it on the PLC's wire",
    "informative": "not a behaviour of the PLC",
    "harness": "a rule of the harness itself, checked by tests/",
    "choice_open": "an [our choice] the suites rightly leave open",
    "pending": "a bench could check it; no suite test does yet",
}

MARKER = ("spec(ID, …): the requirements (hil/requirements.toml) the test checks; an unknown ID is a usage error, "
          "an [our choice] one makes the test need spec_choices; carried as the JUnit property hil.requirements")
PROPERTY = "hil.requirements"


@dataclass(frozen=True)
class Requirement:
    id: str
    manual: str
    spec: str
    statement: str
    choice: bool = False
    untested_kind: str = ""
    untested_reason: str = ""
    gap: str = ""

    @property
    def untested(self) -> bool:
        return bool(self.untested_kind)


_FIELDS = {"id", "manual", "spec", "statement", "choice", "untested", "gap"}


def parse(text: str, where: str = "requirements") -> dict[str, Requirement]:
    """The catalogue in ``text`` (TOML), checked: every entry complete, IDs unique, known ``untested`` kinds."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise HilError(f"{where}: not valid TOML: {exc}") from None
    unknown_top = set(data) - {"requirement"}
    if unknown_top:
        raise HilError(f"{where}: unknown top-level keys {sorted(unknown_top)} (only [[requirement]] entries)")
    found: dict[str, Requirement] = {}
    for n, raw in enumerate(data.get("requirement", []), 1):
        label = f"{where}: requirement #{n} ({raw.get('id', 'no id')})"
        extra = set(raw) - _FIELDS
        if extra:
            raise HilError(f"{label}: unknown keys {sorted(extra)} (allowed: {', '.join(sorted(_FIELDS))})")
        missing = [k for k in ("id", "manual", "spec", "statement") if not str(raw.get(k, "")).strip()]
        if missing:
            raise HilError(f"{label}: missing {', '.join(missing)}")
        untested = raw.get("untested", {})
        kind, reason = untested.get("kind", ""), untested.get("reason", "")
        if untested and (kind not in UNTESTED_KINDS or not reason.strip() or set(untested) - {"kind", "reason"}):
            raise HilError(f"{label}: untested must be {{ kind, reason }} with kind among "
                           f"{', '.join(UNTESTED_KINDS)} and a reason, not {untested}")
        if raw["id"] in found:
            raise HilError(f"{label}: the ID {raw['id']} is used twice")
        choice = raw.get("choice", False)
        if not isinstance(choice, bool):
            raise HilError(f"{label}: choice must be true or false, not {choice!r}")
        if choice != raw["statement"].startswith("[our choice]"):
            raise HilError(f"{label}: choice = {str(choice).lower()} but the statement "
                           f"{'does not start' if choice else 'starts'} with '[our choice]'")
        found[raw["id"]] = Requirement(raw["id"], raw["manual"], raw["spec"], raw["statement"], choice,
                                       kind, reason, raw.get("gap", ""))
    if not found:
        raise HilError(f"{where}: no [[requirement]] entries")
    return found


@functools.lru_cache(maxsize=4)
def load(path: Path = REQUIREMENTS_FILE) -> dict[str, Requirement]:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise HilError(f"cannot read the requirement catalogue {path}: {exc}") from None
    return parse(text, str(path))


def marked_ids(item: pytest.Item) -> tuple[str, ...]:
    """The IDs every ``spec`` marker on ``item`` names, in order, once each."""
    ids: list[str] = []
    for marker in item.iter_markers("spec"):
        if not marker.args or marker.kwargs:
            raise usage_error(f"{item.nodeid}: spec() takes requirement IDs only, e.g. spec(\"RTC-SET-1\")")
        ids.extend(a for a in marker.args if a not in ids)
    return tuple(ids)


_IDS = pytest.StashKey[tuple[str, ...]]()


def item_ids(item: pytest.Item) -> tuple[str, ...]:
    """The requirement IDs collection found on ``item`` (empty when it names none)."""
    return item.stash.get(_IDS, ())


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", MARKER)


@pytest.hookimpl(tryfirst=True)  # before the bench plugin decides its needs() skips
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if not any(item.get_closest_marker("spec") for item in items):
        return
    try:
        catalogue = load()
    except HilError as exc:
        raise usage_error(str(exc)) from None
    for item in items:
        ids = marked_ids(item)
        if not ids:
            continue
        unknown = [i for i in ids if i not in catalogue]
        if unknown:
            raise usage_error(f"{item.nodeid}: spec() names {', '.join(unknown)}, not in the requirement "
                              f"catalogue {REQUIREMENTS_FILE} (`hil spec` lists the IDs)")
        item.stash[_IDS] = ids
        item.user_properties.append((PROPERTY, " ".join(ids)))
        choices = [i for i in ids if catalogue[i].choice]
        if choices:
            item.add_marker(pytest.mark.needs(
                "spec_choices", reason=f"relies on {', '.join(choices)}, an [our choice] of the spec where the "
                                       f"manual is silent"))
