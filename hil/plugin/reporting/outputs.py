"""A run's outputs as OpenHTF has them: callbacks registered once, each handed the run's record; the reporter calls
every registered output and names none of them.

OpenHTF calls its output callbacks once, with the finished record.  A hil run needs three more moments, for its
honesty rules and for pytest's own files: :attr:`Moment.STARTED` (the bench is open and the tests collected: the
report files say INCOMPLETE until the end replaces them, so a run that dies never leaves an earlier run's PASSED),
:attr:`Moment.SUMMARY` (pytest's terminal summary), :attr:`Moment.FINISHED` (the verdict is known) and
:attr:`Moment.CLOSED` (pytest's ``--junitxml`` file is written, so it can be finished).  An output ignores the
moments it has nothing to say at.

The run's record is reached through one typed stash key, :data:`RUN`: ``config.stash[RUN]`` (the history
recorder, the requirement markers and the ``measure``/``report`` fixtures read it there).
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from hil.core.registry import Registry
from hil.plugin.reporting.model import TestRecord
from hil.plugin.reporting.verdict import Verdict
from hil.plugin.stash import BENCH_SESSION


class Moment(enum.Enum):
    STARTED = "started"  # tests collected, bench open: say INCOMPLETE, show the header
    SUMMARY = "summary"  # pytest's terminal summary
    FINISHED = "finished"  # the session's end: the verdict known
    CLOSED = "closed"  # pytest_unconfigure: pytest's own JUnit file written


@dataclass
class RunRecord:
    """What one run's outputs are made of: the record of each test, the bench's properties, the verdict."""

    config: pytest.Config
    records: dict[str, TestRecord] = field(default_factory=dict)
    properties: list[tuple[str, str]] = field(default_factory=list)
    verdict: Verdict | None = None
    uses_bench: bool = False  # some collected test uses the bench (else the outputs say nothing of one)
    html_path: Path | None = None
    html_written: Path | None = None
    attachments_dir: Path | None = None  # where report.attach_file saves (None: no report is being written)
    junit_traces: dict[str, str] = field(default_factory=dict)  # hil.trace_file property → that test's trace
    annotations: Any = None  # the bench's history for the HTML report (hil.history.annotate), set by the recorder
    after_progress: bool = False  # the session ended in an exception: pytest's summary did not end its line

    @property
    def state(self) -> Any:
        """The hil plugin's bench session (profile, target, bench) — None before it was configured."""
        return self.config.stash.get(BENCH_SESSION, None)

    @property
    def xmlpath(self) -> Path | None:
        value = self.config.getoption("xmlpath", None)
        return Path(value) if value else None

    def record(self, nodeid: str, area: str) -> TestRecord:
        """The record of test ``nodeid``, made on first use."""
        return self.records.setdefault(nodeid, TestRecord(nodeid, area))


#: the one typed stash key of a run's record (``config.stash[RUN]``)
RUN = pytest.StashKey[RunRecord]()

Output = Callable[[Moment, RunRecord], None]
#: name → output callback, called in the order registered
OUTPUTS: Registry[Output] = Registry("report output")


def register_output(name: str, output: Output) -> Output:
    return OUTPUTS.register(name, output)


def emit(moment: Moment, run: RunRecord) -> None:
    """Every registered output, at ``moment``."""
    for _name, output in OUTPUTS.items():
        output(moment, run)


__all__ = ["Moment", "OUTPUTS", "Output", "RUN", "RunRecord", "emit", "register_output"]
