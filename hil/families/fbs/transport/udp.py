"""FATEK over UDP (``fatek+udp://HOST:500?station=1``): FBs Ethernet modules answer the FATEK protocol in
datagrams as well as on TCP (jfatek and openHAB's FATEK binding use it).

:class:`UdpLine` is a :class:`~hil.io.line.Line` whose writes are datagrams to the PLC (the socket is connected:
only the PLC's datagrams are received) and whose reads gather the datagrams that have arrived; the FATEK client
(:class:`~hil.families.fbs.transport.fatek.FatekTransport`) is the same as on a serial line or TCP.  UDP may
reorder and repeat datagrams and FATEK frames carry no transaction id, so every read is fenced (``fence=reads``:
a loop-back with a fresh nonce proves the line clear before the read counts) — the scheme is registered as
unordered (:attr:`hil.core.registry.Scheme.ordered`) and ``fence=trouble`` is refused.
"""

from __future__ import annotations

import select
import socket
from typing import Unpack

from hil.core.errors import InvalidValue, TransportError
from hil.families.fbs.transport.fatek import FatekOptions, FatekTransport
from hil.io.line import Line

#: the largest datagram read at once (a FATEK frame is at most a few hundred bytes)
DATAGRAM = 65535


class UdpLine(Line):
    """A connected UDP socket as a :class:`~hil.io.line.Line`: one datagram per write, reads never block."""

    def __init__(self, host: str, port: int) -> None:
        try:
            family, kind, proto, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)[0]
            sock = socket.socket(family, kind, proto)
            sock.connect(address)
        except OSError as exc:
            raise TransportError(f"cannot open udp://{host}:{port}: {exc.strerror or exc} — check the host "
                                 f"name and that this host has a route to it") from exc
        sock.setblocking(False)
        super().__init__(sock, None)  # a socket in the port's place: no write timeout
        self.sock = sock

    def write(self, data: bytes) -> None:
        self.sock.send(data)

    def receive(self, wait: float) -> bytes:
        ready, _, _ = select.select([self.sock], [], [], max(wait, 0.0))
        return self._drain() if ready else b""

    def pending(self) -> bool:
        ready, _, _ = select.select([self.sock], [], [], 0)
        return bool(ready)

    def discard(self) -> None:
        self._drain()

    def _drain(self) -> bytes:
        """Every datagram waiting, in the order they came (an ICMP "port unreachable" raises: nobody listens)."""
        chunks = []
        while True:
            try:
                chunks.append(self.sock.recv(DATAGRAM))
            except BlockingIOError:
                return b"".join(chunks)

    def close(self) -> None:
        self.sock.close()


class FatekUdpTransport(FatekTransport):
    """The FATEK client over :class:`UdpLine`; every read fenced (datagrams may come twice or out of order)."""

    def __init__(self, host: str, port: int, *, fence: str = "reads", description: str | None = None,
                 **options: Unpack[FatekOptions]) -> None:
        if fence != "reads":
            raise InvalidValue(f"fence={fence} relies on replies arriving once and in order, which UDP does not "
                               f"promise: a FATEK line over UDP fences every read (leave fence out)")
        self.host, self.port = host, port
        super().__init__(f"udp://{host}:{port}", fence="reads", paced=False,
                         description=description or f"fatek+udp://{host}:{port}", **options)

    def new_line(self) -> Line:
        return UdpLine(self.host, self.port)


__all__ = ["DATAGRAM", "FatekUdpTransport", "UdpLine"]
