"""PlcCore: one FBs PLC's I/O and time, and the scan discipline every procedure keeps (settle after a write,
read what a whole scan after it left) — what the areas (:mod:`.rtc`, :mod:`.temperature`, :mod:`.pid`) stand on,
below :class:`hil.families.fbs.device.plc.FbsPlc`, which holds them."""

from __future__ import annotations

from hil.core.errors import HilError
from hil.core.timebase import Timebase
from hil.families.fbs.transport.base import PlcStatus, Transport


class PlcCore:
    """One FBs PLC reached through ``transport`` (normally the guarded transport of the bench), waiting through
    ``timebase`` (the bench's time)."""

    def __init__(self, transport: Transport, timebase: Timebase, *, settle_scans: int = 2,
                 scan_counter: str | None = None, answers_at_scan_end: bool = False) -> None:
        self.io = transport
        self.time = timebase
        self.settle_scans = settle_scans
        #: the bench ladder's scan counter ([bench] scan_counter): a word it adds 1 to every scan
        self.scan_counter = scan_counter
        #: [bench] answers_at_scan_end: settles trust port 0's rule, the scan counter is left to what counts scans
        self.answers_at_scan_end = answers_at_scan_end

    def status(self) -> PlcStatus:
        return self.io.status()

    @property
    def _proving_counter(self) -> str | None:
        """The ladder's counter when a settle proves its scans with it; None when it relies on port 0's rule."""
        return None if self.answers_at_scan_end else self.scan_counter

    @property
    def _proves_scans(self) -> bool:
        return self._proving_counter is not None

    def settle(self, scans: int | None = None) -> None:
        """Make sure the PLC has completed whole scans since our last write.

        With a ladder scan counter the PLC proves it: the counter is read after the write and again until it has
        gone up by ``scans`` + 1 (the scan in progress at the first read may have begun before the write landed,
        e.g. on a port that answers at once; the one after it cannot have).  Without one — or where the profile
        says the wire reaches a port that answers at the end of a scan (``[bench] answers_at_scan_end``: ports 0,
        1, 3, 4) — port 0's rule: each round trip spans at least one scan, so a few cheap status requests; the
        reads already answered since the write are such round trips too, and count.
        """
        n = self.settle_scans if scans is None else scans
        if self._proves_scans:
            if n > 0:
                self.await_scans(n)
            return
        for _ in range(max(0, n - self.io.reads_since_write)):
            self.io.status()

    def settle_before_request(self) -> None:
        """Settle when the procedure's next step is itself a request (a read of the effect, the next write).

        On port 0 that request is serviced at the end of a scan after the write too, so it counts as one of the
        ``settle_scans``: one status round trip fewer.  With a scan counter, one whole scan proved instead."""
        if self._proves_scans:
            self.await_scans(1)
            return
        self.settle(max(0, self.settle_scans - 1))

    def read_settled(self, names: list[str]) -> list[int]:
        """:meth:`settle_before_request` and then a read of ``names``, in one round trip fewer: with a scan
        counter, the counter is read in the same frame as ``names`` (one frame is one scan), and the read repeated
        until it shows the whole scan after the last write done — its values are then from after it."""
        counter = self._proving_counter
        if counter is None or not names:
            self.settle_before_request()
            return self.io.read_many(names)
        first = self.read_scan_counter()
        started = self.time.now()
        while True:
            *values, value = self.io.read_many([*names, counter])
            if (value - first) % 65536 >= 2:  # as await_scans(1): the scan begun after `first` has ended
                return values
            self._check_counter_moves(first, value, started, 5.0)

    def read_scan_counter(self) -> int:
        if self.scan_counter is None:
            raise HilError("this bench declares no ladder scan counter ([bench] scan_counter)")
        return self.io.read(self.scan_counter)

    def await_scans(self, scans: int = 1, timeout: float = 5.0) -> int:
        """Poll the ladder's scan counter until ``scans`` whole scans have begun and ended after this call began;
        return the counter's last value.  Raises when it does not move within ``timeout`` bench seconds."""
        first = self.read_scan_counter()
        started = self.time.now()
        while True:
            value = self.read_scan_counter()
            if (value - first) % 65536 >= scans + 1:
                return value
            self._check_counter_moves(first, value, started, timeout)

    def _check_counter_moves(self, first: int, value: int, started: float, timeout: float) -> None:
        if self.time.now() - started > timeout:
            raise HilError(f"the scan counter {self.scan_counter} stayed at {value} (from {first}) for "
                           f"{timeout} s: is its rung in the bench ladder (fixtures/ladder.md), the PLC in RUN?")


__all__ = ["PlcCore"]
