"""The emulator served over FATEK-on-UDP (``emulator+fatek-udp``, ``hil emulate --fatek-udp``), as FBs Ethernet
modules answer it beside TCP (port 500; jfatek and openHAB's binding use it).

A datagram carries a request frame (or several, or a piece: each peer's bytes go through one
:class:`~hil.families.fbs.protocol.fatek.FrameAssembler`, as a TCP connection's do); each reply goes back to the
peer that asked, one datagram per reply, through the wire-fault plan.  UDP keeps no order and may repeat a
datagram: ``late`` (a reply withheld, then sent before the next one) is a reordering, ``echo`` a duplicate that
lands after the next request, ``duplicate`` two frames in one datagram — what the client's fence must survive
(:mod:`hil.families.fbs.transport.udp`).  A peer's requests are served in the order they arrived.
"""

from __future__ import annotations

import asyncio
from typing import cast

from hil.families.fbs.protocol.fatek import FrameAssembler
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs.sim.serve_fatek import FatekServerCore, corrupt_fatek
from hil.sim.runtime import LoopThread, ServerHandle
from hil.sim.wire_faults import FaultySender, WireFaults

#: peers remembered at once (each with its assembler and sender): a port scan cannot grow the server without bound
MAX_PEERS = 64


class _Peer:
    """One client address: its bytes in order, its replies through its own fault plan's sender."""

    def __init__(self, server: _UdpServer, address: tuple) -> None:
        self.server = server
        self.assembler: FrameAssembler = server.core.session()
        self.sender = FaultySender(server.faults, lambda data: server.send(data, address), corrupt_fatek)
        self.inbox: asyncio.Queue[bytes] = asyncio.Queue()
        self.task = asyncio.get_running_loop().create_task(self._serve())

    async def _serve(self) -> None:
        core, emulator = self.server.core, self.server.emulator
        while True:
            data = await self.inbox.get()
            if emulator.realtime:  # the request waits for the end of a scan: not on the shared loop
                replies = await asyncio.get_running_loop().run_in_executor(None, core.feed, self.assembler, data)
            else:
                replies = core.feed(self.assembler, data)
            self.sender.send_all(replies)

    def stop(self) -> None:
        self.sender.stop()
        self.task.cancel()


class _UdpServer(asyncio.DatagramProtocol):
    def __init__(self, emulator: Emulator, faults: WireFaults | None) -> None:
        self.core = FatekServerCore(emulator)
        self.emulator = emulator
        self.faults = faults
        self.peers: dict[tuple, _Peer] = {}
        self.transport: asyncio.DatagramTransport | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self.transport = cast(asyncio.DatagramTransport, transport)  # (the endpoint's: a datagram transport)

    def datagram_received(self, data: bytes, addr: tuple) -> None:
        peer = self.peers.get(addr)
        if peer is None:
            if len(self.peers) >= MAX_PEERS:  # the oldest peer is forgotten (its partial frame with it)
                self.peers.pop(next(iter(self.peers))).stop()
            peer = self.peers[addr] = _Peer(self, addr)
        peer.inbox.put_nowait(data)

    def error_received(self, exc: Exception) -> None:
        pass  # an ICMP "port unreachable" for a reply to a client that left: nothing to answer

    def send(self, data: bytes, address: tuple) -> None:
        if self.transport is not None and not self.transport.is_closing():
            self.transport.sendto(data, address)

    def stop(self) -> None:
        for peer in self.peers.values():
            peer.stop()
        self.peers.clear()
        if self.transport is not None:
            self.transport.close()


def start_fatek_udp(emulator: Emulator, host: str = "127.0.0.1", port: int = 0, *,
                    faults: WireFaults | None = None) -> ServerHandle:
    """Serve ``emulator`` over FATEK-on-UDP; ``port=0`` lets the OS pick.  ``faults``: a wire-fault plan
    consulted for every reply (:mod:`hil.sim.wire_faults`; ``close`` is silence: UDP has no connection)."""
    runtime = LoopThread.shared()

    async def start() -> tuple[asyncio.DatagramTransport, _UdpServer]:
        return await asyncio.get_running_loop().create_datagram_endpoint(
            lambda: _UdpServer(emulator, faults), local_addr=(host, port))

    transport, server = runtime.run(start())
    actual = transport.get_extra_info("sockname")[1]

    async def stop() -> None:
        server.stop()

    return ServerHandle("fatek-udp", f"{host}:{actual}", lambda: runtime.run(stop()))


__all__ = ["MAX_PEERS", "start_fatek_udp"]
