"""The emulator's FATEK protocol server: a transport-independent core plus TCP and pty front ends.

:class:`FatekServerCore` turns request bytes into reply bytes.  It is deliberately strict in what it ignores,
because that is what a real FBs does on a shared RS-485 line: a frame with a bad checksum, addressed to another
station, or that cannot be framed at all gets **no reply** (a reply would collide with the real addressee).
Those rejects are counted in ``emulator.stats`` so tests can prove they were seen:

=========================== ===============================================================================
``fatek_requests``          frames addressed to us (or broadcast) that reached command decoding
``fatek_replies``           replies sent
``fatek_error_<code>``      error replies sent, by code (``fatek_error_4``, ``fatek_error_A`` …)
``fatek_broadcast``         broadcast requests (executed, never answered)
``fatek_bad_checksum``      frames dropped for their checksum
``fatek_wrong_station``     well-formed frames for another station
``fatek_malformed``         frames dropped for their framing (short, no hex station/command, overlong)
``fatek_garbage_bytes``     bytes outside any frame, dropped while hunting for STX
=========================== ===============================================================================

Commands run inside :meth:`Emulator.service` (one scan boundary per request, as port 0 of a real unit answers
at the end of a scan).  A rejected frame or a refused request never reaches ``service``, so it cannot change
memory — nor even advance the scan clock.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import os
import random
import threading
import tty
from collections.abc import Callable, Coroutine
from typing import Any

from hil.families.fbs.address import BIT_BANKS, WORD_BANKS
from hil.families.fbs.identity import emulator_status_tail
from hil.families.fbs.protocol.fatek import (
    BROADCAST,
    BitAction,
    ChecksumError,
    Command,
    DetailedStatus,
    DetailedStatusReply,
    FrameAssembler,
    FrameError,
    Loopback,
    MixedRead,
    MixedWrite,
    ReadBits,
    ReadEnableState,
    ReadRegisters,
    RequestError,
    RunStop,
    ShortStatus,
    StatusReply,
    WriteBits,
    WriteRegisters,
    decode_request,
    encode_error,
    encode_reply,
    split_frame,
)
from hil.families.fbs.sim.memory import Memory, Refused
from hil.families.fbs.sim.plc import OS_VERSION, UNIT_TYPE_MC, Emulator
from hil.sim.pacing import LineRate, PacedSender
from hil.sim.runtime import LoopThread, ServerHandle
from hil.sim.wire_faults import FaultySender, WireFaults

#: Sizes reported by command 53.  [our choice] ladder size of an FBs-MC (20 K words); the banks match memory.
DETAILED_SIZES: dict[str, int] = {
    "ladder": 20 * 1024, "DI": BIT_BANKS["X"], "DO": BIT_BANKS["Y"], "AI": 64, "AO": 64, "M": BIT_BANKS["M"],
    "S": BIT_BANKS["S"], "L": 0, "R": WORD_BANKS["R"], "D": WORD_BANKS["D"], "T": BIT_BANKS["T"],
    "C": BIT_BANKS["C"],
}
IO_POINTS_CODE = 0x00  # [our choice] STATUS3 of command 53; no expansion I/O is modelled

_READ_CHUNK = 4096
# A connection that sends only junk is read at most JUNK_SLICE bytes per JUNK_PAUSE (64 MB/s): a flood on one
# connection cannot starve the others, and the junk is still dropped (in linear time, FrameAssembler).
JUNK_SLICE = 65536
JUNK_PAUSE = 0.001
_MAX_PENDING_OUTPUT = 64 * 1024  # pty: replies kept for a client that stopped reading, then dropped
_MAX_PENDING_INPUT = 64 * 1024  # pty in real time: bytes waiting for the end of a scan, then dropped


def corrupt_fatek(reply: bytes, rng: random.Random) -> bytes:
    """Replace the two checksum characters with another valid-looking pair."""
    if len(reply) < 4:
        return reply
    good = int(reply[-3:-1], 16) if reply[-3:-1].isalnum() else 0
    bad = (good + rng.randint(1, 255)) % 256
    return reply[:-3] + b"%02X" % bad + reply[-1:]


class FatekServerCore:
    """Bytes in, replies out, for one emulator.  Keep one :class:`FrameAssembler` per connection."""

    def __init__(self, emulator: Emulator) -> None:
        self.emulator = emulator

    def session(self) -> FrameAssembler:
        return FrameAssembler()

    def feed(self, assembler: FrameAssembler, data: bytes) -> list[bytes]:
        """Feed received bytes; return the replies to send, in order."""
        dropped, overlong = assembler.dropped, assembler.overlong
        frames = assembler.feed(data)
        self.count("fatek_garbage_bytes", assembler.dropped - dropped)
        self.count("fatek_malformed", assembler.overlong - overlong)
        replies = []
        for frame in frames:
            reply = self.handle_frame(frame)
            if reply is not None:
                replies.append(reply)
        return replies

    def handle_frame(self, frame: bytes) -> bytes | None:
        """One complete candidate frame → the reply, or None when the PLC must stay silent."""
        try:
            request = split_frame(frame)
        except ChecksumError:
            self.count("fatek_bad_checksum")
            return None
        except FrameError:
            self.count("fatek_malformed")
            return None
        station = self.emulator.station
        broadcast = request.station == BROADCAST
        if request.station != station and not broadcast:
            self.count("fatek_wrong_station")
            return None
        self.count("fatek_requests")
        if broadcast:
            self.count("fatek_broadcast")
        try:
            command = decode_request(request)
            result = self.emulator.service(lambda mem: self._execute(command, mem))
        except (RequestError, Refused) as exc:  # the decoder's refusals, and the memory's (the same rule)
            return None if broadcast else self._error(station, request.command, exc.code)
        except Exception:  # noqa: BLE001 - a bug here must not kill the server; answer "cannot execute"
            self.count("fatek_internal_error")
            return None if broadcast else self._error(station, request.command, "4")
        if broadcast:
            return None
        self.count("fatek_replies")
        return encode_reply(station, command, result)

    # -- commands -----------------------------------------------------------------------------------------------
    def _execute(self, command: Command, mem: Memory):  # noqa: ANN202 - shape depends on the command
        emu = self.emulator
        if isinstance(command, ShortStatus):
            return StatusReply(int(emu.running))
        if isinstance(command, DetailedStatus):
            return DetailedStatusReply(int(emu.running), UNIT_TYPE_MC, IO_POINTS_CODE, OS_VERSION,
                                       dict(DETAILED_SIZES), emulator_status_tail(emu.serial))
        if isinstance(command, RunStop):
            emu.running = command.run
            return None
        if isinstance(command, BitAction):
            return self._bit_action(command, mem)
        if isinstance(command, ReadEnableState):
            a = command.address
            return list(mem.disabled[a.kind][a.index:a.index + command.count])
        if isinstance(command, (ReadBits, ReadRegisters)):
            return mem.read(command.address, command.count)
        if isinstance(command, (WriteBits, WriteRegisters)):
            mem.write(command.address, command.values)
            return None
        if isinstance(command, MixedRead):
            return [mem.get(a) for a in command.addresses]
        if isinstance(command, MixedWrite):
            for address, value in command.items:
                mem.set(address, value)
            return None
        if isinstance(command, Loopback):
            return command.text
        raise RequestError("4", f"command {command.code} is not implemented by the emulator")

    @staticmethod
    def _bit_action(command: BitAction, mem: Memory) -> None:
        a = command.address
        if command.action in (1, 2):  # disable / enable: the force flag, kept beside the bit
            mem.disabled[a.kind][a.index] = 1 if command.action == 1 else 0
        else:  # set / reset work on a disabled bit too: that is how a bit is forced
            mem.set(a, 1 if command.action == 3 else 0)

    def _error(self, station: int, command_code: str, code: str) -> bytes:
        self.count(f"fatek_error_{code}")
        return encode_error(station, command_code, code)

    def count(self, key: str, n: int = 1) -> None:
        """Add ``n`` to the emulator's wire statistic ``key`` (the servers around the core count what they drop)."""
        if n:
            with self.emulator.lock:  # Counter updates from several loops/threads
                self.emulator.stats[key] += n


# --- TCP --------------------------------------------------------------------------------------------------------
def start_fatek_tcp(emulator: Emulator, host: str = "127.0.0.1", port: int = 0, *,
                    faults: WireFaults | None = None) -> ServerHandle:
    """Serve ``emulator`` over FATEK-on-TCP (a real Ethernet module listens on 500); ``port=0`` lets the OS pick.

    ``faults``: a wire-fault plan consulted for every reply (see :mod:`hil.sim.wire_faults`)."""
    runtime = LoopThread.shared()
    core = FatekServerCore(emulator)
    writers: set[asyncio.StreamWriter] = set()

    async def client(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        writers.add(writer)
        assembler = core.session()
        sender = FaultySender(faults, writer.write, corrupt_fatek, close=writer.close)
        junk = 0  # bytes dropped since this connection's last frame
        try:
            while not sender.closed and (data := await reader.read(_READ_CHUNK)):
                dropped = assembler.dropped
                if emulator.realtime:  # the request waits for the end of a scan: not on the shared loop
                    replies = await asyncio.get_running_loop().run_in_executor(None, core.feed, assembler, data)
                else:
                    replies = core.feed(assembler, data)
                sender.send_all(replies)
                await writer.drain()
                junk = 0 if replies else junk + assembler.dropped - dropped
                if junk >= JUNK_SLICE:  # a connection sending only junk gets its share of the loop, no more:
                    junk -= JUNK_SLICE  # the other clients are answered in between (issue 15)
                    await asyncio.sleep(JUNK_PAUSE)
        except (ConnectionError, OSError):
            pass  # the client went away, possibly mid-frame: nothing to answer
        finally:
            sender.stop()
            writers.discard(writer)
            writer.close()

    async def start() -> asyncio.Server:
        return await asyncio.start_server(client, host, port)

    server = runtime.run(start())
    actual = server.sockets[0].getsockname()[1]

    async def stop() -> None:
        server.close()
        for writer in list(writers):
            writer.close()
        await server.wait_closed()

    return ServerHandle("fatek-tcp", f"{host}:{actual}", lambda: _run_on_loop(runtime, stop))


# --- pty --------------------------------------------------------------------------------------------------------
class _PtyServer:
    """The master side of a pty; a pyserial client opens the slave path as if it were /dev/ttyUSB0."""

    def __init__(self, emulator: Emulator, loop: asyncio.AbstractEventLoop,
                 faults: WireFaults | None = None, line: LineRate | None = None) -> None:
        self.core = FatekServerCore(emulator)
        self.emulator = emulator
        # ``line``: characters take their time both ways — a request is decoded when its last character is in,
        # and the reply (sent at the end of the scan that services it) leaves one character time at a time
        self.paced_in = PacedSender(loop, line, self._serve) if line else None
        self.paced_out = PacedSender(loop, line, self._queue_output) if line else None
        self.sender = FaultySender(faults, self.paced_out.send if self.paced_out else self._queue_output,
                                   corrupt_fatek)  # a pty cannot hang up: "close" = silence
        self._inbox: list[bytes] = []  # real time: requests waiting for the worker (one at a time, in order)
        self._worker: asyncio.Task | None = None
        self.loop = loop
        self.assembler = self.core.session()
        self.master, self.slave = os.openpty()
        # Raw line discipline on the shared termios: no echo, no CR/LF mangling before a client opens the port.
        tty.setraw(self.slave)
        # We keep self.slave open on purpose: with no slave fd open, reading the master fails with EIO (and
        # add_reader would spin on it) every time a client closes the port.
        self.path = os.ttyname(self.slave)
        os.set_blocking(self.master, False)
        self.pending = bytearray()
        self.closed = False

    def start(self) -> None:
        # Listen only; never write first (pyserial flushes input on open, and a real PLC never talks first).
        self.loop.add_reader(self.master, self._readable)

    def _readable(self) -> None:
        try:
            data = os.read(self.master, _READ_CHUNK)
        except BlockingIOError:
            return
        except OSError as exc:
            if exc.errno == errno.EIO:  # cannot happen while we hold the slave, but never spin on it
                self.loop.remove_reader(self.master)
            return
        if self.paced_in is not None:
            self.paced_in.send(data)
        else:
            self._serve(data)

    def _serve(self, data: bytes) -> None:
        if not self.emulator.realtime:
            self.sender.send_all(self.core.feed(self.assembler, data))
            return
        # real time: the request waits for the end of a scan — not on the shared loop (pacing timers, other
        # servers), and one at a time so replies keep their order
        if sum(map(len, self._inbox)) + len(data) > _MAX_PENDING_INPUT:
            self.core.count("fatek_input_dropped", len(data))  # a flood in real time: drop, don't grow
            return
        self._inbox.append(data)
        if self._worker is None:
            self._worker = self.loop.create_task(self._work())

    async def _work(self) -> None:
        try:
            while self._inbox and not self.closed:
                data = self._inbox.pop(0)
                replies = await self.loop.run_in_executor(None, self.core.feed, self.assembler, data)
                if not self.closed:
                    self.sender.send_all(replies)
        finally:
            self._worker = None

    def _queue_output(self, reply: bytes) -> None:
        if len(self.pending) + len(reply) > _MAX_PENDING_OUTPUT:
            self.core.count("fatek_output_dropped")  # a client that stopped reading: drop, don't grow
            return
        self.pending += reply
        self._writable()

    def _writable(self) -> None:
        try:
            while self.pending:
                n = os.write(self.master, self.pending)
                del self.pending[:n]
        except BlockingIOError:
            pass
        except OSError:
            self.pending.clear()
        if self.pending:
            self.loop.add_writer(self.master, self._writable)
        else:
            self.loop.remove_writer(self.master)

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        self.sender.stop()
        for paced in (self.paced_in, self.paced_out):
            if paced is not None:
                paced.close()
        if self._worker is not None:
            self._worker.cancel()
        self.loop.remove_reader(self.master)
        self.loop.remove_writer(self.master)
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):  # (already closed)
                os.close(fd)


def start_fatek_pty(emulator: Emulator, *, faults: WireFaults | None = None,
                    line: LineRate | None = None) -> ServerHandle:
    """Serve ``emulator`` on a new pty; the handle's address is the slave path a serial client opens.  ``line``:
    pace every character at that rate and frame (:mod:`hil.sim.pacing`); None: as fast as the pty copies."""
    runtime = LoopThread.shared()

    async def start() -> _PtyServer:
        pty = _PtyServer(emulator, asyncio.get_running_loop(), faults, line)
        pty.start()
        return pty

    pty = runtime.run(start())

    async def stop() -> None:
        pty.close()

    handle = ServerHandle("fatek-serial", pty.path, lambda: _run_on_loop(runtime, stop))
    handle.line = line
    return handle


def _run_on_loop(runtime: LoopThread, coro_fn: Callable[[], Coroutine[Any, Any, None]]) -> None:
    """Run a stop coroutine on the server loop; from the loop thread itself, schedule it instead of deadlocking."""
    if threading.current_thread() is runtime.thread:
        runtime.loop.create_task(coro_fn())
    elif runtime.loop.is_running():
        runtime.run(coro_fn())


__all__ = ["FatekServerCore", "start_fatek_tcp", "start_fatek_pty", "DETAILED_SIZES"]
