"""One request policy for every wire: how often a request is tried, the pause between tries, what a failed write
means, and the time one request may take (issue 28; pymodbus's transaction manager keeps the same rules for its
own client).

The rules, the same on FATEK, Modbus and S7:

* a **read** is tried ``1 + retries`` times; between tries the wire recovers (a reconnect, a resynchronisation)
  and pauses :meth:`RequestPolicy.pause` — doubling from ``backoff``, at most 8× it;
* a **write** is sent once: when its reply never came the write may or may not have landed, and it is reported as
  :class:`~hil.core.errors.OutcomeUnknown`, never silently repeated;
* a reply that refuses the request (the PLC answered with an error) is final: it is not a lost request.

A wire supplies only its own parts — one try (send and receive), what counts as a lost request, how to recover —
and :meth:`RequestPolicy.run` applies the rules.  :meth:`RequestPolicy.budget` is the longest a request may take
under them (the soak checks no call runs past it).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, TypeVar

from hil.core.errors import InvalidValue, OutcomeUnknown, ReplyTimeout

T = TypeVar("T")


@dataclass(frozen=True)
class RequestPolicy:
    retries: int = 2
    backoff: float = 0.05

    def __post_init__(self) -> None:
        if self.retries < 0:
            raise InvalidValue(f"retries must be 0 or more, not {self.retries}")
        if self.backoff < 0:
            raise InvalidValue(f"backoff must be 0 s or more, not {self.backoff}")

    def tries(self, write: bool = False) -> int:
        return 1 if write else 1 + self.retries

    def pause(self, attempt: int) -> float:
        """Seconds before try ``attempt + 1``: doubling from ``backoff``, at most 8× it."""
        return self.backoff * min(2 ** (attempt - 1), 8)

    def pauses(self, tries: int) -> float:
        """The pauses between ``tries`` tries, in all."""
        return sum(self.pause(a) for a in range(1, tries))

    def budget(self, one_try: float, write: bool = False) -> float:
        """The longest one request takes when each try takes at most ``one_try`` seconds."""
        tries = self.tries(write)
        return tries * one_try + self.pauses(tries)

    def run(self, what: str, attempt: Callable[[int, int], T], *, write: bool,
            lost: tuple[type[BaseException], ...], recover: Callable[[], None] = lambda: None) -> T:
        """``attempt(n, tries)`` under the rules: an exception in ``lost`` is a request whose reply never came (a
        write's: OutcomeUnknown; a read's: ``recover()``, pause, try again; after the last try ReplyTimeout naming
        every try's failure); anything else (a refusal) goes to the caller as it is."""
        tries = self.tries(write)
        failures: list[str] = []
        started = time.monotonic()
        for n in range(1, tries + 1):
            try:
                return attempt(n, tries)
            except lost as exc:
                if write:
                    raise OutcomeUnknown(f"{what}: {exc} — the write may or may not have been applied (writes "
                                         f"are not repeated)") from None
                failures.append(str(exc))
            recover()
            if n < tries:
                time.sleep(self.pause(n))
        tail = f"; {tries} tries, {time.monotonic() - started:.2f} s in all" if tries > 1 else ""
        raise ReplyTimeout(f"{what}: {failures[-1]}{tail}")


__all__ = ["RequestPolicy"]
