"""A bench that cannot be opened stops the run before anything is collected: one line naming the target and what
to check, exit 4 (pytest's usage error) — not a screen of skips and the same reason once per test.

The bench is opened (lock, wire, recovery of a dead run's journal) and asked for its status in
``pytest_sessionstart``, before pytest prints its header, whenever the run names a bench (``--bench``, which
``hil run`` always passes, or ``--target``) — so plain ``pytest suites --target …`` behaves as ``hil run`` does.
``--collect-only`` opens nothing; a pytest-xdist controller lets go of the wire once it has checked (its workers
open it) — on a real bench it keeps the locks for them, each a lane (:mod:`hil.plugin.lanes`).
Without either option the bench is opened when the first bench test is collected
(:func:`hil.plugin.pytest_plugin.pytest_collection_finish`), and one that cannot be is the same line there.

PYTEST_DONT_REWRITE (no asserts here: see ``pytest_plugins`` in :mod:`hil.plugin.pytest_plugin`)."""

from __future__ import annotations

import pytest

from hil.core import signals
from hil.core.errors import HilError
from hil.core.registry import examples
from hil.io.url import parse_target
from hil.plugin import lanes
from hil.plugin.stash import BENCH_SESSION, BenchState
from hil.plugin.usage import usage_error


def pytest_sessionstart(session: pytest.Session) -> None:
    # Not tryfirst: before the terminal reporter's header (its hook is trylast), nothing printed yet.
    config = session.config
    given = config.getoption("--target")
    if given is not None and not given.strip():
        raise usage_error("--target is empty", f"give a target URL (e.g. {examples()}), or leave it out to use the "
                                               f"bench profile's target")
    if config.option.collectonly or not (config.getoption("--bench") or config.getoption("--target")):
        return
    state = config.stash[BENCH_SESSION]
    signals.install()  # as hil.plugin.safety does (idempotent): a recovery replayed on opening is shielded
    try:
        target = state.target
        bench = state.open()
        bench.plc.status()  # a wire that connects but never answers is as unreachable as a refused port
    except HilError as exc:
        raise usage_error(unreachable(state, exc)) from None
    except pytest.fail.Exception as exc:  # state.open() says why in pytest's own form
        raise usage_error(unreachable(state, exc, target)) from None
    if lanes.distributed(config):  # a pytest-xdist controller runs no test: it checked, its workers open the bench
        problem = lanes.check_run(config, parse_target(target))
        if problem is not None:
            state.release()
            raise usage_error(f"hil: {problem}")
        if state.lock is None:
            state.release()  # each worker builds its own emulator
        else:
            lanes.lease(config)  # the locks stay with this run; each worker opens the wire as a lane


def unreachable(state: BenchState, exc: BaseException, target: str | None = None) -> str:
    """One line: the bench, the target and the reason (which says what to check)."""
    reason = " ".join(str(getattr(exc, "msg", None) or exc).split())
    reason = reason.removeprefix("cannot open the bench: ")
    try:
        name, target = state.profile.name, target or state.target
    except HilError:
        return f"hil: {reason}"
    return f"hil: cannot open bench {name!r} at {target}: {reason}"
