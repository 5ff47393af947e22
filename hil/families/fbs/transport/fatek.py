"""FatekTransport: what the harness asks of an FBs in the FATEK protocol — words, bits and mixed elements in the
fewest frames (:mod:`hil.families.fbs.transport.plan`), the status and identity, RUN/STOP, bit actions and
loop-backs — each one request of :class:`~hil.families.fbs.transport.fatek_exchange.FatekExchange`, which sends it
on the line and trusts its reply (or says why not).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, TypeVar

from hil.core.errors import PlcErrorReply, ReplyTimeout
from hil.families.fbs.address import Address, parse
from hil.families.fbs.protocol.fatek import (
    BitAction,
    Command,
    DetailedStatus,
    DetailedStatusReply,
    Loopback,
    MixedRead,
    MixedWrite,
    ReadBits,
    ReadEnableState,
    ReadRegisters,
    RunStop,
    ShortStatus,
    StatusReply,
    WriteBits,
    WriteRegisters,
)
from hil.families.fbs.transport.base import Limits, NameLike, PlcStatus, check_value
from hil.families.fbs.transport.fatek_exchange import READ_COMMANDS, FatekExchange, FatekOptions
from hil.families.fbs.transport.plan import plan

if TYPE_CHECKING:
    from hil.families.fbs.transport.replay import RecordedPlc

_R = TypeVar("_R")  # what a command's reply decodes to

UNIT_TYPES = {0x01: "MC"}  # [our choice] only the code the spec names; others print as hex


class FatekTransport(FatekExchange):
    """FATEK protocol client.  ``port_url``: ``/dev/ttyUSB0``, a pty path, ``socket://host:port`` or
    ``rfc2217://host:port``."""

    # 46/47: 64 words (the base halves it for 32-bit names); 44/45: 256 bits; 48: 64 words; 49: 32 words.
    limits = Limits(words=64, bits=256, mixed_read_words=64, mixed_write_words=32)
    #: the recorded PLC a ``replay+fatek://`` target talks to (``.replay.verify()`` after use), else None
    replay: RecordedPlc | None = None
    _identity: DetailedStatusReply | None = None  # command 53's reply, asked once
    _identity_error: str | None = None  # why command 53 was not answered, asked once

    # -- extra FATEK operations ---------------------------------------------------------------------------------
    def request(self, command: Command[_R]) -> _R:
        """One command, with the retry policy of its kind; returns the decoded reply."""
        with self._lock:
            return self._count(self._exchange(command))

    def identity(self) -> DetailedStatusReply:
        """The decoded detailed status (command 53): unit type, OS version, sizes.  Asked once, then cached."""
        with self._lock:
            if self._identity is None:
                self._identity = self._count_read(self._exchange(DetailedStatus()))
            return self._identity

    def set_running(self, run: bool) -> None:
        """RUN (True) or STOP (False) the PLC — command 41."""
        self.request(RunStop(run))

    def bit_action(self, name: str | Address, action: int) -> None:
        """Command 42: 1 disable, 2 enable, 3 set, 4 reset one bit."""
        self.request(BitAction(action, parse(name)))

    def read_disabled(self, name: str | Address, count: int = 1) -> list[int]:
        """Command 43: 1 for each bit that is disabled (forced)."""
        return self.request(ReadEnableState(parse(name), count))

    def loopback(self, text: str) -> str:
        return self.request(Loopback(text))

    # -- many elements: the fewest bytes (hil.families.fbs.transport.plan) ------------------------------------------
    def read_many(self, names: Iterable[NameLike], *, one_scan: bool = True) -> list[int]:
        """Read named elements of any kinds, in order (bits as 0/1): what fits one 48 frame in one frame (one
        scan) unless ``one_scan`` is False, more in range frames where elements are adjacent and mixed frames for
        the rest."""
        addresses = [parse(n) for n in names]
        out = [0] * len(addresses)
        with self._lock:
            for piece in plan(addresses, self.limits, one_scan=one_scan):
                group = [addresses[i] for i in piece.positions]
                if piece.run:
                    read = self._read_bits if group[0].is_bit else self._read_words
                    values = self._count_read(read(group[0], len(group)))
                else:
                    values = self._count_read(self._read_many(group))
                for i, value in zip(piece.positions, values):
                    out[i] = int(value)
        return out

    def write_many(self, items: Mapping[NameLike, int] | Iterable[tuple[NameLike, int]], *,
                   one_scan: bool = True) -> None:
        """Write named elements of any kinds, in the order given: as :meth:`read_many` plans its frames."""
        pairs = list(items.items()) if isinstance(items, Mapping) else list(items)
        checked = [(address, check_value(address, v)) for address, v in ((parse(a), v) for a, v in pairs)]
        addresses = [a for a, _ in checked]
        values = [v for _, v in checked]
        with self._lock:
            for piece in plan(addresses, self.limits, values, one_scan=one_scan):
                group = [checked[i] for i in piece.positions]
                if piece.run:
                    write = self._write_bits if group[0][0].is_bit else self._write_words
                    write(group[0][0], [v for _, v in group])
                else:
                    self._write_many(group)
                self._count(None)

    # -- Transport primitives -----------------------------------------------------------------------------------
    def _read_words(self, first: Address, count: int) -> list[int]:
        return self._exchange(ReadRegisters(first, count))

    def _write_words(self, first: Address, values: list[int]) -> None:
        self._exchange(WriteRegisters(first, values))

    def _read_bits(self, first: Address, count: int) -> list[int]:
        return self._exchange(ReadBits(first, count))

    def _write_bits(self, first: Address, values: list[int]) -> None:
        self._exchange(WriteBits(first, values))

    def _read_many(self, addresses: list[Address]) -> list[int]:
        return self._exchange(MixedRead(addresses))

    def _write_many(self, items: list[tuple[Address, int]]) -> None:
        self._exchange(MixedWrite(items))

    def _status(self) -> PlcStatus:
        status: StatusReply = self._exchange(ShortStatus())
        return PlcStatus(running=status.running, flags=status.flags, identity=self._identity_fields(),
                         via=f"FATEK station {self.station} on {self.line_name}")

    def _identity_fields(self) -> dict[str, str]:
        if self._identity is None and self._identity_error is None:
            try:
                self._identity = self._exchange(DetailedStatus())
            except (PlcErrorReply, ReplyTimeout) as exc:
                # A unit that refuses or ignores 53 still has a useful short status; ask only once.
                self._identity_error = str(exc)
        if self._identity is None:
            return {"detailed status": f"unavailable: {self._identity_error}"}
        ident = self._identity
        fields = {"unit type": f"{ident.unit_type:02X} ({UNIT_TYPES.get(ident.unit_type, 'unknown')})",
                  "os version": ident.os_text, "io code": f"{ident.io_code:02X}"}
        fields.update({f"{name} size": str(n) for name, n in ident.sizes.items()})
        return fields


__all__ = ["READ_COMMANDS", "FatekOptions", "FatekTransport"]
