"""One harness run per bench: an OS file lock (``fcntl.flock``) keyed by the target.

Two runs against the same PLC would interleave writes and restores and corrupt each other's results.  The lock
file lives in ``$HIL_LOCK_DIR`` (default ``<tmp>/hil-locks``) and holds who has it — pid, host, user, start time,
command — so a run that cannot get it can say who to ask.  The kernel drops a flock when its process dies, so
a lock left by a crashed run is taken over at once; its leftover holder record is kept as :attr:`stale`.
In-process ``emulator…`` targets need no lock: each run builds its own emulator.
"""

from __future__ import annotations

import datetime as dt
import fcntl
import getpass
import hashlib
import json
import os
import socket
import sys
import tempfile
import time
from pathlib import Path

from hil.core.errors import HilError


class BenchBusy(HilError):
    """Another run holds the bench."""

    def __init__(self, key: str, holder: dict, waited: float) -> None:
        self.key = key
        self.holder = holder
        self.waited = waited
        who = describe_holder(holder) if holder else "another process (no holder record)"
        wait = f" (waited {waited:.1f} s; --hil-lock-wait SECONDS waits longer)" if waited else \
            " (pass --hil-lock-wait SECONDS to wait for it)"
        super().__init__(f"bench {key} is in use by {who}{wait}")


def describe_holder(holder: dict) -> str:
    return (f"pid {holder.get('pid')} on {holder.get('host')} (user {holder.get('user')}), since "
            f"{holder.get('started')}, running: {holder.get('command')}")


def lock_key(target: str) -> str:
    """What identifies a bench: the target URL, with a serial device resolved to its real path."""
    scheme, sep, rest = target.partition("://")
    if sep and scheme.endswith(("serial", "rtu")):
        device, q, query = rest.partition("?")
        return f"{scheme}://{os.path.realpath(device)}"
    return target.partition("?")[0]


def lock_dir() -> Path:
    return Path(os.environ.get("HIL_LOCK_DIR") or Path(tempfile.gettempdir()) / "hil-locks")


class BenchLock:
    def __init__(self, target: str, directory: Path | None = None) -> None:
        self.key = lock_key(target)
        digest = hashlib.sha256(self.key.encode()).hexdigest()[:16]
        self.directory = Path(directory) if directory else lock_dir()
        self.path = self.directory / f"bench-{digest}.lock"
        self.stale: dict | None = None  # the record a dead holder left behind, if we took over its lock
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def acquire(self, wait: float = 0.0, poll: float = 0.1) -> "BenchLock":
        """Take the lock, waiting up to ``wait`` seconds; raise :class:`BenchBusy` naming the holder."""
        if self._fd is not None:
            return self
        self.directory.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
        started = time.monotonic()
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                waited = time.monotonic() - started
                if waited >= wait:
                    holder = _read(fd)
                    os.close(fd)
                    raise BenchBusy(self.key, holder, waited if wait else 0.0) from None
                time.sleep(min(poll, max(0.0, wait - waited)))
        previous = _read(fd)
        if previous:  # a clean release empties the file: a record means its holder died holding the lock
            self.stale = previous
        record = {"pid": os.getpid(), "host": socket.gethostname(), "user": _user(),
                  "started": dt.datetime.now().isoformat(timespec="seconds"),
                  "command": " ".join(sys.argv) or sys.executable, "target": self.key}
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps(record).encode(), 0)
        os.fsync(fd)
        self._fd = fd
        return self

    def release(self) -> None:
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        try:
            os.ftruncate(fd, 0)
            fcntl.flock(fd, fcntl.LOCK_UN)
        finally:
            os.close(fd)

    def holder(self) -> dict:
        """The record in the lock file (whoever holds it now, or a dead holder's)."""
        try:
            fd = os.open(self.path, os.O_RDONLY)
        except FileNotFoundError:
            return {}
        try:
            return _read(fd)
        finally:
            os.close(fd)

    def __enter__(self) -> "BenchLock":
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()


def _read(fd: int) -> dict:
    try:
        raw = os.pread(fd, 4096, 0)
        return json.loads(raw) if raw.strip() else {}
    except (OSError, ValueError):
        return {}


def _user() -> str:
    try:
        return getpass.getuser()
    except (KeyError, OSError):
        return str(os.getuid())


__all__ = ["BenchLock", "BenchBusy", "lock_key", "lock_dir", "describe_holder"]
