"""Records a report is made of: measurements with limits, plot-ready series, one record per test."""

from __future__ import annotations

import enum
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import PurePath

from hil.core.measurement import Measurement
from hil.core.registry import REPORT_AREAS


@dataclass
class Series:
    """Plot-ready columns: ``x`` names the horizontal axis, every other column is one line."""

    name: str
    columns: dict[str, list[float]]
    x: str
    title: str = ""
    xlabel: str = ""
    ylabel: str = ""
    #: columns drawn against a second vertical axis (e.g. a PID output in % beside PV/SV in °C)
    secondary: tuple[str, ...] = ()
    secondary_label: str = ""

    @classmethod
    def build(cls, name: str, data: Mapping[str, Sequence[float]] | Sequence[Sequence[float]], *,
              columns: Sequence[str] | None = None, x: str | None = None, title: str = "", xlabel: str = "",
              ylabel: str = "", secondary: Sequence[str] = (), secondary_label: str = "") -> Series:
        """A series from named columns or from rows (``columns`` naming each position); ``x`` defaults to the first
        column.  ValueError saying what is wrong with the shape."""
        cols = _columns_of(name, data, columns)
        x = x or next(iter(cols), "")
        _check_shape(name, cols, x, secondary)
        return cls(name, cols, x, title or name, xlabel or x, ylabel, tuple(secondary), secondary_label)

    @property
    def points(self) -> int:
        return len(self.columns[self.x])


def _columns_of(name: str, data: Mapping[str, Sequence[float]] | Sequence[Sequence[float]],
                columns: Sequence[str] | None) -> dict[str, list[float]]:
    """The data as named columns of floats: a mapping already is; rows are turned, named by ``columns``."""
    if isinstance(data, Mapping):
        return {str(k): [float(v) for v in vs] for k, vs in data.items()}
    if not columns:
        raise ValueError(f"series {name!r}: rows need columns=(…) naming each position")
    rows = [tuple(r) for r in data]
    if any(len(r) != len(columns) for r in rows):
        raise ValueError(f"series {name!r}: every row must have {len(columns)} values ({', '.join(columns)})")
    return {c: [float(r[i]) for r in rows] for i, c in enumerate(columns)}


def _check_shape(name: str, cols: dict[str, list[float]], x: str, secondary: Sequence[str]) -> None:
    """Plottable: columns of one length, ``x`` among them with a y column beside it, the secondary ones known."""
    if not cols:
        raise ValueError(f"series {name!r} has no columns")
    lengths = {len(v) for v in cols.values()}
    if len(lengths) != 1:
        raise ValueError(f"series {name!r}: columns differ in length ({sorted(lengths)})")
    if x not in cols:
        raise ValueError(f"series {name!r}: x column {x!r} not among {list(cols)}")
    if len(cols) < 2:
        raise ValueError(f"series {name!r}: needs a y column besides {x!r}")
    unknown = [c for c in secondary if c not in cols]
    if unknown:
        raise ValueError(f"series {name!r}: secondary columns {unknown} not among {list(cols)}")


class TestOutcome(enum.StrEnum):
    """What one test showed, as OpenHTF's test outcomes: never more than its reports did.  The values are the words
    every output shows (and the history keeps); a test has no result until a report gives it one."""

    __test__ = False  # not a test class, whatever pytest's name pattern says

    PASS = "passed"
    FAIL = "failed"
    ERROR = "error"  # its setup or teardown failed (the fixture, the bench's restore)
    SKIP = "skipped"
    XFAIL = "xfailed"
    ABORTED = "aborted"  # the run stopped inside it (a signal, an internal error): it has no result
    INCOMPLETE = "incomplete"  # started and not finished: a run still under way, or one that died

    @property
    def bad(self) -> bool:
        """A test that did not pass and was not skipped: what a report opens, keeps the wire trace of, lists."""
        return self in (TestOutcome.FAIL, TestOutcome.ERROR, TestOutcome.ABORTED, TestOutcome.INCOMPLETE)


@dataclass
class TestRecord:
    """What the report keeps of one test."""

    __test__ = False  # not a test class, whatever pytest's name pattern says

    nodeid: str
    area: str
    outcome: TestOutcome = TestOutcome.INCOMPLETE
    duration: float = 0.0
    message: str = ""  # failure text or skip reason
    longrepr: str = ""
    measurements: list[Measurement] = field(default_factory=list)
    series: list[Series] = field(default_factory=list)
    trace: str = ""  # formatted wire trace, when kept
    trace_file: str = ""
    attachments: list[str] = field(default_factory=list)  # files saved with report.attach_file
    requirements: list[str] = field(default_factory=list)  # the IDs its spec() marker names (hil.requirements)
    #: pytest's own count of this test's reports (its ``pytest_report_teststatus`` categories): a failed call and a
    #: failed teardown are one failure and one error, as pytest's summary line and its JUnit file count them
    counted: dict[str, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.outcome = TestOutcome(self.outcome)  # a record read back (JSON) or made by hand names it as a word


def outcome_counts(records: Iterable[TestRecord]) -> Counter:
    """The counts pytest gives for these tests (a record made outside a session counts its outcome once)."""
    total: Counter = Counter()
    for r in records:
        total.update(r.counted or {r.outcome: 1})
    return total


def records_to_json(records: list[TestRecord], properties: list[tuple[str, str]]) -> str:
    """What one run's report is made of, for a report that merges several runs (``hil run --bench a --bench b``)."""
    import dataclasses
    import json
    return json.dumps({"properties": properties, "records": [dataclasses.asdict(r) for r in records]})


def records_from_json(text: str) -> tuple[list[TestRecord], list[tuple[str, str]]]:
    import json
    data = json.loads(text)
    records = []
    for raw in data["records"]:
        raw["measurements"] = [Measurement(**m) for m in raw["measurements"]]
        raw["series"] = [Series(**{**s, "secondary": tuple(s["secondary"])}) for s in raw["series"]]
        records.append(TestRecord(**raw))
    return records, [tuple(p) for p in data["properties"]]


#: Suite file (stem, or a folder on its path) → report area: the families register theirs (hil.core.registry);
#: the first match wins, a folder before a stem
REPORT_AREAS.register("test_smoke", "smoke")


def area_of(path: str) -> str:
    """The report area of a test file (``suites/test_smoke.py`` → "smoke")."""
    p = PurePath(path.split("::", 1)[0])
    areas = REPORT_AREAS.items()
    for part in p.parts[:-1]:
        for key, area in areas:
            if part == key:
                return area
    for key, area in areas:
        if p.stem.startswith(key):
            return area
    stem = p.stem.removeprefix("test_")
    return stem or "other"
