"""hil's usage errors inside pytest — a bench that cannot be opened, a marker used wrongly — said in hil's one
error-line form (``hil: error: <what> — <what to do next>``), as the command line says its own, rather than in
pytest's ``ERROR: …`` frame.  pytest's own usage errors stay pytest's.

PYTEST_DONT_REWRITE (no asserts here: see ``pytest_plugins`` in :mod:`hil.plugin.pytest_plugin`)."""

from __future__ import annotations

import sys
from collections.abc import Generator

import pytest

from hil.core.errors import ERROR_PREFIX, error_line


def usage_error(what: str, next_step: str = "") -> pytest.UsageError:
    """A usage error of hil's, to raise: pytest ends the run with its usage-error exit (4) as for its own.
    (pytest.UsageError is final: hil's are told apart by their line's form.)"""
    return pytest.UsageError(error_line(what, next_step))


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_cmdline_main(config: pytest.Config) -> Generator[None, object, object]:
    """Say hil's usage error as its one line (pytest would print it as ``ERROR: hil: error: …``)."""
    try:
        return (yield)
    except pytest.UsageError as exc:
        if not all(str(line).startswith(ERROR_PREFIX) for line in exc.args):
            raise
        for line in exc.args:
            print(line, file=sys.stderr, flush=True)
        return pytest.ExitCode.USAGE_ERROR
