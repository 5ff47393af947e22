"""The scan engine every emulated controller shares: memory, models, and a clock that is virtual (tests) or
wall-driven (``hil emulate``).

Requests from any wire are serviced at a scan boundary, as port 0 of a real FBs answers at the end of a scan:
:meth:`Engine.service` completes one scan and then runs the request against memory, under one lock.  A family
subclasses it with its memory (and whatever a power-on leaves there); the engine knows no family — only that the
memory names its banks (``memory.banks()``: name → a list or bytearray), whose sizes a PLC never changes.
"""

from __future__ import annotations

import collections
import math
import threading
import time
from collections.abc import Callable, Iterable, Sized
from typing import Any, TypeVar

from hil import __version__
from hil.core.errors import EmulatorFault, InvalidValue
from hil.sim.model import Model
from hil.sim.timing import INSTANT, Timing

T = TypeVar("T")


class Engine:
    """A controller in software.  Thread-safe: every entry point takes :attr:`lock`."""

    version = f"hil-emulator {__version__}"
    #: the controller family (the name its plug-in is registered under)
    family = ""

    #: real time: scans run one by one up to this many per tick; a host that falls further behind jumps the rest
    realtime_catch_up = 1000

    def __init__(self, memory: Any, *, scan_time: float = 0.01, models: Iterable[Model[Any]] = (), station: int = 1,
                 seed: int = 0, timing: Timing = INSTANT) -> None:
        if scan_time <= 0:
            raise InvalidValue(f"scan time must be positive, not {scan_time}")
        #: when the models publish (hil.sim.timing); with a range of scan lengths, scan_time is its shortest: the
        #: grid the clock lands jumps on, and the room every "is there a whole scan left" test asks for
        self.timing = timing
        scan_range = timing.scan_range if timing.bench else None
        self._scan_lengths = timing.stream("scan") if scan_range else None
        self._scan_range = scan_range or (scan_time, scan_time)  # (shortest, longest) a drawn scan takes
        self.scan_time = scan_range[0] if scan_range else scan_time
        self.station = station
        self.seed = seed
        self.memory = memory
        #: the memory's banks and their sizes: a model that changes one is a broken emulator (_check_sizes)
        self._banks: list[tuple[str, Sized]] = list(memory.banks().items())
        self._bank_list = [bank for _, bank in self._banks]
        self._sizes = tuple(map(len, self._bank_list))
        self.models: list[Model[Any]] = []
        self.lock = threading.RLock()
        self.stats: collections.Counter[str] = collections.Counter()
        self.now = 0.0  # virtual seconds since power-on
        self.scans = 0
        self.skipped_time = 0.0  # virtual seconds jumped over without scanning (no model needed a scan)
        self.running = True
        self.realtime = False  # True while run_realtime() drives the clock
        #: called with the engine after every scan, with what it left in memory
        self.observers: list[Callable[[Engine], None]] = []
        # Real time: requests wait here for the end of the current scan (run_realtime services them there).
        self._pending: list[_Pending] = []
        self._pending_lock = threading.Lock()
        for model in models:
            self.add_model(model)

    def add_model(self, model: Model[Any]) -> None:
        with self.lock:
            model.power_on(self)
            self._check_sizes(model)
            self.models.append(model)

    def model(self, cls: type[T]) -> T | None:
        """The first model of type ``cls``, if fitted."""
        return next((m for m in self.models if isinstance(m, cls)), None)

    # -- scanning -------------------------------------------------------------------------------------------
    def scan(self) -> None:
        with self.lock:
            self.tick()
            for model in self.models:
                model.scan(self)
            if tuple(map(len, self._bank_list)) != self._sizes:  # (once a scan: a length per bank, under 1 µs)
                self._check_sizes(*self.models)
            self.end_scan()
            for observer in self.observers:
                observer(self)

    def _check_sizes(self, *models: Model[Any]) -> None:
        """A PLC's memory has a fixed size: raise :class:`EmulatorFault` naming the banks resized and the model —
        or, after a scan, the models — that may have done it (a slice assignment of the wrong length inserts or
        drops elements, and every later element moves: the registers a request reads would then be other
        registers, and a suite could pass on them)."""
        resized = [f"{name} from {size} to {len(bank)} elements" for (name, bank), size in zip(self._banks, self._sizes)
                   if len(bank) != size]
        if resized:
            who = " or ".join(f"{m.name!r} ({type(m).__name__})" for m in models)
            raise EmulatorFault(f"the {who} model changed the size of memory: {'; '.join(resized)} — a PLC's memory "
                                f"has a fixed size")

    def tick(self) -> None:
        """The clock of one scan."""
        self.now += self.scan_length()
        self.scans += 1

    def scan_length(self) -> float:
        """How long the coming scan takes: ``scan_time``, or in bench timing a seeded draw from the range."""
        if self._scan_lengths is None:
            return self.scan_time
        return self._scan_lengths.uniform(*self._scan_range)

    def end_scan(self) -> None:
        """What the controller does at the end of every scan after the models (a family may add to it)."""

    def landing(self, due: float, target: float) -> float:
        """Where the next scan lands for an event at ``due``: never before the next scan nor after ``target``."""
        return min(max(due, self.now + self.scan_time), target)

    def land(self, due: float, target: float) -> None:
        """Set the clock so that the next :meth:`tick` lands where :meth:`landing` says, counting the scans jumped
        over (a PLC would have run them) in :attr:`skipped_time`."""
        landing = self.landing(due, target)
        self.skipped_time += landing - self.scan_time - self.now
        self.now = landing - self.scan_time

    @property
    def scans_represented(self) -> int:
        """The scans a PLC would have run by now: those run plus those the engine jumped over (a ladder's scan
        counter shows this; the partial span the real-time clock adds between scans is no scan)."""
        return self.scans + round(self.skipped_time / self.scan_time)

    def service(self, request: Callable[[Any], T]) -> T:
        """Run one request at a scan boundary and return its result.

        Virtual time: one scan, then the request.  Real time (:meth:`run_realtime`): the request waits for the
        end of the scan in progress, as port 0 of a real PLC answers; two requests in a row therefore always have
        at least one whole scan between them, and a client sees what it would see on a bench."""
        with self._pending_lock:
            queued = self.realtime
            if queued:
                pending = _Pending(request)
                self._pending.append(pending)
        if queued:
            return pending.result()
        with self.lock:
            self.scan()
            self.stats["requests"] += 1
            return request(self.memory)

    def _service_pending(self, error: BaseException | None = None) -> None:
        """Answer every request that waited for the scan just completed (real time; caller holds the lock) — with
        ``error``, when that scan failed."""
        with self._pending_lock:
            batch, self._pending = self._pending, []
        for pending in batch:
            self.stats["requests"] += 1
            if error is None:
                pending.run(self.memory)
            else:
                pending.fail(error)

    def advance(self, seconds: float) -> None:
        """Let ``seconds`` of virtual time pass, jumping over spans in which no model needs a scan."""
        if seconds < 0:
            raise InvalidValue(f"cannot advance by a negative time ({seconds} s)")
        with self.lock:
            self.advance_to(self.now + seconds)

    def advance_to(self, target: float, partial: bool = True) -> None:
        """Scan up to ``target``; with ``partial`` False the clock stays at the last scan when ``target`` falls
        between two (real time: a reading taken in that part-scan belongs to the next scan, not to a skipped one)."""
        with self.lock:
            # The scan right after a request is never skipped: a PLC sees a written value on its next scan, so
            # edges (M1952 falling, M1953 rising) and new settings act before any fast-forward jump.
            if self.now + self.scan_time <= target + 1e-9:
                self.scan()
            steps = 0
            if not partial:  # real time: every scan on the scan grid, as a PLC runs them (a jump lands off it)
                while self.now + self.scan_time <= target + 1e-9 and steps < self.realtime_catch_up:
                    steps += 1
                    self.scan()
            while self.now + self.scan_time <= target + 1e-9:
                self.land(min((m.next_event(self.now) for m in self.models), default=math.inf), target)
                self.scan()
            if partial:
                self.now = max(self.now, target)

    def run_realtime(self, stop: threading.Event, time_scale: float = 1.0) -> None:
        """Drive the clock from the wall clock (× ``time_scale``) until ``stop`` is set (for ``hil emulate``).

        The PLC scans on its own, one scan per ``scan_time`` of (scaled) wall time, and services the requests
        that arrived meanwhile at the end of each scan — never with no scan between two of them.  When the host
        falls behind, the missed scans are run (or fast-forwarded, as in virtual time) before the requests."""
        if time_scale <= 0:
            raise InvalidValue(f"time scale must be positive, not {time_scale}")
        with self.lock, self._pending_lock:  # under the lock: a holder of it sees realtime stay as it found it
            self.realtime = True
        start_wall, start_virtual = time.monotonic(), self.now
        period = self.scan_time / time_scale
        try:
            while not stop.is_set():
                with self.lock:
                    before = self.scans
                    self.advance_to(start_virtual + (time.monotonic() - start_wall) * time_scale, partial=False)
                    if self.scans > before:
                        self._service_pending()
                # sleep to the next scan boundary of the wall clock (a request waits at most one scan)
                due = start_wall + (self.now - start_virtual + self.scan_time) / time_scale
                stop.wait(min(max(due - time.monotonic(), 0.0002), period))
        finally:
            with self._pending_lock:
                self.realtime = False
            with self.lock:  # whoever still waits gets the virtual-time service: one scan, then the request — or
                # that scan's error (a broken model stopped the clock): answered, not left waiting for ever
                if self._pending:
                    try:
                        self.scan()
                    except BaseException as exc:
                        self._service_pending(exc)
                        raise
                    self._service_pending()


class _Pending:
    """A request waiting for the end of a scan (real time)."""

    __slots__ = ("request", "done", "value", "error")

    def __init__(self, request: Callable[[Any], Any]) -> None:
        self.request = request
        self.done = threading.Event()
        self.value: Any = None
        self.error: BaseException | None = None

    def run(self, memory: Any) -> None:
        try:
            self.value = self.request(memory)
        except BaseException as exc:  # noqa: BLE001 - handed to the waiting thread, raised there
            self.error = exc
        self.done.set()

    def fail(self, error: BaseException) -> None:
        self.error = error
        self.done.set()

    def result(self) -> Any:
        self.done.wait()
        if self.error is not None:
            raise self.error
        return self.value
