"""Opening the PLC a command names: one place that knows an ``emulator…`` URL needs the profile's emulator.

Commands use a *direct* transport, not the bench's guarded one: the operator named the PLC and asked for any
write on the command line.  An ``emulator…`` target is built from a bench profile (default
fixtures/benches/emulator.toml, so it has an RTC and temperature modules) and runs in virtual time.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from functools import partial

from hil.bench.profile import Profile, load_profile, plc_target
from hil.core.errors import HilError
from hil.core.journal import Journal
from hil.core.lock import bench_locks, lock_key, plc_key
from hil.core.paths import default_bench
from hil.core.timebase import Timebase, timebase_for
from hil.families.fbs.device.plc import FbsPlc
from hil.families.fbs.identity import read_identity
from hil.families.fbs.plugin import FAMILY as FBS
from hil.families.fbs.recovery import recover
from hil.families.fbs.sim.build import build_emulator
from hil.families.fbs.transport.base import Transport
from hil.families.fbs.transport.factory import open_transport
from hil.io.url import parse_target


@dataclass
class OpenTarget:
    transport: Transport
    timebase: Timebase
    profile: Profile | None  # the bench profile given (or the default one behind an emulator target)

    def plc(self) -> FbsPlc:
        return FbsPlc(self.transport, self.timebase,
                      settle_scans=self.profile.settle_scans if self.profile is not None else 2)


@contextlib.contextmanager
def open_target(url: str | None, bench: str | None = None, *, writing: bool = False) -> Iterator[OpenTarget]:
    """The PLC at ``url`` (default: the profile's target); ``bench`` supplies timeout, time scale, layout.

    A command that writes (``writing``) holds the bench lock while it runs (keyed by the canonical endpoint:
    a test run on the same PLC, however spelt, makes it refuse) and first replays what a dead run left in the
    bench's journal (:meth:`hil.bench.guard.Guard.recover`)."""
    given = _fbs_profile(bench)
    if url is None and given is None:  # as hil run: the default profile's target, the emulator
        given = load_profile(default_bench())
    # a profile's PLC at its station (and a URL the profile does not name refused); a bare URL as it stands
    target = plc_target(given, url) if given is not None else parse_target(url or "")
    profile = given if given is not None or not target.in_process else load_profile(default_bench())
    epoch = dt.datetime.now().replace(microsecond=0)
    factory = partial(build_emulator, profile, epoch) if profile is not None and target.in_process else None
    with contextlib.ExitStack() as stack:
        if writing and not target.in_process:
            _hold_locks(stack, str(target), given.plc_id if given is not None else None)
        transport = stack.enter_context(open_transport(target, emulator_factory=factory,
                                                       timeout=given.timeout if given is not None else None))
        timebase = timebase_for(transport.emulator, epoch, given.time_scale if given is not None else 1.0)
        if writing and not target.in_process:
            recover_first(str(target), transport, timebase, given)
        yield OpenTarget(transport, timebase, profile)


def _fbs_profile(bench: str | None) -> Profile | None:
    """The ``--bench`` profile, refused unless an FBs PLC's: rtc and drift are commands of the FBs family."""
    given = load_profile(bench) if bench else None
    if given is not None and given.plugin.name != FBS.name:
        raise HilError(f"bench {given.name!r} ({bench}) is {given.plugin.a_title} (family {given.family!r}); this "
                       f"command works an FBs PLC (M1952, R4128…). For that bench: hil probe --bench {bench} shows "
                       f"it, hil run --bench {bench} runs its suites")
    return given


def _hold_locks(stack: contextlib.ExitStack[bool | None], target: str, plc_id: str | None) -> None:
    """The bench lock of the endpoint (and of the PLC's identity, where the profile names one) until ``stack``
    closes: a test run on the same PLC, however spelt, makes this command refuse."""
    for lock in bench_locks(target, plc_id):
        stack.enter_context(lock)


def recover_first(target: str, transport: Transport, timebase: Timebase, profile: Profile | None = None) -> None:
    """Replay a journal a dead run left for this PLC (under ``profile``'s allow-list; without one nothing is
    replayed), saying so on stderr; refuse to go on if that failed."""
    journal = Journal(plc_key(target, profile.plc_id if profile is not None else None), endpoint=lock_key(target),
                      plc=read_identity(transport))
    if not journal.pending:
        return
    report = recover(journal, transport, timebase, profile)
    print(report.summary(), file=sys.stderr, flush=True)
    if not report.ok:
        raise HilError(f"{report.summary()} — not going on; `hil restore --show` lists them")
