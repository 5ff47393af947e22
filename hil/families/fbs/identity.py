"""Which FBs PLC a wire reaches: its identity as FATEK command 53 tells it, for the journal and recovery.

Command 53 (spec/fatek-protocol.md) gives the main-unit type, the I/O points code, the OS version and the memory
sizes — what kind of PLC it is, not which one: two FBs of one model answer alike, so a bench with several names
each PLC with ``[bench] plc_id``.  STATUS1 (RUN, battery) is left out: it changes.  The emulator gives each
instance a serial of its own in STATUS29–STATUS40 after the marker ``HIL`` [our choice], so emulators started side
by side are told apart; hil reads a serial there only after that marker.  A wire without command 53 (Modbus)
reads no identity: None.
"""

from __future__ import annotations

from typing import Any

from hil.core.errors import HilError

MARK = b"HIL"
MARK_AT = 28  # STATUS29: the first byte after the sizes


def emulator_status_tail(serial: bytes) -> bytes:
    """The bytes of STATUS1…STATUS64 from :data:`MARK_AT` on, as the emulator serves them."""
    return bytes(MARK_AT) + MARK + serial


def identity_of(reply: Any) -> dict[str, str]:
    """The identity fields of a decoded command 53 reply (:class:`DetailedStatusReply`)."""
    out = {"unit type": f"{reply.unit_type:02X}", "io code": f"{reply.io_code:02X}", "os": reply.os_text,
           "sizes": ",".join(f"{k}={v}" for k, v in reply.sizes.items())}
    raw = bytes(reply.raw)
    tail = raw[MARK_AT:MARK_AT + len(MARK)]
    if tail == MARK:
        out["serial"] = raw[MARK_AT + len(MARK):MARK_AT + len(MARK) + 8].hex()
    return out


def read_identity(transport: Any) -> dict[str, str] | None:
    """The PLC's identity over ``transport`` (unguarded), or None when the wire has none or the PLC does not say."""
    ask = getattr(transport, "identity", None)
    if ask is None:
        return None
    try:
        return identity_of(ask())
    except HilError:
        return None


__all__ = ["MARK", "emulator_status_tail", "identity_of", "read_identity"]
