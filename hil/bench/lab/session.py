"""One run's hold on a labgrid place: reserve → wait (with progress) → acquire → resolve … release.

A reservation is what queues runs: labgrid allocates a free place whose tags match (a place's name counts as
the tag ``name``, so ``--lg-place X`` reserves ``name=X``) in priority and age order, and holds it for the
reservation until it is cancelled.  So :meth:`LabSession.close` both releases the place and cancels the
reservation — otherwise the next run would wait for this reservation to expire (a minute after its last poll).
"""

from __future__ import annotations

import time
from collections.abc import Callable

from hil.bench.lab.client import LabError, LabgridClient
from hil.bench.lab.resolve import Lab, resolve
from hil.bench.lab.spec import LabSpec

#: progress(state, what to say): "waiting" while queued (about once a second), "acquired"; at the end "released"
#: (the place) and "cancelled" (the reservation)
Progress = Callable[[str, str], None]


class LabSession:
    def __init__(self, spec: LabSpec, *, client: LabgridClient | None = None,
                 progress: Progress | None = None) -> None:
        self.spec = spec
        self.client = client or LabgridClient(spec.address)
        self.progress: Progress = progress or (lambda state, text: None)
        self.token: str | None = None
        self.place: str | None = None
        self.lab: Lab | None = None

    def open(self, station: int = 1) -> Lab:
        """Reserve, wait for the allocation, acquire and resolve.  Anything that goes wrong on the way (a
        KeyboardInterrupt from Ctrl-C or SIGTERM included) releases and cancels what was taken, then raises."""
        try:
            self._refuse_unmatchable()
            token = self.token = self.client.reserve(self.spec.filters)
            started = time.monotonic()
            queued = f"{self.spec.describe()} (reservation {token}, coordinator {self.spec.address})"
            self.progress("waiting", f"queued for {queued} — 0 s")
            self.client.wait(token, lambda state, waited: self.progress(
                "waiting", f"{'queued for' if state == 'waiting' else state} {queued} — {waited:.0f} s"),
                self.spec.wait)
            waited = time.monotonic() - started
            self.place = self.client.acquire(token)
            self.lab = resolve(self.spec, self.client.show(self.place), token=token, station=station, waited=waited)
            self.progress("acquired", f"labgrid place {self.place} acquired after {waited:.1f} s (reservation {token}, "
                                      f"coordinator {self.spec.address}): {self.lab.target}")
            return self.lab
        except BaseException:
            self.close()
            raise

    def close(self) -> list[str]:
        """Release the place and cancel the reservation (each once, each tried); returns what failed."""
        failed: list[str] = []
        if self.place is None and self.token is not None:
            self.place = self._acquired_for(self.token, failed)
        if self.place is not None:
            place, self.place = self.place, None
            try:
                self.client.release(place)
                self.progress("released", f"labgrid place {place} released")
            except LabError as exc:
                failed.append(str(exc))
        if self.token is not None:
            token, self.token = self.token, None
            try:
                self.client.cancel(token)
                self.progress("cancelled", f"labgrid reservation {token} cancelled")
            except LabError as exc:
                failed.append(str(exc))
        return failed

    def _acquired_for(self, token: str, failed: list[str]) -> str | None:
        """The place this reservation acquired, if an acquire was cut short after labgrid had done it."""
        try:
            return next((p.name for p in self.client.places() if p.reservation == token and p.acquired), None)
        except LabError as exc:
            failed.append(str(exc))
            return None

    def _refuse_unmatchable(self) -> None:
        """A reservation no place can ever match would wait forever: say so now, with what the lab has."""
        places = self.client.places()
        wanted = set(self.spec.filters.items())
        if any(wanted <= {*p.tags.items(), ("name", p.name)} for p in places):
            return
        have = "; ".join(f"{p.name} ({' '.join(f'{k}={v}' for k, v in sorted(p.tags.items())) or 'no tags'})"
                         for p in places) or "no places"
        raise LabError(f"no place on coordinator {self.spec.address} matches {self.spec.describe()} "
                       f"(it has: {have})")


__all__ = ["LabSession", "Progress"]
