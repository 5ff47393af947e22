"""Shared fixtures for the harness's own tests."""

from __future__ import annotations

import random
from pathlib import Path

import numpy  # noqa: F401 - before any pytester run: its in-process runs put sys.modules back as they found it,

# and numpy's C core cannot be loaded a second time in one process (the report's plots then silently go missing)
import pytest

REPO = Path(__file__).resolve().parent.parent
EMULATOR_BENCH = REPO / "fixtures" / "benches" / "emulator.toml"
EMULATOR_TARGETS = ["emulator", "emulator+fatek-tcp", "emulator+fatek-serial", "emulator+modbus-tcp",
                    "emulator+modbus-rtu"]

pytest_plugins = ["pytester"]


def over_targets(*matrix_only: str) -> list:
    """EMULATOR_TARGETS as parameters; those named are marked ``matrix`` (a whole suite over a slow wire costs the
    gate CPU time that other tests of that wire already spend on the same frames)."""
    return [pytest.param(target, marks=pytest.mark.matrix if target in matrix_only else ())
            for target in EMULATOR_TARGETS]


@pytest.fixture
def emulator():
    from hil.families.fbs.sim import Emulator
    return Emulator()


@pytest.fixture(autouse=True)
def _private_hil_state(tmp_path_factory, monkeypatch):
    """Each test's bench journals and locks in its own directories, never the user's (hil.core.journal,
    hil.core.lock)."""
    base = tmp_path_factory.mktemp("hil-state")
    monkeypatch.setenv("HIL_STATE_DIR", str(base / "state"))
    monkeypatch.setenv("HIL_HISTORY_URL", "off")  # the run history only where a test turns it on (test_history*)
    if "HIL_LOCK_DIR" not in __import__("os").environ:
        monkeypatch.setenv("HIL_LOCK_DIR", str(base / "locks"))


@pytest.fixture(autouse=True)
def _no_process_left_behind():
    """What a test started in a group of its own (tests/processes.py) and did not end — it failed or was
    interrupted first — is ended here: an interrupted run leaves no ``hil emulate`` or worker behind."""
    from tests import processes
    before = processes.running()  # a module's or the session's emulator: ended by its own fixture
    yield
    processes.end_all(but=before)


# -- the gate's tiers and a new order every run (pyproject's markers; docs/getting-started.md) ----------------
# The order is shuffled here rather than by pytest-randomly: installed, that plugin would also shuffle the pytest
# runs these tests start (pytester's and subprocesses'), whose order is what those tests are about.
def pytest_addoption(parser):
    parser.addoption("--matrix", action="store_true",
                     help="also run the exhaustive real-time matrix (tests marked matrix; scripts/e2e_matrix.py)")
    parser.addoption("--order-seed", type=int, default=None,
                     help="shuffle the tests with this seed (default: a new one, printed in the header); "
                          "--order-seed=0 keeps the files' order")


ORDER_SEED = pytest.StashKey[int]()  # the controller's seed, chosen once a run


def _order_seed(config) -> int:
    workerinput = getattr(config, "workerinput", None)
    if workerinput is not None:  # a pytest-xdist worker: the controller's seed, so that every worker agrees
        return workerinput["hil_order_seed"]
    if ORDER_SEED not in config.stash:
        given = config.getoption("--order-seed")
        config.stash[ORDER_SEED] = given if given is not None else random.SystemRandom().randrange(1, 2**32)
    return config.stash[ORDER_SEED]


def _shuffled(path: Path) -> bool:
    """The project's own tests only: a pytest run they start may collect the suites and tests/data with this
    conftest loaded (``--rootdir`` the checkout), and its order is what such a test is about."""
    return path.is_relative_to(REPO / "tests") and not path.is_relative_to(REPO / "tests" / "data")


def pytest_configure_node(node):
    node.workerinput["hil_order_seed"] = _order_seed(node.config)


def pytest_report_header(config):
    return f"tests shuffled with --order-seed={_order_seed(config)}"


def pytest_collection_modifyitems(config, items):
    """The matrix only when asked for; the modules in a shuffled order and each module's tests too (a module's
    tests stay together: its fixtures are set up once); the longest e2e test first (a stable sort)."""
    if not config.getoption("--matrix"):
        deselected = [item for item in items if item.get_closest_marker("matrix")]
        if deselected:
            config.hook.pytest_deselected(items=deselected)
            items[:] = [item for item in items if not item.get_closest_marker("matrix")]
    seed = _order_seed(config)
    ours = [item for item in items if _shuffled(item.path)]
    if seed and ours:
        shuffle = random.Random(seed).shuffle
        modules: dict[str, list] = {}
        for item in ours:
            modules.setdefault(item.nodeid.split("::")[0], []).append(item)
        groups = list(modules.values())
        shuffle(groups)
        for group in groups:
            shuffle(group)
        items[:] = [item for item in items if not _shuffled(item.path)] + [item for group in groups for item in group]
    items.sort(key=_tier)


def _tier(item) -> int:
    """``e2e(leads=True)`` first of all, then the rest in the shuffled order, e2e and unmarked mixed: the longest (a
    minute of real time) starts at once on one worker while the others work through the rest, and the e2e tests,
    which mostly wait for real-time processes, share the host with the unmarked ones, which compute, instead of
    leaving it half idle at the end."""
    e2e = item.get_closest_marker("e2e")
    return 0 if e2e is not None and e2e.kwargs.get("leads", False) else 1


def pytest_sessionfinish(session):
    from tests import processes
    processes.end_all(grace=0)
