"""One harness run per bench: an OS file lock (``fcntl.flock``) keyed by the target.

Two runs against the same PLC would interleave writes and restores and corrupt each other's results.  The lock
file lives in a per-user directory (:func:`lock_dir`, mode 0700, opened with O_NOFOLLOW), is keyed by the
bench's canonical endpoint (:func:`lock_key`), and holds who has it — pid, host, user, start time,
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
    """What identifies a bench, whatever the URL's spelling: its canonical endpoint.

    ``FATEK+TCP://LocalHost/`` and ``fatek+tcp://127.0.0.1:500`` are one PLC: the scheme is lower-cased, the host
    resolved to its address (the first the resolver gives), the scheme's default port filled in, a trailing ``/``
    and the query ignored.  A serial device is named by its real path (``/dev/serial/by-id/…`` → ``/dev/ttyUSB0``).
    Different protocols to one host:port are still one endpoint: the key is ``tcp://ADDRESS:PORT``.
    """
    text = target.strip()
    scheme, sep, rest = text.partition("://")
    scheme = scheme.lower()
    if not sep:
        return scheme
    rest = rest.partition("?")[0].partition("#")[0]
    if scheme.endswith(("serial", "rtu")) or scheme.startswith("replay"):
        device = rest.rstrip("/") or "/"
        if not device.startswith("/"):
            device = "/" + device
        return f"serial://{os.path.realpath(device)}"
    from hil.core.ports import DEFAULT_PORTS, NETWORK_SCHEMES
    if scheme.endswith(NETWORK_SCHEMES):  # an RFC 2217 server too: the key is the endpoint it listens on
        from urllib.parse import urlsplit
        parts = urlsplit(f"{scheme}://{rest.rstrip('/')}")
        host = (parts.hostname or "").lower()
        try:
            port = parts.port or DEFAULT_PORTS.get(scheme, 0)
        except ValueError:
            port = 0
        try:
            infos = socket.getaddrinfo(host, port or None, type=socket.SOCK_STREAM)
            address = sorted(infos, key=lambda i: i[0] != socket.AF_INET)[0][4][0]
        except (OSError, IndexError, UnicodeError):
            address = host
        if address in ("::1", "0.0.0.0", "::") or address.startswith("127."):
            address = "127.0.0.1"  # every spelling of this host's loopback is one host
        return f"tcp://{address}:{port}"
    return f"{scheme}://{rest.rstrip('/')}"


def lock_dir() -> Path:
    """A per-user directory nobody else can write (mode 0700): ``$HIL_LOCK_DIR``, else
    ``$XDG_RUNTIME_DIR/hil``, else ``~/.cache/hil/locks``."""
    given = os.environ.get("HIL_LOCK_DIR")
    if given:
        return Path(given)
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime and os.path.isdir(runtime):
        return Path(runtime) / "hil"
    cache = os.environ.get("XDG_CACHE_HOME")
    return (Path(cache) if cache else Path.home() / ".cache") / "hil" / "locks"


def _private_dir(directory: Path) -> None:
    directory.mkdir(parents=True, exist_ok=True, mode=0o700)
    info = os.lstat(directory)
    import stat
    if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid():
        raise HilError(f"lock directory {directory} is not a directory owned by you — refusing to use it")
    if info.st_mode & 0o077:
        os.chmod(directory, 0o700)


class BenchLock:
    def __init__(self, target: str, directory: Path | None = None) -> None:
        self.key = lock_key(target)
        self.name = target if lock_key(target) == target else f"{target} (endpoint {self.key})"
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
        _private_dir(self.directory)
        try:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
        except OSError as exc:
            if os.path.islink(self.path):
                raise HilError(f"bench lock {self.path} is a symbolic link — refusing to follow it (someone planted "
                               f"it; remove it after checking where it points)") from None
            raise HilError(f"cannot open the bench lock {self.path}: {exc}") from None
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
                    raise BenchBusy(self.name, holder, waited if wait else 0.0) from None
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
            fd = os.open(self.path, os.O_RDONLY | os.O_NOFOLLOW)
        except OSError:
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
