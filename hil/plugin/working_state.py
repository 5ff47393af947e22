"""``pytest.mark.working_state(kind, …)``: a suite's working state, put back when its last test ends.

Every test's writes are put back (and read back) when it ends.  On port 0 at 9600 bit/s that costs a PID test more
than the test itself: it reads the originals of a FUN86 box's operand blocks, writes the test's values, then
writes the originals back and reads them back — and the next test reads them again as its own originals.  Yet
those words (SV, Os and the gains of a box that is off — never OR and WR, FUN86's outputs; the bench's
scratch) are set by every test of the
suite before it relies on them, and between two of its tests their values are as arbitrary as a bench's
originals are.  A suite module marked ``working_state("pid", "scratch")`` has them journaled as usual (on disk
before the first write; recovery replays them after a crash) but put back once, when the module's last test ends
(:meth:`hil.bench.guard.Guard.hold`); every other element, EN, the outputs, the clock unless ``"clock"`` is named,
still goes back after each test.  The kinds a bench knows are its family's (:meth:`BenchBase.working_state`).

PYTEST_DONT_REWRITE (no asserts here: see ``pytest_plugins`` in :mod:`hil.plugin.pytest_plugin`)."""

from __future__ import annotations

from collections.abc import Generator
from typing import Any

import pytest

MARKER = ("working_state(kind, …): the module's tests each set these before relying on them — put back once the "
          "module's last test ends instead of after each test; \"clock\" on every bench, the other kinds are the "
          "bench family's (docs/safety.md)")

_NEXT = pytest.StashKey[Any]()  # the item pytest runs after this one (None: the last)
_HELD = pytest.StashKey[Any]()  # (module, kinds) of the hold in force on the session's bench


def kinds_of(item: pytest.Item | None) -> tuple[str, ...]:
    """The working-state kinds ``item``'s module declares (``pytestmark``), in order; () without the mark."""
    if item is None:
        return ()
    return tuple(dict.fromkeys(kind for mark in item.iter_markers("working_state") for kind in mark.args))


def _scope(item: pytest.Item | None) -> tuple[Any, tuple[str, ...]] | None:
    kinds = kinds_of(item)
    return (getattr(item, "module", None), kinds) if kinds and item is not None else None


def begin(bench: Any, item: pytest.Item) -> None:
    """Before ``item``'s test starts: the hold its module declares begins, when it is not already held (a hold
    of another module is released first — normally it ended with that module's last test)."""
    wanted = _scope(item)
    if item.config.stash.get(_HELD, None) == wanted:
        return
    end(bench, item.config)
    if wanted is not None:
        bench.hold(wanted[1])
        item.config.stash[_HELD] = wanted


def end_if_last(bench: Any, item: pytest.Item) -> None:
    """After ``item``'s own restore: end the hold when the next test is not of the same hold (or there is none)."""
    held = item.config.stash.get(_HELD, None)
    if held is not None and _scope(item.stash.get(_NEXT, None)) != held:
        end(bench, item.config)


def end(bench: Any, config: pytest.Config) -> None:
    """End the hold now: everything held put back and read back (RestoreError when the PLC refuses)."""
    if config.stash.get(_HELD, None) is None:
        return
    config.stash[_HELD] = None
    bench.release()


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_teardown(item: pytest.Item, nextitem: pytest.Item | None) -> Generator[None, object, object]:
    """Tell the bench fixture's teardown which test comes next (pytest runs the teardown inside this hook)."""
    item.stash[_NEXT] = nextitem
    return (yield)


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", MARKER)
