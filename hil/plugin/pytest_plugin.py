"""The hil pytest plugin: options, markers, collection-time skips, and the ``bench`` fixture.

Loaded automatically through the ``pytest11`` entry point.  The bench is opened once per session — before
collection when the run names one (:mod:`hil.plugin.preflight`), else once a bench test is collected; one that
cannot be opened stops the run there, in one line — and every test's writes are restored when the test ends (a
module's declared working state when its last test ends: :mod:`hil.plugin.working_state`).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Collection, Generator, Iterator
from pathlib import Path

import pytest

from hil.bench.base import BenchBase as Bench
from hil.bench.capabilities import CAPABILITIES, bench_capabilities, how_to_offer, unknown
from hil.bench.faces import BenchView
from hil.bench.family import build_emulator, default_family, open_bench
from hil.bench.lab.session import LabSession
from hil.bench.profile import Profile, load_profile, plc_target, refuse_default_for_a_plc
from hil.bench.replay import Recovery
from hil.bench.view import suite_view
from hil.core.errors import HilError, TransportError
from hil.core.evidence import StaleEvidence
from hil.core.lock import BenchLock, bench_locks, describe_holder
from hil.core.paths import default_bench
from hil.core.registry import examples
from hil.core.signals import shielded
from hil.io.url import Target, parse_target
from hil.plugin import bench_time, hookspecs, lanes, order, working_state
from hil.plugin.lab import hold_place, let_go
from hil.plugin.preflight import unreachable
from hil.plugin.safety import announce
from hil.plugin.stash import BENCH_SESSION
from hil.plugin.usage import usage_error
from hil.sim.engine import Engine

# round trips and wire bytes per test (hil_requests … JUnit properties); bench safety; labgrid places; spec() IDs;
# the bench opened before collection; the fixtures every bench has (plc, io, faults)
#: this plugin's own plugin modules; each says PYTEST_DONT_REWRITE (no asserts to rewrite), so importing one before
#: pytest loads it — the command line does, the reports' entry point does — costs no "already imported" warning
pytest_plugins = ["hil.plugin.perf", "hil.plugin.safety", "hil.plugin.lab", "hil.plugin.requirements",
                  "hil.plugin.preflight", "hil.plugin.fixtures", "hil.plugin.working_state", "hil.plugin.lanes",
                  "hil.plugin.usage"]
DEFAULT_BENCH = Path("fixtures") / "benches" / "emulator.toml"
MARKERS = {
    "needs": "needs(capability, …, reason=…): the test needs what not every bench offers (virtual_time, "
             "power_on_state, power_cycle, spec_choices, scan_counter; hil.bench.capabilities); skipped with "
             "the reason and what would offer it on a bench that does not; power_on_state tests run first",
    "slow": "slow: takes minutes of bench time on a real PLC; skipped there unless --hil-run-slow "
            "(runs in virtual time on the emulator)",
    "destructive": "destructive: changes RUN/STOP or outputs; skipped unless --hil-allow-destructive or the "
                   "profile's [safety] allow_destructive",
    "measures": "measures(name, unit=…, low=…, high=…): a measurement the test declares before it runs (OpenHTF's "
                "way); it stays UNSET until measure(name, value) records it, and a test that passes with a "
                "declared measurement still UNSET fails: no pass without the evidence",
    "bench_time": bench_time.MARKER,
    "family": "family(name, …): the controller families a bench test is for (a [bench] family of an installed "
              "family plug-in); unmarked bench tests are for the default family; deselected when the bench "
              "profile's [bench] family differs",
}


def pytest_addhooks(pluginmanager: pytest.PytestPluginManager) -> None:
    pluginmanager.add_hookspecs(hookspecs)


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("hil", "hil hardware-in-the-loop")
    group.addoption("--bench", metavar="FILE", default=None,
                    help=f"bench profile (TOML); default {DEFAULT_BENCH}")
    group.addoption("--target", metavar="URL", default=None,
                    help="target URL overriding the profile's, e.g. " + examples())
    group.addoption("--hil-allow-destructive", action="store_true", default=False,
                    help="allow tests marked destructive (RUN/STOP, outputs)")
    group.addoption("--hil-run-slow", action="store_true", default=False,
                    help="run tests marked slow on a real bench (they take real minutes)")
    group.addoption("--hil-lock-wait", metavar="SECONDS", type=float, default=0.0,
                    help="wait up to SECONDS for another run to release the bench (default: refuse at once, "
                         "naming who holds it)")


def pytest_configure(config: pytest.Config) -> None:
    for text in MARKERS.values():
        config.addinivalue_line("markers", text)
    state = config.stash[BENCH_SESSION] = BenchSession(config)
    # a labgrid place is held for the whole session: the target comes from it, so before anything is collected
    hold_place(config, state, lambda: resolve_bench_path(config))


class BenchSession:
    """Per-session state: the profile (read at once, so a bad profile fails early) and the bench (lazily)."""

    def __init__(self, config: pytest.Config) -> None:
        self.config = config
        self.bench: Bench | None = None
        self.error: str | None = None
        self.dead: str | None = None  # set when the PLC stopped answering: later tests error with this reason
        self.lock: BenchLock | None = None  # on a real bench, held until unconfigure
        self.place_lock: BenchLock | None = None  # and one keyed on the labgrid place, when the bench is one
        self.plc_lock: BenchLock | None = None  # and one keyed on the profile's [bench] plc_id, when it names the PLC
        self.lab: LabSession | None = None  # the labgrid place held for this session
        self.recovery: Recovery | None = None  # what a dead run left, replayed when the bench opened
        self.plc_line = ""  # the header's "hil PLC: …" line, once written (hil.plugin.reporting shows it)
        self.header_panel = False  # True: the console output's panel shows that line instead (hil.plugin.reporting)
        self._profile: Profile | None = None

    @property
    def profile(self) -> Profile:
        if self._profile is None:
            self._profile = load_profile(resolve_bench_path(self.config), lab=self.lab.lab if self.lab else None)
        return self._profile

    @property
    def target(self) -> str:
        return self.config.getoption("--target") or self.profile.target

    def open(self) -> Bench:
        if self.dead:
            raise pytest.fail.Exception(f"bench not usable: {self.dead}", pytrace=False)
        if self.bench is None:
            if self.error:
                raise pytest.fail.Exception(self.error, pytrace=False)
            hook = self.config.hook.pytest_hil_make_emulator
            try:
                self._refuse_default_profile()
                self._lock_bench()
                self.bench = open_bench(self.profile, target=self.config.getoption("--target"),
                                   allow_destructive=self.config.getoption("--hil-allow-destructive"),
                                   emulator_builder=lambda p, e: hook(profile=p, epoch=e) or _default_build(p, e),
                                   lane=lanes.worker_lane(self.config))
                self._recover(self.bench)
            except HilError as exc:
                self.error = f"cannot open the bench: {exc}"
                raise pytest.fail.Exception(self.error, pytrace=False) from None
        return self.bench

    def _recover(self, bench: Bench) -> None:
        """Recovery first (issue 15): a journal a dead run left is replayed before any test, and said loudly."""
        self.recovery = recovery = bench.recover()
        if recovery is None or not recovery.needed:
            return
        announce(self.config, recovery)
        if not recovery.ok:
            self.dead = recovery.summary()

    def _refuse_default_profile(self) -> None:
        """The bundled profile is the emulator's: never for a PLC named by --target alone; and a PLC only ever
        with a profile that names it, at its station (before any lock is taken or byte sent)."""
        refuse_default_for_a_plc(self.config.getoption("--target"), self.config.getoption("--bench"),
                                 self.profile.path or resolve_bench_path(self.config))
        plc_target(self.profile, self.config.getoption("--target"))

    def _lock_bench(self) -> None:
        """Two runs must not interleave on one real bench (an in-process emulator is each run's own)."""
        if self.lock is not None or parse_target(self.target).in_process:
            return
        if lanes.worker_lane(self.config) is not None:
            return  # a lane of a run with lanes: the controller holds every lock for the whole run (hil.plugin.lanes)
        wait = self.config.getoption("--hil-lock-wait") or 0.0
        if self.profile.lab is not None:  # labgrid excludes other hosts; this guards this host, also without labgrid
            self.place_lock = BenchLock(self.profile.lab.lock_target).acquire(wait=wait)
        endpoint, *plc = bench_locks(self.target, self.profile.plc_id)
        self.lock = endpoint.acquire(wait=wait)
        self.plc_lock = plc[0].acquire(wait=wait) if plc else None

    @property
    def leased(self) -> bool:
        """The locks are held with the wire closed: a run with lanes' controller, for its workers."""
        return self.bench is None and self.lock is not None

    def close_wire(self) -> None:
        """Close the bench's wire but keep the locks: a run with lanes' controller, for its workers."""
        try:
            if self.bench is not None:
                self.bench.close()
        finally:
            self.bench = None

    def release(self) -> None:
        try:
            self.close_wire()
        finally:
            for lock in (self.plc_lock, self.lock, self.place_lock):
                if lock is not None:
                    lock.release()
            self.lock = self.place_lock = self.plc_lock = None
            if self.lab is not None:
                session, self.lab = self.lab, None
                let_go(self.config, session)

    def finish(self, request: pytest.FixtureRequest, bench: Bench) -> None:
        """The bench fixture's teardown: restore; a restore that fails goes into the report (JUnit properties);
        a dead wire marks the bench dead so the remaining tests error at once with the reason."""
        try:
            bench.end_test()
            working_state.end_if_last(bench, request.node)  # the module's last test: its working state back too
        except HilError as exc:
            failures = getattr(exc, "failures", None)
            if failures is not None:
                request.node.user_properties.append(
                    ("hil_restore_failed", "; ".join(f"{a} (original {v}): {why}" for a, v, why in failures)))
            why = bench.alive()
            if why is not None:
                self.dead = f"restore after {request.node.nodeid} failed and the PLC does not answer: {exc}"
            raise
        failure = request.node.stash.get(_WIRE_FAILURE, None)
        if failure is not None:
            why = bench.alive()
            if why is not None:
                self.dead = f"the PLC stopped answering during {request.node.nodeid}: {failure}"


_WIRE_FAILURE = pytest.StashKey[str]()


def _default_build(profile: Profile, epoch: dt.datetime) -> Engine:
    return build_emulator(profile, epoch)


def resolve_bench_path(config: pytest.Config) -> Path:
    given = config.getoption("--bench")
    if given:
        return Path(given)
    for base in (Path.cwd(), Path(str(config.rootpath))):
        if (base / DEFAULT_BENCH).is_file():
            return base / DEFAULT_BENCH
    if default_bench().is_file():  # the bundled default (a checkout or an installed wheel)
        return default_bench()
    raise usage_error(f"no bench profile given and {DEFAULT_BENCH} not found", "pass --bench FILE")


def pytest_report_header(config: pytest.Config) -> list[str] | None:
    if not (config.getoption("--bench") or config.getoption("--target")):
        return None
    state = config.stash[BENCH_SESSION]
    try:
        profile = state.profile
    except HilError as exc:
        raise usage_error(str(exc)) from None
    return [f"hil bench: {profile.name} ({profile.path})", f"hil target: {state.target}"]


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if not any("bench" in getattr(item, "fixturenames", ()) for item in items):
        return
    state = config.stash[BENCH_SESSION]
    try:
        target = parse_target(state.target)
        profile = state.profile
    except HilError as exc:
        raise usage_error(str(exc)) from None
    destructive_ok = config.getoption("--hil-allow-destructive") or profile.safety.allow_destructive
    offered = bench_capabilities(target, profile.scan_counter, profile.offers)
    order.power_on_first(items)
    _deselect_other_families(config, items, profile)
    run_slow = target.in_process or config.getoption("--hil-run-slow")
    for item in items:
        _skip_what_the_target_lacks(item, target, offered)
        _skip_without_opt_in(item, destructive_ok=destructive_ok, run_slow=run_slow)
    bench_time.apply(items, profile, target.in_process)


def _skip_what_the_target_lacks(item: pytest.Item, target: Target, offered: Collection[str]) -> None:
    """A test whose ``needs(...)`` names a capability the target does not offer is skipped, saying why and how to
    offer it; a ``needs()`` naming none, or one not known, is a usage error."""
    for marker in item.iter_markers("needs"):
        bad = unknown(marker.args)
        if bad or not marker.args:
            raise usage_error(f"{item.nodeid}: needs() takes capabilities among "
                              f"{', '.join(CAPABILITIES)}, not {', '.join(bad) or 'nothing'}")
        missing = [name for name in marker.args if name not in offered]
        if missing:
            why = marker.kwargs.get("reason") or "; ".join(CAPABILITIES[name] for name in missing)
            offer = "; ".join(how_to_offer(name) for name in missing)
            item.add_marker(pytest.mark.skip(
                reason=f"needs {', '.join(missing)}: {why} (target {target} does not offer it; {offer})"))


def _skip_without_opt_in(item: pytest.Item, *, destructive_ok: bool, run_slow: bool) -> None:
    """Destructive tests and, on a real bench, slow ones run only when the run opted in."""
    if item.get_closest_marker("destructive") and not destructive_ok:
        item.add_marker(pytest.mark.skip(reason="destructive: pass --hil-allow-destructive to run it"))
    if item.get_closest_marker("slow") and not run_slow:
        item.add_marker(pytest.mark.skip(reason="slow on a real bench: pass --hil-run-slow to run it"))


_OTHER_FAMILIES = pytest.StashKey[str]()


def _deselect_other_families(config: pytest.Config, items: list[pytest.Item], profile: Profile) -> None:
    """Bench tests for another controller family are deselected, with one line saying why (not a screen of
    identical skips: the default run collects every family's suites)."""
    other: dict[str, int] = {}
    kept, dropped = [], []
    for item in items:
        family = item.get_closest_marker("family") if "bench" in getattr(item, "fixturenames", ()) else None
        wanted = tuple(family.args) if family and family.args else (default_family().name,)
        if "bench" in getattr(item, "fixturenames", ()) and profile.family not in wanted:
            label = " or ".join(wanted)
            other[label] = other.get(label, 0) + 1
            dropped.append(item)
        else:
            kept.append(item)
    if not dropped:
        return
    config.hook.pytest_deselected(items=dropped)
    items[:] = kept
    config.stash[_OTHER_FAMILIES] = "; ".join(
        f"hil: {n} test{'s' if n != 1 else ''} for {label} PLCs deselected: bench {profile.name!r} is family "
        f"{profile.family!r}" for label, n in other.items())


def pytest_report_collectionfinish(config: pytest.Config) -> str | None:
    return config.stash.get(_OTHER_FAMILIES, None)


def pytest_collection_finish(session: pytest.Session) -> None:
    if not any("bench" in getattr(item, "fixturenames", ()) for item in session.items):
        return
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    state = session.config.stash[BENCH_SESSION]
    try:
        bench = state.open()
        line = f"hil PLC: {bench.plc.status().summary()} via {bench.raw.description}"
        if state.lock is not None and state.lock.stale:
            line += f" (took over a stale bench lock left by {describe_holder(state.lock.stale)})"
    except (HilError, pytest.fail.Exception) as exc:
        if state.bench is None:  # never opened (not opened before collection either): one line, exit 4
            raise usage_error(unreachable(state, exc)) from None
        line = f"hil PLC: unreachable — {exc}"
        state.error = state.error or line
    state.plc_line = line  # hil.plugin.reporting shows it in its header panel (which replaces this line)
    if reporter is not None and session.config.get_verbosity() >= 0 and not state.header_panel:
        reporter.write_line(line)


@pytest.hookimpl(tryfirst=True)  # while hil.core.signals still defers a signal (the safety plugin uninstalls it)
def pytest_unconfigure(config: pytest.Config) -> None:
    state = config.stash.get(BENCH_SESSION, None)
    if state is not None:
        state.release()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item,
                              call: pytest.CallInfo[None]) -> Generator[None, pytest.TestReport, pytest.TestReport]:
    """Remember a wire failure in a bench test: its teardown checks whether the PLC still answers."""
    report = yield
    if call.when == "setup" and report.failed and "bench" in getattr(item, "fixturenames", ()):
        state = item.config.stash[BENCH_SESSION]
        if state.bench is None and state.error:
            # The bench never opened: this test's error says why, and the session stops here — every other
            # bench test would repeat the same line (exit status 1, as for a failed test)
            item.session.shouldfail = state.error
    if (call.when == "call" and call.excinfo is not None and call.excinfo.errisinstance(TransportError)
            and "bench" in getattr(item, "fixturenames", ())):
        item.stash[_WIRE_FAILURE] = f"{call.excinfo.typename}: {call.excinfo.value}"
    if call.when == "call" and call.excinfo is not None and call.excinfo.errisinstance(StaleEvidence):
        # a plain attribute, as pytest lets a plugin add to a report: it travels with it from an xdist worker
        report.stale_evidence = True  # type: ignore[attr-defined]  # pytest's TestReport declares none of these
    return report


def pytest_report_teststatus(report: pytest.TestReport, config: pytest.Config) -> tuple[str, str, str] | None:
    """A wait satisfied before its stimulus is an error of the test, not a verdict on the PLC: counted and
    listed as an error (the run still exits 1)."""
    if report.when == "call" and getattr(report, "stale_evidence", False):
        return "error", "E", "ERROR (stale evidence)"
    return None


@pytest.fixture
def bench(request: pytest.FixtureRequest) -> Iterator[BenchView]:
    """The bench (``hil.api.Bench`` on an FBs): ``bench.plc`` the PLC under test behind the guard, ``bench.wait(s)``
    bench time (virtual on the in-process emulator), ``bench.time.calendar()``, ``bench.cannot_reach(...)`` for a
    skip's reason, ``bench.faults``, ``bench.profile``.  Opened once per session (``--bench FILE``, ``--target
    URL``); every write a test makes is put back, and read back, when the test ends, pass or fail — what its
    module declares as working state (``pytest.mark.working_state``) when the module's last test ends."""
    state = request.config.stash[BENCH_SESSION]
    bench = state.open()  # raises at once, with the reason, once the bench is known dead
    with shielded():
        working_state.begin(bench, request.node)  # the module's working state held (another module's put back)
        bench.begin_test(request.node.nodeid)  # retries a restore that failed earlier, first
    try:
        # only the guarded surface: no bench.raw, no .io.inner, no transport's private _write_* (issue 15)
        yield suite_view(bench)  # a test stopped by pytest-timeout (signal method) or SIGTERM/SIGHUP unwinds here
    finally:
        with shielded():  # a signal during the restore waits for it to finish
            state.finish(request, bench)
