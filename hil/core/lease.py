"""A run's bench locks shared with the worker processes it starts, which die with it.

A run with lanes (:mod:`hil.plugin.lanes`) holds the bench's locks in its controller while its workers write to the
PLC.  A ``flock`` belongs to an open file, not to a process: a worker given the controller's own open lock files
(passed over a Unix socket, ``SCM_RIGHTS``) holds the very same locks, so the kernel frees them only once the
controller *and every worker* has closed them — a controller killed no longer frees the bench while a lane still
writes.  And a worker asks the kernel to kill it when its controller dies (``PR_SET_PDEATHSIG``), so a lane never
goes on, nor restores anything, after its run is gone: the next run, which can take the locks only then, replays the
lanes' journals.

Each worker borrows the locks once, at its start.  The lender's socket is in Linux's abstract namespace (nothing
left on disk by a controller killed) and it answers only its own children (the peer's credentials, ``SO_PEERCRED``);
elsewhere it is a file in a directory only this user can enter.  Borrowed descriptors are close-on-exec: a program
a worker starts does not hold the bench.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import secrets
import shutil
import signal
import socket
import struct
import sys
import tempfile
import threading
from pathlib import Path

from hil.core.errors import HilError
from hil.core.lock import parent_of

_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
_HELLO = b"hil-locks"
_MAX_FDS = 16
_LINUX = sys.platform.startswith("linux")


class LockLender:
    """Lends the open lock files ``fds`` to each process that connects to :attr:`address` (a daemon thread)."""

    def __init__(self, fds: list[int]) -> None:
        self.fds = list(fds)
        self._dir: Path | None = None
        if _LINUX:
            self.address = f"\0hil-lease-{os.getpid()}-{secrets.token_hex(8)}"
        else:
            self._dir = Path(tempfile.mkdtemp(prefix="hil-lease-"))  # mode 0700: this user's processes only
            self.address = str(self._dir / "locks")
        self._server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            self._server.bind(self.address)
            self._server.listen()
        except OSError as exc:  # e.g. a path longer than a Unix socket's 107 bytes
            self.close()
            raise HilError(f"cannot lend the bench's locks to the lanes ({_named(self.address)}: {exc}): set TMPDIR "
                           f"to a short, writable directory") from None
        threading.Thread(target=self._serve, name="hil-lock-lender", daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self._server.accept()
            except OSError:
                return  # closed
            # a worker that died connecting: the next one is served
            with conn, contextlib.suppress(OSError):
                if _child_of_mine(conn):
                    socket.send_fds(conn, [_HELLO], self.fds)

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self._server.shutdown(socket.SHUT_RDWR)  # wakes the thread's accept (a close alone leaves it waiting)
        with contextlib.suppress(OSError):
            self._server.close()
        if self._dir is not None:
            shutil.rmtree(self._dir, ignore_errors=True)


def _child_of_mine(conn: socket.socket) -> bool:
    """The connected process is one this process started (Linux: its credentials and /proc); elsewhere the
    socket's private directory vouches for it."""
    if not _LINUX:
        return True
    pid, _, _ = struct.unpack("3i", conn.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, struct.calcsize("3i")))
    return parent_of(pid) == os.getpid()


def borrow(address: str) -> list[int]:
    """The lender's open lock files, as descriptors of this process (close-on-exec), held until it exits."""
    try:
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
            sock.connect(address)
            message, fds, _, _ = socket.recv_fds(sock, len(_HELLO), _MAX_FDS)
        for fd in fds:  # (Python 3.11's recv_fds drops its flags argument: no MSG_CMSG_CLOEXEC)
            os.set_inheritable(fd, False)
    except OSError as exc:
        raise HilError(f"cannot share the run's bench locks ({_named(address)}: {exc})") from None
    if message != _HELLO or not fds:
        for fd in fds:
            os.close(fd)
        raise HilError(f"cannot share the run's bench locks: {_named(address)} lent none (it lends them only "
                       f"to its run's own workers)")
    return fds


def _named(address: str) -> str:
    """A socket's address as a message shows it (an abstract one without its leading NUL)."""
    return address.lstrip("\0")


def die_with_parent(parent: int) -> bool:
    """Ask the kernel to SIGKILL this process when its parent dies (Linux); whether ``parent`` is still its parent
    (it may have died before the request was made).  Elsewhere only the check."""
    if _LINUX:
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            if libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) != 0:
                raise OSError(ctypes.get_errno(), os.strerror(ctypes.get_errno()))
        except (OSError, AttributeError) as exc:
            raise HilError(f"cannot tie this process to its parent's life (prctl PR_SET_PDEATHSIG: {exc})") from None
    return os.getppid() == parent


__all__ = ["LockLender", "borrow", "die_with_parent"]
