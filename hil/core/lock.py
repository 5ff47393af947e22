"""One harness run per PLC: an OS file lock (``fcntl.flock``) keyed by the PLC.

Two runs against the same PLC would interleave writes and restores and corrupt each other's results.  The key is
the PLC (:func:`plc_key`): the profile's ``[bench] plc_id`` where it names one — then every wire to that PLC (FATEK,
Modbus, another port) shares one lock and one journal — and the canonical endpoint (:func:`lock_key`) always: a run
takes both.  The lock files live in the bench directory every user of the host shares (:func:`lock_dir`, the
bench group's, mode 2770: :func:`hil.core.paths.prepare_bench_dir`; files 0660, opened with O_NOFOLLOW and checked
to be plain files), so two users' runs on one PLC are kept apart too; each file holds who has it — pid, host, user,
start time, command — so a run that cannot get it can say who to ask.  The kernel drops a flock when its process
dies, so a lock left by a crashed run is taken over at once; its leftover holder record is kept as :attr:`stale`.
In-process ``emulator…`` targets need no lock: each run builds its own emulator.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import fcntl
import getpass
import hashlib
import json
import os
import socket
import stat
import sys
import time
from pathlib import Path
from urllib.parse import urlsplit

from hil.core.errors import HilError
from hil.core.paths import (
    BENCH_FILE_MODE,
    bench_dir,
    bench_file_problem,
    prepare_bench_dir,
    share_with_bench,
    user_and_uid,
)
from hil.core.redact import hide_passwords
from hil.core.registry import SCHEMES


class BenchBusy(HilError):
    """Another run holds the bench."""

    def __init__(self, key: str, holder: dict, waited: float) -> None:
        self.key = key
        self.holder = holder
        self.waited = waited
        who = describe_holder(holder) if holder.get("pid") else \
            (" and ".join(holder.get("kernel", ())) or "another process") + " (no holder record)"
        wait = f" (waited {waited:.1f} s; --hil-lock-wait SECONDS waits longer)" if waited else \
            " (pass --hil-lock-wait SECONDS to wait for it)"
        super().__init__(f"bench {key} is in use by {who}{wait}")


def describe_holder(holder: dict) -> str:
    return (f"pid {holder.get('pid')} on {holder.get('host')} (user {holder.get('user')}), since "
            f"{holder.get('started')}, running: {hide_passwords(str(holder.get('command')))}")  # an older hil's record


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
    entry = SCHEMES.get(scheme)
    network = entry.network if entry is not None else scheme.endswith("+tcp")  # also labgrid+tcp:// (a coordinator)
    if entry is not None and not network:  # a serial device or a recording: keyed by its real path
        device = rest.rstrip("/") or "/"
        if not device.startswith("/"):
            device = "/" + device
        return f"serial://{os.path.realpath(device)}"
    if network:  # an RFC 2217 server too: the key is the endpoint it listens on
        return _endpoint_key(scheme, rest, entry.default_port if entry is not None else None)
    return f"{scheme}://{rest.rstrip('/')}"


def _endpoint_key(scheme: str, rest: str, default_port: int | None) -> str:
    """``tcp://ADDRESS:PORT`` for a network URL's ``rest`` (host[:port][/…]): the host resolved, the loopback one."""
    parts = urlsplit(f"{scheme}://{rest.rstrip('/')}")
    host = (parts.hostname or "").lower()
    try:
        port = parts.port or default_port or 0
    except ValueError:
        port = 0
    try:
        infos = socket.getaddrinfo(host, port or None, type=socket.SOCK_STREAM)
        address = str(sorted(infos, key=lambda i: i[0] != socket.AF_INET)[0][4][0])
    except (OSError, IndexError, UnicodeError):
        address = host
    if address in ("::1", "0.0.0.0", "::") or address.startswith("127."):
        address = "127.0.0.1"  # every spelling of this host's loopback is one host
    return f"tcp://{address}:{port}"


def plc_key(target: str, plc_id: str | None = None) -> str:
    """The key of the PLC behind ``target``: ``plc:<plc_id>`` when the profile names it, else the endpoint."""
    return f"plc:{plc_id}" if plc_id else lock_key(target)


#: the bench directory (``$HIL_LOCK_DIR``), created and checked by :func:`shared_dir`
lock_dir = bench_dir
#: create the bench directory (mode 2770, the bench group's) or refuse one not safe to share
shared_dir = prepare_bench_dir


class BenchLock:
    def __init__(self, target: str, directory: Path | None = None, *, key: str | None = None) -> None:
        self.key = key or lock_key(target)
        self.name = target if self.key == target else f"{target} ({'PLC' if key else 'endpoint'} {self.key})"
        digest = hashlib.sha256(self.key.encode()).hexdigest()[:16]
        self.directory = Path(directory) if directory else lock_dir()
        self.path = self.directory / f"bench-{digest}.lock"
        self.stale: dict | None = None  # the record a dead holder left behind, if we took over its lock
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def fileno(self) -> int | None:
        """The open lock file while held (a run with lanes lends it to its workers: :mod:`hil.core.lease`)."""
        return self._fd

    def acquire(self, wait: float = 0.0, poll: float = 0.1) -> BenchLock:
        """Take the lock, waiting up to ``wait`` seconds; raise :class:`BenchBusy` naming the holder."""
        if self._fd is not None:
            return self
        shared_dir(self.directory)
        fd = self._open()
        started = time.monotonic()
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                waited = time.monotonic() - started
                if waited >= wait:
                    holder = _read(fd) or {"kernel": [describe_process(pid) for pid in kernel_holders(fd)]}
                    os.close(fd)
                    raise BenchBusy(self.name, holder, waited if wait else 0.0) from None
                time.sleep(min(poll, max(0.0, wait - waited)))
        previous = _read(fd)
        if previous:  # a clean release empties the file: a record means its holder died holding the lock
            self.stale = previous
        record = {"pid": os.getpid(), "host": socket.gethostname(), "user": _user(),
                  "started": dt.datetime.now().isoformat(timespec="seconds"),
                  "command": hide_passwords(" ".join(sys.argv)) or sys.executable, "target": self.key}
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps(record).encode(), 0)
            os.fsync(fd)
        except OSError:
            pass  # another user's lock file opened read-only: the lock is held, only the holder record is missing
        self._fd = fd
        return self

    def _open(self) -> int:
        return open_lock_file(self.path, "bench lock")

    def release(self) -> None:
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        try:
            # opened read-only (another user's file): there is no record of ours to clear
            with contextlib.suppress(OSError):
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

    def __enter__(self) -> BenchLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()


def open_lock_file(path: Path, what: str) -> int:
    """A lock file in the bench directory: created readable and writable by the bench group (each user records
    themselves in it), opened without following a link, and checked (:func:`hil.core.paths.bench_file_problem`)."""
    flags = os.O_NOFOLLOW | os.O_CLOEXEC
    try:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL | flags, BENCH_FILE_MODE)
            share_with_bench(fd, path.parent)
        except FileExistsError:
            try:
                fd = os.open(path, os.O_RDWR | flags)
            except PermissionError:
                fd = os.open(path, os.O_RDONLY | flags)  # flock needs no write access
    except OSError as exc:
        raise HilError(_unopenable(path, what, exc)) from None
    info = os.fstat(fd)
    if info.st_uid == os.getuid() and stat.S_ISREG(info.st_mode) and stat.S_IMODE(info.st_mode) != BENCH_FILE_MODE:
        share_with_bench(fd, path.parent)  # ours from an earlier hil (0666, 0600): the bench group's from now on
        info = os.fstat(fd)
    problem = bench_file_problem(path, info)
    if problem:
        os.close(fd)
        raise HilError(f"{what} {problem}")
    return fd


def _unopenable(path: Path, what: str, exc: OSError) -> str:
    """Why a lock file cannot be opened, and what to do: a planted link, or another user's file closed to us."""
    if os.path.islink(path):
        return (f"{what} {path} is a symbolic link — refusing to follow it (someone planted it; remove it after "
                f"checking where it points)")
    try:
        info = os.lstat(path)
    except OSError:
        return f"cannot open the {what} {path}: {exc}"
    owner = user_and_uid(info.st_uid)
    return (f"cannot open the {what} {path} (mode {stat.S_IMODE(info.st_mode):04o}, owner {owner}): {exc} — the "
            f"bench group must be able to read and write it: ask {owner} to chmod 0660 it (or remove it while no "
            f"run uses the bench)")


# -- who holds a lock, as the kernel says ---------------------------------------------------------------------------
def kernel_holders(fd: int) -> list[int]:
    """The pids holding a flock on ``fd``'s file, from ``/proc/locks`` (empty where it cannot be read): the truth
    even where a holder wrote no record (a serial line's lock, another user's read-only file)."""
    info = os.fstat(fd)
    device = f"{os.major(info.st_dev):02x}:{os.minor(info.st_dev):02x}:{info.st_ino}"
    try:
        with open("/proc/locks") as locks:
            lines = locks.read().splitlines()
    except OSError:
        return []
    pids = []
    for line in lines:
        fields = line.split()
        if len(fields) >= 6 and fields[1] == "FLOCK" and fields[5] == device:  # not a waiter's "-> FLOCK"
            pids.append(int(fields[4]))
    return pids


def parent_of(pid: int) -> int | None:
    """``pid``'s parent, from /proc (None where it cannot be read: gone, or another system)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        return int(stat.rsplit(")", 1)[1].split()[1])  # (after the command's parenthesis: state, then the parent)
    except (OSError, ValueError, IndexError):
        return None


def describe_process(pid: int) -> str:
    """``pid 1234 of user bob (uid 1001): python3 -m hil probe …`` from /proc (the bare pid where it cannot be
    read)."""
    try:
        raw = Path(f"/proc/{pid}/cmdline").read_bytes()
        owner = user_and_uid(os.stat(f"/proc/{pid}").st_uid)
    except OSError:
        return f"pid {pid}"
    command = " ".join(part.decode(errors="replace") for part in raw.split(b"\0") if part)
    return f"pid {pid} of user {owner}: {hide_passwords(command) or '?'}"


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


__all__ = ["BenchLock", "BenchBusy", "describe_holder", "describe_process", "kernel_holders", "lock_dir",
           "lock_key", "open_lock_file", "plc_key", "shared_dir"]


def bench_locks(target: str, plc_id: str | None) -> list[BenchLock]:
    """The locks a bench is held by, in the order they are taken: its endpoint's and, where the profile names the
    PLC (``plc_id``), the PLC's own — one lock per PLC, whatever wire reaches it (:func:`plc_key`)."""
    return [BenchLock(target)] + ([BenchLock(target, key=plc_key(target, plc_id))] if plc_id else [])
