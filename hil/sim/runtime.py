"""One background asyncio loop that hosts every emulator server of this process.

Servers (ours and pymodbus's) are asyncio-based and must be created inside a running loop; the harness itself is
synchronous, so the loop lives in a daemon thread and sync code hands it coroutines.
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable, Coroutine
from typing import Any, TypeVar

T = TypeVar("T")


class LoopThread:
    _shared: LoopThread | None = None
    _shared_lock = threading.Lock()

    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._run, name="hil-emulator-loop", daemon=True)
        self._thread.start()

    @property
    def alive(self) -> bool:
        """Its thread still runs the loop."""
        return self._thread.is_alive()

    @classmethod
    def shared(cls) -> LoopThread:
        with cls._shared_lock:
            if cls._shared is None or not cls._shared.alive:
                cls._shared = cls()
            return cls._shared

    @property
    def thread(self) -> threading.Thread:
        return self._thread

    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        self.loop.run_forever()

    def run(self, coro: Coroutine[Any, Any, T], timeout: float = 10.0) -> T:
        """Run ``coro`` on the loop and wait for its result."""
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(timeout)


class ServerHandle:
    """A running emulator server: what kind, where a client connects, and how to stop it (idempotent)."""

    #: the wire-fault plan its replies go through (a :class:`~hil.sim.wire_faults.WireFaults`), or None
    faults: Any = None
    line: Any = None  # a pty wire's served line (its pace and byte counts), else None
    ptys: Any = None  # a pty wire's pair (byte counters for tests), else None

    def __init__(self, kind: str, address: str, stop: Callable[[], None]) -> None:
        self.kind = kind  # the wire's name: "fatek-tcp", "fatek-serial", "modbus-tcp", "modbus-rtu", …
        self.address = address  # "127.0.0.1:40123" or a pty path such as "/dev/pts/7"
        self._stop = stop
        self.stopped = False

    def stop(self) -> None:
        if not self.stopped:
            self.stopped = True
            self._stop()

    def __repr__(self) -> str:
        return f"<ServerHandle {self.kind} {self.address}>"
