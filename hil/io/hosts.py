"""Whether a host name resolves: "nothing accepted the connection" is the wrong advice for a name that names no
host, so every TCP wire asks this first when a connection fails."""

from __future__ import annotations

import socket


def unresolved(host: str | None) -> str | None:
    """What to check when ``host`` does not resolve to an address, else None (an address, or a name that does)."""
    if not host:
        return None
    try:
        socket.getaddrinfo(host, None)
    except socket.gaierror as exc:
        return (f"the host name {host!r} does not resolve ({exc.strerror}) — check its spelling, DNS or /etc/hosts, "
                f"or give the PLC's IP address")
    except (UnicodeError, ValueError):
        return f"{host!r} is not a host name or address"
    return None
