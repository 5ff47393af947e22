"""Wire faults for the emulator's servers: what a noisy serial line or a flaky gateway does to a reply.

One :class:`WireFaults` plan (a seeded ``random.Random`` with per-kind probabilities, and/or a scripted queue)
is consulted by a server each time it sends a reply.  Every kind but ``echo`` keeps replies **in order**, as a real
slave that handles one request at a time must — so a client can always resynchronise:

============ ====================================================================================================
``drop``      the reply is never sent (the request was executed: a write may have landed)
``delay``     the reply is held ``delay`` seconds (set it past the client's timeout), later replies queue behind
``corrupt``   the checksum (FATEK), CRC (Modbus RTU) or MBAP protocol id (Modbus/TCP) is made wrong
``split``     the reply goes out in 2–4 pieces with ``split_gap`` seconds between them
``late``      the reply is withheld, then sent just before the next reply — after the client gave up on it
``duplicate`` the reply is sent twice
``echo``      the reply is sent, then sent again 1–50 ms later (a delayed duplicate: it may land after the next
              request, where a client without transaction ids would take it for that request's answer); like
              every frame it goes out whole — one due while a split reply is on its way follows that reply
``garbage``   1–16 random bytes go out before the reply
``close``     the connection is closed instead of replying (on a pty: no reply, as a line cannot hang up)
============ ====================================================================================================

Counted in :attr:`WireFaults.injected` by kind (and ``replies`` for every reply seen).
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import random
import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

from hil.core.errors import InvalidValue

KINDS = ("drop", "delay", "corrupt", "split", "late", "duplicate", "echo", "garbage", "close")

Corrupt = Callable[[bytes, random.Random], bytes]


@dataclass
class WireFaults:
    """Which fault (if any) hits each reply.  ``rates``: probability per kind (sum ≤ 1); ``script``: kinds (or
    None = no fault) used first, one per reply, before the random rates apply."""

    rates: dict[str, float] = field(default_factory=dict)
    seed: int = 0
    delay: float = 1.0  # s a "delay" holds a reply
    split_gap: float = 0.005  # s between the pieces of a "split" reply
    script: list[str | None] = field(default_factory=list)

    def __post_init__(self) -> None:
        check_rates(self.rates)
        for kind in self.script:
            if kind is not None and kind not in KINDS:
                raise InvalidValue(f"unknown wire fault {kind!r} (known: {', '.join(KINDS)})")
        if self.delay < 0 or self.split_gap < 0:
            raise InvalidValue("delay and split_gap must be ≥ 0")
        self.random = random.Random(self.seed)
        self.queue: collections.deque[str | None] = collections.deque(self.script)
        self.injected: collections.Counter[str] = collections.Counter()
        self.replies = 0
        self.enabled = True
        self._lock = threading.Lock()

    @classmethod
    def from_config(cls, table: dict[str, Any]) -> WireFaults:
        """From a profile's ``[wire_faults]`` table (already validated by :func:`hil.bench.profile`)."""
        rates = {k: float(v) for k, v in table.items() if k in KINDS}
        return cls(rates=rates, seed=int(table.get("seed", 0)),
                   delay=float(table.get("delay_seconds", 1.0)),
                   split_gap=float(table.get("split_gap", 0.005)), script=list(table.get("script", [])))

    def push(self, *kinds: str | None) -> None:
        """Script the next replies: ``push("drop", None, "late")`` drops one, passes one, delays the third."""
        for kind in kinds:
            if kind is not None and kind not in KINDS:
                raise InvalidValue(f"unknown wire fault {kind!r} (known: {', '.join(KINDS)})")
        with self._lock:
            self.queue.extend(kinds)

    def choose(self) -> str | None:
        """The fault for the next reply (counted), or None."""
        with self._lock:
            self.replies += 1
            if self.queue:
                kind = self.queue.popleft()
            elif not self.enabled or not self.rates:
                kind = None
            else:
                kind, x = None, self.random.random()
                for name in KINDS:
                    x -= self.rates.get(name, 0.0)
                    if x < 0:
                        kind = name
                        break
            if kind is not None:
                self.injected[kind] += 1
            return kind


def check_rates(rates: dict[str, float]) -> None:
    for kind, p in rates.items():
        if kind not in KINDS:
            raise InvalidValue(f"unknown wire fault {kind!r} (known: {', '.join(KINDS)})")
        if not 0.0 <= p <= 1.0:
            raise InvalidValue(f"probability of {kind} must be 0–1, not {p}")
    if sum(rates.values()) > 1.0 + 1e-9:
        raise InvalidValue(f"fault probabilities add up to {sum(rates.values()):g}, more than 1")


# -- corruption per protocol (a family's own protocol brings its own: FaultySender's corrupt) ---------------------
def corrupt_crc(reply: bytes, rng: random.Random) -> bytes:
    """Flip bits of the CRC (Modbus RTU)."""
    if len(reply) < 2:
        return reply
    return reply[:-1] + bytes([reply[-1] ^ rng.randint(1, 255)])


def corrupt_mbap(reply: bytes, rng: random.Random) -> bytes:
    """Make the MBAP protocol id non-zero (Modbus/TCP has no checksum of its own; TCP already has one)."""
    if len(reply) < 4:
        return reply
    return reply[:2] + bytes([rng.randint(1, 255), rng.randint(0, 255)]) + reply[4:]


# -- the sender that applies a plan ----------------------------------------------------------------------------------
class FaultySender:
    """Sends one connection's replies in order through a fault plan.  Create and use on the server's loop.

    ``write(data)`` puts bytes on the wire; ``close()`` hangs up (None: the wire cannot, "close" = no reply).
    Without a plan (``faults=None``) a reply is written at once, exactly as before.
    """

    def __init__(self, faults: WireFaults | None, write: Callable[[bytes], None], corrupt: Corrupt,
                 close: Callable[[], None] | None = None) -> None:
        self.faults = faults
        self.write = write
        self.corrupt = corrupt
        self.hangup = close
        self.held: list[bytes] = []  # "late" replies waiting for the next one
        self.splitting = False  # a split reply is on its way: an echo due now waits for its last piece
        self.echoes: list[bytes] = []  # echoes that came due meanwhile
        self.closed = False
        self._queue: asyncio.Queue[bytes] | None = None
        self._task: asyncio.Task | None = None

    def send(self, reply: bytes) -> None:
        if self.closed:
            return
        if self.faults is None:
            self.write(reply)
            return
        if self._queue is None:
            self._queue = asyncio.Queue()
            self._task = asyncio.get_running_loop().create_task(self._run())
        self._queue.put_nowait(reply)

    def send_all(self, replies: Iterable[bytes]) -> None:
        for reply in replies:
            self.send(reply)

    def stop(self) -> None:
        self.closed = True
        if self._task is not None:
            self._task.cancel()

    async def _run(self) -> None:
        assert self._queue is not None and self.faults is not None
        while not self.closed:
            reply = await self._queue.get()
            with contextlib.suppress(OSError, RuntimeError):  # the peer went away: nothing to answer
                await self._one(reply)

    def _echo(self, reply: bytes) -> None:
        if self.splitting:  # a sender writes whole frames: never inside another one
            self.echoes.append(reply)
        elif not self.closed:
            with contextlib.suppress(OSError, RuntimeError):  # the peer went away: nothing to echo to
                self.write(reply)

    async def _one(self, reply: bytes) -> None:
        faults = self.faults
        assert faults is not None
        kind = faults.choose()
        rng = faults.random
        if kind == "late":
            self.held.append(reply)
            return
        for stale in self.held:  # what the client gave up on goes out first: replies stay in order
            self.write(stale)
        self.held.clear()
        if kind == "drop":
            return
        if kind == "close":
            if self.hangup is not None:
                self.closed = True
                self.hangup()
            return
        if kind == "delay":
            await asyncio.sleep(faults.delay)
        elif kind == "corrupt":
            reply = self.corrupt(reply, rng)
        elif kind == "garbage":
            self.write(bytes(rng.randrange(256) for _ in range(rng.randint(1, 16))))
        elif kind == "duplicate":
            reply = reply + reply
        elif kind == "echo":
            asyncio.get_running_loop().call_later(rng.uniform(0.001, 0.050), self._echo, reply)
        elif kind == "split" and len(reply) > 1:
            cuts = sorted(rng.sample(range(1, len(reply)), min(len(reply) - 1, rng.randint(1, 3))))
            pieces = [reply[a:b] for a, b in zip([0] + cuts, cuts + [len(reply)])]
            self.splitting = True
            try:
                for piece in pieces[:-1]:
                    self.write(piece)
                    await asyncio.sleep(faults.split_gap)
            finally:
                self.splitting = False
            reply = pieces[-1]
        self.write(reply)
        for echo in self.echoes:
            self.write(echo)
        self.echoes.clear()


__all__ = ["KINDS", "WireFaults", "FaultySender", "check_rates", "corrupt_crc", "corrupt_mbap"]
