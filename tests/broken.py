"""Run the suites against deliberately broken emulators: a suite is worth something only if it fails on them."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.sim.plc import Emulator
from tests.conftest import EMULATOR_BENCH, REPO

SUITES = REPO / "suites"


class BrokenEmulator:
    """Plugin object for an inner pytest run: builds the profile's emulator, then lets ``breakage`` damage it."""

    def __init__(self, breakage: Callable[[Emulator, object, object], None]) -> None:
        self.breakage = breakage

    def pytest_hil_make_emulator(self, profile, epoch):
        emulator = build_emulator(profile, epoch)
        self.breakage(emulator, profile, epoch)
        return emulator


def inline_suites(pytester: pytest.Pytester, files: list[str], plugin: object | None = None,
                  *extra: str, bench: Path = EMULATOR_BENCH) -> pytest.HookRecorder:
    """Run suite ``files`` in-process on the emulator bench (or ``bench``); the inner run's recorder (its ``ret``:
    the run's exit code)."""
    paths = [str(SUITES / f) for f in files]
    # no:hypothesispytest: pytester restores sys.modules after each run, so every inner run would re-import it
    return pytester.inline_run(*paths, "--bench", str(bench), "-p", "no:cacheprovider", "-p", "no:hypothesispytest",
                               *extra, plugins=[plugin] if plugin else [])


def run_suites(pytester: pytest.Pytester, files: list[str], plugin: object | None = None,
               *extra: str, bench: Path = EMULATOR_BENCH) -> tuple[list[str], list[str]]:
    """Run suite ``files`` in-process on the emulator bench (or ``bench``); return (passed, failed) test ids."""
    recorder = inline_suites(pytester, files, plugin, *extra, bench=bench)
    passed, _skipped, failed = recorder.listoutcomes()
    return [r.nodeid for r in passed], [r.nodeid for r in failed]


def replace_model(emulator: Emulator, cls: type, replacement: object) -> None:
    """Swap the model of type ``cls`` for ``replacement`` (powered on in its place)."""
    index = next(i for i, m in enumerate(emulator.models) if type(m) is cls)
    replacement.power_on(emulator)
    emulator.models[index] = replacement


__all__ = ["BrokenEmulator", "inline_suites", "run_suites", "replace_model", "Path"]
