"""One serial line taken in turns by several processes' clients: the lanes of one run on a PLC's port
(:mod:`hil.plugin.lanes`).

A FATEK master waits for each reply, so two clients on one line must take turns by whole exchanges: a request, its
reply and whatever the client does before it trusts the reply (the fence's loop-back, the retries and the
resynchronising loop-backs after a timeout).  :class:`SharedLine` is the client's lock: this process's threads take
turns on a re-entrant thread lock, other processes on an OS file lock (``flock``) on a file named by the device's
real path in the shared lock directory (:func:`hil.core.lock.lock_dir`).  The outermost hold takes the file lock;
an inner one (a section of several requests no other lane may split, :meth:`hil.core.link.Link.exclusive`) only
counts.

What passes from one holder to the next is whether a late reply may still be on its way (the client's ``dirty``).
The mark is set while the line is held and left as the holder leaves it on release, so a holder that gave up on a
reply — or was killed in the middle of an exchange — makes the next one resynchronise before its request rather
than take another lane's late reply for its own answer.

Turns are not equal in a run with lanes: a process is in the foreground (the main lane) or the background (its
named lanes), as :func:`run_in_background` says; a process that says neither takes plain turns.  A background
client takes the line only while no foreground client wants it: a foreground one holds a shared lock on a second
file (``….want``) from before it asks for the line until :data:`LINGER` after it let go of it (so across
back-to-back exchanges), and a background one must take that file's lock exclusively before it asks.  So the main
lane runs as it would alone but for a background turn already on the line when it asks (one frame, tens of
milliseconds at 9600 bit/s, or one procedure that holds the line: an RTC set's five), and the background lanes
fill the line's idle time: the main lane's waits for the PLC.

A wait for the line is bounded (:data:`WAIT`, ``$HIL_LINE_WAIT`` seconds): a process that keeps it longer — another
user's run, a stuck tool — is named (pid, user, command, from the kernel's lock table) instead of hanging the
command with no output.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import threading
import time
from collections.abc import Callable

from hil.core.errors import TransportError
from hil.core.lock import describe_process, kernel_holders, lock_dir, open_lock_file, parent_of, shared_dir

#: the mark's two values (one byte at the start of the file)
_SUSPECT, _CLEAN = b"1", b"0"
_background: bool | None = None  # None: plain turns (no lanes); False: the foreground; True: the background
#: how long a foreground client keeps the line wanted after an exchange: longer than a client takes between two
#: back-to-back exchanges (a decode and the next encode), shorter than a poll's pause
LINGER = 0.03
#: how long a client waits for the line before it names the holder and gives up: far longer than any holder of a
#: run keeps it (an exchange with its retries, a section of several requests), far shorter than a user's patience
WAIT = 30.0
WAIT_ENV = "HIL_LINE_WAIT"
#: the pause between two tries while the line is held: short against an exchange (tens of milliseconds at
#: 9600 bit/s), so a turn passes at about the speed the kernel's own wait would give it
POLL = 0.002


def line_wait() -> float:
    """The wait for the line, in seconds: ``$HIL_LINE_WAIT``, else :data:`WAIT`."""
    given = os.environ.get(WAIT_ENV, "").strip()
    if not given:
        return WAIT
    try:
        value = float(given)
    except ValueError:
        value = -1.0
    if not value > 0:
        raise TransportError(f"{WAIT_ENV}={given}: want a number of seconds greater than 0")
    return value


def run_in_background(yes: bool = True) -> None:
    """This process's clients of a shared line take it only while no foreground process's client wants it (``yes``),
    or are the foreground and keep it wanted across their back-to-back exchanges (``not yes``)."""
    global _background
    _background = yes


class SharedLine:
    """The lock of one client on the serial line ``device``.

    ``taken(suspect)`` is called once the line is this client's, with whether the previous holder left a late reply
    possible (or died holding the line); ``leaving()`` as it lets go, and says whether one is possible now.
    ``background``: this client's turn, True or False (None: the process's, :func:`run_in_background`)."""

    def __init__(self, device: str, *, taken: Callable[[bool], None], leaving: Callable[[], bool],
                 background: bool | None = None) -> None:
        self.device = os.path.realpath(device)
        directory = lock_dir()
        shared_dir(directory)
        self.path = directory / f"line-{hashlib.sha256(self.device.encode()).hexdigest()[:16]}.lock"
        self._fd = open_lock_file(self.path, "serial line lock")
        self._want = open_lock_file(self.path.with_suffix(".want"), "serial line lock")
        self._thread = threading.RLock()
        self._depth = 0  # holds by the owning thread; the file lock is held while > 0
        self._closing = False  # closed while held: the file goes when the last hold ends
        self._taken = taken
        self._leaving = leaving
        self._background: bool | None = None  # how the hold in progress was taken
        self._turn = background
        self._wanting = False  # the shared lock on the want file is held (a foreground client, until LINGER after)
        self._unwant_timer: threading.Timer | None = None
        self._wait = line_wait()

    def __enter__(self) -> SharedLine:
        self._thread.acquire()
        if self._depth == 0:
            if self._fd < 0:
                self._thread.release()
                raise TransportError(f"the serial line {self.device} was closed")
            try:
                self._take()
                suspect = os.pread(self._fd, 1, 0) == _SUSPECT
                _mark(self._fd, _SUSPECT)  # until a clean release says otherwise (a holder may die mid-exchange)
            except BaseException as exc:  # a signal while waiting too: nothing of the line stays held
                fcntl.flock(self._fd, fcntl.LOCK_UN)
                self._unwant()
                self._thread.release()
                if isinstance(exc, OSError):
                    raise TransportError(f"cannot take the serial line {self.device} in turn ({self.path}): "
                                         f"{exc}") from None
                raise
            self._depth = 1
            try:
                self._taken(suspect)
            except BaseException:
                self.__exit__()
                raise
            return self
        self._depth += 1
        return self

    def __exit__(self, *exc: object) -> None:
        try:
            if self._depth == 1:
                try:
                    _mark(self._fd, _SUSPECT if self._leaving() else _CLEAN)
                finally:
                    fcntl.flock(self._fd, fcntl.LOCK_UN)
                    if self._wanting:
                        self._unwant_timer = threading.Timer(LINGER, self._unwant)
                        self._unwant_timer.daemon = True
                        self._unwant_timer.start()
        finally:
            self._depth -= 1
            if self._depth == 0 and self._closing:
                self._close_file()
            self._thread.release()

    def _take(self) -> None:
        deadline = time.monotonic() + self._wait  # one wait for the whole turn, whatever it queues behind
        self._background = _background if self._turn is None else self._turn  # the release matches it
        if self._background is None:  # plain turns: no lane is anyone's background
            self._flock(self._fd, fcntl.LOCK_EX, deadline)
            return
        if not self._background:
            if self._unwant_timer is not None:
                self._unwant_timer.cancel()
                self._unwant_timer = None
            if not self._wanting:
                self._flock(self._want, fcntl.LOCK_SH, deadline)  # wanted: no background client may ask from now on
                self._wanting = True
            self._flock(self._fd, fcntl.LOCK_EX, deadline)
            return
        self._flock(self._want, fcntl.LOCK_EX, deadline)  # granted only while no foreground client wants the line
        try:
            self._flock(self._fd, fcntl.LOCK_EX, deadline)
        finally:
            fcntl.flock(self._want, fcntl.LOCK_UN)

    def _flock(self, fd: int, operation: int, deadline: float) -> None:
        """``flock`` by tries until ``deadline`` (the kernel's own wait cannot be bounded); then name the holder —
        unless every holder is another lane of this run, whose turns on the line are this lane's to wait out."""
        while True:
            try:
                fcntl.flock(fd, operation | fcntl.LOCK_NB)
                return
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    if not self._our_lanes(kernel_holders(fd)):
                        raise self._busy(fd) from None
                    deadline = time.monotonic() + self._wait
                time.sleep(POLL)

    def _our_lanes(self, holders: list[int]) -> bool:
        """In a run with lanes (a background/foreground turn), holders that are all workers of this run's
        controller: our parent's other children (``hil run --lanes``'s workers are its only children).  None at all
        in a lock table the kernel keeps: the holder let go since the try — try again."""
        if self._background is None:
            return False
        if not holders:
            return os.path.exists("/proc/locks")
        return all(parent_of(pid) == os.getppid() for pid in holders)

    def _busy(self, fd: int) -> TransportError:
        holders = " and ".join(describe_process(pid) for pid in kernel_holders(fd)) or \
            "another process (the kernel's lock table does not say which)"
        return TransportError(f"the serial line {self.device} is held by {holders}: waited {self._wait:g} s for it "
                              f"({self.path}) — ask its user or end that process, or set {WAIT_ENV}=SECONDS to wait "
                              f"longer")

    def _unwant(self) -> None:
        with self._thread:
            if self._depth == 0 and self._wanting and self._want >= 0:
                fcntl.flock(self._want, fcntl.LOCK_UN)
                self._wanting = False

    def close(self) -> None:
        """Let go of the lock file (the line's client closed) — at once, or when the hold in progress ends."""
        with self._thread:
            if self._depth:
                self._closing = True
            else:
                self._close_file()

    def _close_file(self) -> None:
        if self._unwant_timer is not None:
            self._unwant_timer.cancel()
        if self._fd >= 0:
            os.close(self._fd)
            os.close(self._want)  # (its lock with it)
            self._fd = self._want = -1
            self._wanting = False


def _mark(fd: int, value: bytes) -> None:
    # another user's lock file, opened read-only: the next holder resynchronises anyway (an empty mark)
    with contextlib.suppress(OSError):
        os.pwrite(fd, value, 0)


__all__ = ["SharedLine", "run_in_background"]
