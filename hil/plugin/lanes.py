"""Lanes: one run on one PLC in several pytest-xdist worker processes at once (``hil run --lanes N``).

On port 0 at 9600 bit/s the line is idle while a test waits for the PLC — a PID interval, a module's update, the
clock's next second — and busy while another sets a clock field by field.  A second lane's requests fill those
gaps (docs/performance.md).  What keeps it safe:

* **Which tests may overlap.**  Every test is in a lane: its module's ``pytest.mark.lane(NAME)``, else ``"main"``.
  ``hil run --lanes N`` is ``-n N --dist each``: every worker collects every test and keeps its own lanes' (they
  are dealt round the workers), so a lane's tests run in one worker, in their order, as in a run without lanes;
  only different lanes overlap.  The modules of one lane may touch the same elements; different lanes must
  not (the RTC suites' clock and M1952–M1955 are one lane, the temperature and PID suites, which share the plant
  and the scratch registers, the other).  A lane is a process, so each keeps its own working state.
* **One run, one lock.**  The controller opens the bench before any worker starts: it takes the locks and replays
  whatever a dead run left (its journal and every lane's), then lets go of the wire but keeps the locks to the end.
  Each worker opens the wire under that lease (``hil_lane_lease``) instead of locking, and journals what it changes
  in its own lane journal (``journal-….lane-gwN.json``), which the next run replays with the run's own.  A worker
  holds the controller's own open lock files and is killed by the kernel when its controller dies
  (:mod:`hil.core.lease`): a controller killed leaves the bench locked until its last worker is gone, and no lane
  writes after it — the next run replays what they left.
* **A wire lanes can share** (the scheme's ``lanes``): TCP or UDP to the PLC, a connection each; a serial device or
  pty, taken in turn by whole exchanges (:mod:`hil.io.shared_line`), the main lane first: the other lanes fill
  the line while it waits for the PLC.  Not an RFC 2217 server (one client at a time)
  nor a Modbus RTU line; an in-process emulator is each worker's own, as in any xdist run.
* **The verdict.**  Each worker says, at its end, whether it left the PLC as it found it (``hil_plc_left``); the
  controller fails the run when one did not.  When a worker died, the controller replays the journals itself (its
  locks are still held) before it lets go, and says what that found.

PYTEST_DONT_REWRITE (no asserts here: see ``pytest_plugins`` in :mod:`hil.plugin.pytest_plugin`)."""

from __future__ import annotations

import os
from collections.abc import Generator
from typing import Any

import pytest

from hil.core.errors import HilError
from hil.core.lease import LockLender, borrow, die_with_parent
from hil.core.registry import SCHEMES
from hil.io.shared_line import run_in_background
from hil.plugin.order import by_line_use, line_use
from hil.plugin.safety import AS_FOUND, PLC_LEFT, announce, say
from hil.plugin.stash import BENCH_SESSION, BenchState
from hil.plugin.usage import usage_error

MARKER = ("lane(name, line=\"busy\"|\"paced\"|\"idle\"): the lane of this module's tests in a run with lanes "
          "(hil run --lanes N): tests of one lane run in one process, in order; tests of different lanes may run at "
          "the same time on one PLC, so they must touch no element in common (unmarked: lane \"main\"); line: how "
          "the module uses a shared line — requests back to back, bursts at a short cadence, or mostly waits for the "
          "PLC —, which orders a lane's modules (hil.plugin.order)")
DEFAULT = "main"
#: in a worker's ``workerinput``: the controller holds the bench's locks for it (its pid)
LEASE = "hil_lane_lease"
#: in a worker's ``workerinput``: the controller runs ``--dist each`` (a worker's own option says "no")
SPLIT = "hil_lanes"
#: in a worker's ``workerinput``: where it borrows the controller's open lock files (:class:`LockLender`)
LOCKS = "hil_lane_locks"
#: in a worker's ``workeroutput``: what it says of the PLC at its end (:data:`hil.plugin.safety.PLC_LEFT`)
LEFT = "hil_plc_left"
_LANES_LEFT = pytest.StashKey[dict]()  # worker id → what it said of the PLC (None: nothing)
_LENDER = pytest.StashKey[LockLender]()  # the controller's: its locks, lent to each worker
_BORROWED: list[int] = []  # a worker's: the controller's lock files, held open until this process ends


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", MARKER)
    if distributed(config) and getattr(config.option, "dist", "no") == "each":
        config.pluginmanager.register(_Collected(), "hil-lanes-collected")
    given = getattr(config, "workerinput", None)
    if given and given.get(LEASE):
        _hold_the_runs_locks(given)


def _hold_the_runs_locks(given: dict) -> None:
    """A worker, before it touches the PLC: die with the controller, and hold its locks with it."""
    holder, lane = given[LEASE], given.get("workerid")
    try:
        if not die_with_parent(holder):
            raise HilError(f"the run's controller (pid {holder}) is gone, and the bench's locks with it")
        _BORROWED.extend(borrow(given[LOCKS]))
    except HilError as exc:
        raise usage_error(f"hil: lane {lane} does not start: {exc}") from None


def pytest_unconfigure(config: pytest.Config) -> None:
    lender = config.stash.get(_LENDER, None)
    if lender is not None:
        lender.close()


def lane_of(item: pytest.Item) -> str:
    mark = item.get_closest_marker("lane")
    return str(mark.args[0]) if mark is not None and mark.args else DEFAULT


def worker_lane(config: pytest.Config) -> str | None:
    """In a worker that the controller leased the bench to: its lane's name (the worker id); else None."""
    given = getattr(config, "workerinput", None)
    if not given or not given.get(LEASE):
        return None
    return str(given.get("workerid") or "gw")


def distributed(config: pytest.Config) -> bool:
    """This process is a pytest-xdist controller: it runs no test, its workers do."""
    return getattr(config.option, "dist", "no") != "no" and not hasattr(config, "workerinput")


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """A worker of a run with lanes (``--dist each``: every worker collects every test) keeps its own lanes' tests
    and deselects the others: the lanes, in name order, dealt round the workers.  Every worker sees the same
    collection, so each deals the same way and every test runs exactly once, in its lane's worker.

    (Not ``--dist loadgroup``: pytest-xdist 3.8 names a group by rewriting ``item._nodeid``, which pytest 9.2 no
    longer reads, so its groups silently spread over the workers.)"""
    for item in items:
        line_use(item)  # (a bad line= is an error in any run, not only one with lanes)
    given = getattr(config, "workerinput", None)
    if not given or not given.get(SPLIT):
        return
    index, count = _worker_index(given), int(given.get("workercount") or 1)
    names = sorted({lane_of(item) for item in items})
    mine = {name for n, name in enumerate(names) if n % count == index}
    kept = [item for item in items if lane_of(item) in mine]
    dropped = [item for item in items if lane_of(item) not in mine]
    # the main lane has the line first; the others fill its idle time (hil.io.shared_line)
    background = DEFAULT not in mine and DEFAULT in names
    run_in_background(background)
    by_line_use(kept, background)
    if dropped:
        config.hook.pytest_deselected(items=dropped)
    items[:] = kept


def _worker_index(given: dict) -> int:
    worker = str(given.get("workerid") or "gw0")
    digits = worker.removeprefix("gw")
    return int(digits) if digits.isdigit() else 0


def check_run(config: pytest.Config, target: Any) -> str | None:
    """Why this xdist run cannot have lanes on ``target`` (a parsed target URL); None: it can (or needs none)."""
    if target.in_process:
        return None  # each worker builds its own emulator
    if getattr(config.option, "dist", "no") != "each":
        return (f"several workers on one PLC need --dist each, so that each lane's tests stay in one worker "
                f"(`hil run --lanes N` passes it), not --dist {config.option.dist}")
    scheme = SCHEMES.get(target.scheme)
    if scheme is None or not scheme.lanes:
        shared = ", ".join(sorted(name for name, s in SCHEMES.items() if s.lanes and not s.in_process))
        return (f"lanes cannot share a {target.scheme} wire (one client at a time): run without -n/--lanes, or "
                f"reach the PLC over one of {shared}")
    return None


def lease(config: pytest.Config) -> None:
    """The controller, once it has opened the bench (locks taken, recovery done): let go of the wire, keep the locks
    for the workers."""
    state = config.stash[BENCH_SESSION]
    recovery = state.recovery
    if recovery is not None and not recovery.ok:
        state.release()
        raise usage_error(f"{recovery.summary()} — no lane starts on a PLC left changed: `hil restore` once "
                          f"the cause is fixed")
    state.close_wire()
    try:
        config.stash[_LENDER] = LockLender(_lock_files(state))
    except HilError as exc:
        state.release()
        raise usage_error(f"hil: {exc}") from None
    config.stash[_LANES_LEFT] = {}
    # A worker that dies is not replaced: its replacement would run beside the dead lane's journal, unreplayed
    # (the controller replays it at the end).  pytest-xdist reads --max-worker-restart when it configures, before
    # the bench is known to be a real one; its session object keeps the number.
    dsession = config.pluginmanager.getplugin("dsession")
    if dsession is not None and hasattr(dsession, "_max_worker_restart"):
        dsession._max_worker_restart = 0  # noqa: SLF001 - xdist has no public way to change it after configure


def _lock_files(state: BenchState) -> list[int]:
    """The open files of the bench's locks the controller holds (its place's, its endpoint's, its PLC's)."""
    locks = (state.place_lock, state.lock, state.plc_lock)
    return [fd for lock in locks if lock is not None and (fd := lock.fileno()) is not None]


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    """A lane goes on only while its controller does.  On Linux the kernel kills the lane with it (its first line of
    defence, :func:`_hold_the_runs_locks`); elsewhere the lane stops here, before its next test — it holds the run's
    locks until it exits, so no other run takes the PLC while its teardown puts its writes back."""
    given = getattr(item.config, "workerinput", None)
    holder = given.get(LEASE) if given else None
    if holder and os.getppid() != holder:
        pytest.exit(f"hil: the run's controller (pid {holder}) is gone, and the bench's locks with it: lane "
                    f"{worker_lane(item.config)} stops", returncode=pytest.ExitCode.INTERRUPTED)


@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node: Any) -> None:
    if getattr(node.config.option, "dist", "no") == "each":
        node.workerinput[SPLIT] = True
    state = node.config.stash.get(BENCH_SESSION, None)
    if state is not None and state.leased:
        node.workerinput[LEASE] = os.getpid()
        node.workerinput[LOCKS] = node.config.stash[_LENDER].address
    # every lane started has said nothing of the PLC until it does (pytest_testnodedown): a run stopped before a
    # worker could report (Ctrl-C, SIGTERM to the controller) replays its journal rather than call the PLC as found
    left = node.config.stash.get(_LANES_LEFT, None)
    if left is not None:
        left.setdefault(node.gateway.id, None)


class _Collected:
    """A ``--dist each`` controller's count of the run's tests: each worker collected its own lanes' tests, and
    pytest-xdist takes the last worker's count for the run's (its progress would pass 100 %) — the sum instead."""

    def __init__(self) -> None:
        self.per_worker: dict[str, int] = {}
        self.session: pytest.Session | None = None

    def pytest_sessionstart(self, session: pytest.Session) -> None:
        self.session = session

    @pytest.hookimpl(optionalhook=True)
    def pytest_xdist_node_collection_finished(self, node: Any, ids: list[str]) -> None:
        self.per_worker[node.gateway.id] = len(ids)

    def pytest_runtest_logstart(self) -> None:
        if self.session is not None and self.per_worker:
            self.session.testscollected = sum(self.per_worker.values())


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node: Any, error: object | None) -> None:
    left = node.config.stash.get(_LANES_LEFT, None)
    if left is None:
        return
    # None: the lane said nothing of the PLC (its process died, or it never got to its safety report)
    left[node.gateway.id] = (getattr(node, "workeroutput", {}).get(LEFT) or None) if error is None else None


@pytest.hookimpl(wrapper=True)
def pytest_sessionfinish(session: pytest.Session) -> Generator[None, object, object]:
    """After every other session-end hook (the safety report's last restores among them):

    * a worker says how it left the PLC — inside pytest-xdist's own wrapper, which sends ``workeroutput`` once
      this returns;
    * the controller gives the run's word on the PLC from every lane's — inside the report's wrapper, which gives
      the verdict from the exit status this may set."""
    result = yield
    config = session.config
    if worker_lane(config) is not None:
        config.workeroutput[LEFT] = config.stash.get(PLC_LEFT, "")  # type: ignore[attr-defined]  # xdist's, on a worker
    elif config.stash.get(_LANES_LEFT, None) is not None:
        _the_runs_word(session)
    return result


def _the_runs_word(session: pytest.Session) -> None:
    config = session.config
    lanes = config.stash[_LANES_LEFT]
    died = [lane for lane, said in lanes.items() if said is None]
    if died:  # replayed by this run, which still holds the locks: as found only if that put everything back
        say(config, f"hil: lane{'s' if len(died) > 1 else ''} {', '.join(sorted(died))} ended without a word on the "
                    f"PLC (a process that died): this run replays the journals now", bold=True, yellow=True)
        word = AS_FOUND if _replay(config) else "its process died, and what it left is not known to be put back"
        lanes.update(dict.fromkeys(died, word))
    wrong = {lane: said for lane, said in lanes.items() if said != AS_FOUND}
    config.stash[PLC_LEFT] = AS_FOUND if not wrong else "; ".join(
        f"lane {lane}: {said}" for lane, said in sorted(wrong.items()))
    if wrong:
        say(config, f"hil: {config.stash[PLC_LEFT]}", bold=True, red=True)
        if session.exitstatus == 0:
            session.exitstatus = pytest.ExitCode.TESTS_FAILED


def _replay(config: pytest.Config) -> bool:
    """A lane died: open the bench again (the locks are still this run's) and replay every journal now; whether
    that was done and put everything back, read back."""
    state = config.stash[BENCH_SESSION]
    try:
        state.open()
    except (Exception, pytest.fail.Exception) as exc:  # noqa: BLE001 - said; the lane's journal stays for later
        say(config, f"hil: a lane died and its journal could not be replayed now ({exc}): the next run or "
                    f"`hil restore` does it", bold=True, red=True)
        return False
    try:
        recovery = state.recovery
        if recovery is not None and recovery.needed:
            announce(config, recovery)
        return recovery is not None and recovery.ok
    finally:
        state.close_wire()
