"""A run on a labgrid place (``hil run --lg-place`` / ``--lg-reserve``, pytest's ``--hil-lg-place`` /
``--hil-lg-reserve``, or a profile's ``[labgrid]``): the place is held for the whole pytest session — reserved and
acquired in ``pytest_configure``, before anything is collected, and released in ``pytest_unconfigure``, which
pytest runs however the session ends (failures, errors, Ctrl-C; SIGTERM and SIGHUP unwind like Ctrl-C,
:mod:`hil.core.signals`).

The pytest options are ``--hil-lg-…``: labgrid's own pytest plugin (installed with it, ``-p no:labgrid`` keeps it
out) already has ``--lg-coordinator``.

PYTEST_DONT_REWRITE (no asserts here: see ``pytest_plugins`` in :mod:`hil.plugin.pytest_plugin`)."""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console
from rich.text import Text

from hil.bench.lab.session import LabSession
from hil.bench.lab.spec import TAGS_EXAMPLE
from hil.bench.profile import check_profile, lab_request, load_profile
from hil.core import signals
from hil.core.errors import HilError
from hil.core.signals import shielded
from hil.plugin.usage import usage_error

#: a queued run prints a plain line this often where there is no terminal (CI logs)
LOG_EVERY = 30.0


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("hil")
    group.addoption("--hil-lg-place", metavar="NAME", default=None,
                    help="run on this labgrid place: reserve it, wait for it, acquire it, take the target (and the "
                         "fault rig's coils) from its resources, release it at the end")
    group.addoption("--hil-lg-reserve", metavar="TAGS", default=None,
                    help=f"run on any labgrid place with these tags, e.g. \"{TAGS_EXAMPLE}\"")
    group.addoption("--hil-lg-coordinator", metavar="HOST:PORT", default=None,
                    help="the labgrid coordinator (default [labgrid] coordinator, $LG_COORDINATOR, 127.0.0.1:20408)")
    group.addoption("--hil-lg-wait", metavar="SECONDS", type=float, default=None,
                    help="give up when no place is allocated within SECONDS (default: wait as long as it takes)")


def hold_place(config: pytest.Config, state: Any, bench_path: Callable[[], Path]) -> None:
    """Reserve, wait for and acquire the place the run asks for, as ``state.lab`` (left None when it asks for
    none).  The whole profile is checked first, so a bad key costs no wait in the queue, and again with the
    place's URLs."""
    place, tags = config.getoption("--hil-lg-place"), config.getoption("--hil-lg-reserve")
    if not (place or tags or config.getoption("--bench")):
        return  # the bundled default profile names no place
    try:
        spec = lab_request(bench_path(), place=place, tags=tags,
                           coordinator=config.getoption("--hil-lg-coordinator"), wait=config.getoption("--hil-lg-wait"))
        if spec is None:
            return
        if config.getoption("--target"):
            raise usage_error(f"--target and {spec.describe()} both say where the PLC is", "give one of them")
        station = check_profile(bench_path(), spec).station
        signals.install()  # Ctrl-C, SIGTERM, SIGHUP while queued: the reservation is cancelled on the way out
        progress = _Progress(config)
        session = LabSession(spec, progress=progress)
        try:
            lab = session.open(station=station)
            state.lab = session  # from here on, pytest_unconfigure lets go of it
        finally:
            progress.stop()  # the status line, however the wait ended
        load_profile(bench_path(), lab=lab)  # what the place resolved to fits the profile (a rig for its faults…)
    except HilError as exc:
        raise usage_error(str(exc)) from None


def let_go(config: pytest.Config, session: LabSession) -> None:
    """Release the place and cancel the reservation; a second signal meanwhile does not cut it short."""
    with shielded():
        failed = session.close()
    if failed:
        _say(config, "hil: labgrid could not let go cleanly — " + "; ".join(failed) + " (labgrid-client -p PLACE "
                     "release --kick frees a place by hand)")


class _Progress:
    """What the session says: while the run queues, on a terminal one transient status line (what, seconds so
    far), elsewhere a plain line at first and every :data:`LOG_EVERY` seconds, so a queued CI job never looks like
    a hang; every other step (acquired, released, cancelled) one plain line."""

    def __init__(self, config: pytest.Config) -> None:
        self.config = config
        self.console = Console(file=sys.stdout, highlight=False, soft_wrap=True)
        self.status: Any = None
        self.logged: float | None = None
        self._uncaptured = contextlib.ExitStack()

    def __call__(self, state: str, text: str) -> None:
        if state != "waiting":
            self.stop()
            _say(self.config, f"hil: {text}")
        elif self.console.is_terminal:
            if self.status is None:
                self._uncaptured.enter_context(_uncaptured(self.config))
                self.status = self.console.status(Text(f"hil: {text}"), spinner="dots")
                self.status.start()
            self.status.update(Text(f"hil: {text}"))
        elif self.logged is None or time.monotonic() - self.logged >= LOG_EVERY:
            self.logged = time.monotonic()
            _say(self.config, f"hil: {text}")

    def stop(self) -> None:
        if self.status is not None:
            self.status.stop()
            self.status = None
            self._uncaptured.close()


def _say(config: pytest.Config, text: str) -> None:
    with _uncaptured(config):
        print(text, flush=True)


def _uncaptured(config: pytest.Config) -> Any:
    capman = config.pluginmanager.get_plugin("capturemanager")
    return capman.global_and_fixture_disabled() if capman is not None else contextlib.nullcontext()
