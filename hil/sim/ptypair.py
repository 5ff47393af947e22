"""Two ptys bridged back to back on an asyncio loop — ``socat pty pty`` without socat.

pymodbus's serial server and client both open a *device path* with pyserial (the client exclusively), and a pty
master has no path; so the server opens one pty's slave, the client opens the other's, and the loop copies
bytes between the two masters.  The bridge keeps a slave fd of each pty open itself: when the last slave fd of a
pty closes, reads on its master fail with EIO at once and forever, which would turn a client that simply
disconnects into a busy loop (and end the session for the next client).
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import errno
import os
import tty

from hil.sim.pacing import LineRate, PacedSender
from hil.sim.rtu_gate import RtuGate
from hil.sim.wire_faults import FaultySender, WireFaults, corrupt_crc

_CHUNK = 4096


class PtyPair:
    """Bytes written to :attr:`path_a` come out of :attr:`path_b` and vice versa (create and use on the loop)."""

    def __init__(self, loop: asyncio.AbstractEventLoop, *, gate_b_to_a: bool = False,
                 faults: WireFaults | None = None, line: LineRate | None = None) -> None:
        """``gate_b_to_a``: pass what the client (side b) sends through an :class:`RtuGate` on its way to a.
        ``faults``: a wire-fault plan applied to what side a (the server) sends back — its replies.  ``line``:
        every character takes its time at that rate and frame, both ways (:mod:`hil.sim.pacing`)."""
        self.loop = loop
        self.line = line
        self._gate = RtuGate(loop, self._write_to_a) if gate_b_to_a else None
        # the client's bytes reach the gate (or side a) one character time at a time; replies leave side a paced
        # after the fault plan, as a noisy line delays nothing but carries everything at its rate
        self._paced_a_to_b = PacedSender(loop, line, self._write_to_b) if line else None
        self._to_b = self._paced_a_to_b.send if self._paced_a_to_b else self._write_to_b
        self._paced_b_to_a = PacedSender(loop, line, self._arrived_at_a) if line else None
        self._replies = FaultySender(faults, self._to_b, corrupt_crc) if faults is not None else None
        self.stats: collections.Counter[str] = collections.Counter()  # bytes moved / dropped, for tests
        self._fds: list[int] = []
        try:
            self._a_master, self._a_slave = self._open()
            self._b_master, self._b_slave = self._open()
        except BaseException:
            self._close_fds()
            raise
        self.path_a = os.ttyname(self._a_slave)
        self.path_b = os.ttyname(self._b_slave)
        self.closed = False
        loop.add_reader(self._a_master, self._pump, self._a_master, self._b_master, "a_to_b")
        loop.add_reader(self._b_master, self._pump, self._b_master, self._a_master, "b_to_a")

    def _open(self) -> tuple[int, int]:
        master, slave = os.openpty()
        self._fds += [master, slave]
        # Raw from the start: a cooked pty echoes and edits lines before pyserial gets to configure it.
        tty.setraw(slave)
        os.set_blocking(master, False)
        return master, slave

    def _pump(self, src: int, dst: int, direction: str) -> None:
        try:
            data = os.read(src, _CHUNK)
        except BlockingIOError:
            return
        except OSError as exc:  # cannot happen while we hold the slave fds; never spin on it regardless
            if exc.errno == errno.EIO:
                self.loop.remove_reader(src)
            return
        self.stats[direction] += len(data)
        if direction == "b_to_a":
            if self._paced_b_to_a is not None:
                self._paced_b_to_a.send(data)
            else:
                self._arrived_at_a(data)
            return
        if self._replies is not None:
            self._replies.send(data)
            return
        self._to_b(data)

    def _arrived_at_a(self, data: bytes) -> None:
        """What the client sent, as it comes off the line at side a's end."""
        if self.closed:
            return
        if self._gate is not None:
            self._gate.feed(data)
            self.stats.update(self._gate.stats)
            self._gate.stats.clear()
            return
        self._write_to_a(data)

    def _write_to_a(self, data: bytes) -> None:
        self._write(self._a_master, data, "b_to_a")

    def _write_to_b(self, data: bytes) -> None:
        if not self.closed:
            self._write(self._b_master, data, "a_to_b")

    def _write(self, dst: int, data: bytes, direction: str) -> None:
        view = memoryview(data)
        while view:
            try:
                view = view[os.write(dst, view):]
            except BlockingIOError:
                # Nobody reads that side (no client open): drop, as a serial line with no listener does.
                self.stats[f"{direction}_dropped"] += len(view)
                return
            except OSError:
                self.stats[f"{direction}_dropped"] += len(view)
                return

    def close(self) -> None:
        """Stop bridging and close every fd (idempotent; call on the loop)."""
        if self.closed:
            return
        self.closed = True
        if self._gate is not None:
            self._gate.close()
        if self._replies is not None:
            self._replies.stop()
        for paced in (self._paced_a_to_b, self._paced_b_to_a):
            if paced is not None:
                paced.close()
        for master in (self._a_master, self._b_master):
            self.loop.remove_reader(master)
        self._close_fds()

    def _close_fds(self) -> None:
        for fd in self._fds:
            with contextlib.suppress(OSError):  # already closed: nothing to release
                os.close(fd)
        self._fds = []


__all__ = ["PtyPair"]
