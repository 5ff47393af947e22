"""The FATEK protocol as pure byte codecs: frames, checksum, commands, error codes.  No I/O here.

Frame: ``STX · station(2 hex) · command(2 hex) · data · checksum(2 hex) · ETX``.  The checksum is the low byte of
the sum of every byte from STX through the last data character (leaving STX out is a classic client bug).
A reply repeats station and command, then one error character, then data (none unless the error is 0);
command 4E (loop-back) echoes without an error character.

Each command is a small dataclass that knows its request data, how to decode its reply data (client side),
how to be rebuilt from request data (server side) and how to encode a reply.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Generic, TypeVar

from hil.core.errors import AddressError, InvalidValue, PlcErrorReply, ProtocolError
from hil.families.fbs.address import DWORD, Address, missing, parse, take_frame_name

STX = 0x02
ETX = 0x03
MAX_FRAME = 508  # bytes, STX to ETX
MAX_DATA = 500
BROADCAST = 0

MAX_BITS = 256  # commands 43/44/45
MAX_WORDS = 64  # commands 46/47/48 (32-bit values count two)
MAX_MIXED_WRITE_WORDS = 32  # command 49

ERROR_CODES: dict[str, str] = {
    "0": "no error",
    "2": "illegal value",
    "3": "write disabled (unconfirmed meaning)",
    "4": "illegal format, or the command cannot be executed",
    "5": "cannot RUN: ladder checksum error",
    "6": "cannot RUN: PLC ID does not match the ladder ID",
    "7": "cannot RUN: syntax check error",
    "9": "cannot RUN: function not supported",
    "A": "illegal address",
}


# --- frame errors: distinct types so callers (and tests) can tell what went wrong ---------------------------
class FrameError(ProtocolError):
    """A frame that cannot be accepted."""


class ChecksumError(FrameError):
    pass


class StationMismatch(FrameError):
    pass


class CommandMismatch(FrameError):
    pass


class TruncatedFrame(FrameError):
    pass


class OverlongFrame(FrameError):
    pass


class MalformedFrame(FrameError):
    pass


class RequestError(ProtocolError):
    """Server side: a well-framed request the PLC must refuse with ``code`` (4 = format, A = address, 2 = value)."""

    def __init__(self, code: str, detail: str) -> None:
        self.code = code
        super().__init__(f"error {code} ({ERROR_CODES[code]}): {detail}")


_HEX = frozenset("0123456789ABCDEFabcdef")


def _is_hex(text: str) -> bool:
    """Strict hex digits (``int(x, 16)`` alone would accept " 1", "+1", "0x1" and "1_0")."""
    return bool(text) and all(c in _HEX for c in text)


# --- frames -------------------------------------------------------------------------------------------------
def checksum(body: bytes) -> bytes:
    """Two uppercase hex characters: the low byte of the sum of ``body`` (which starts with STX)."""
    return b"%02X" % (sum(body) & 0xFF)


@dataclass(frozen=True)
class Frame:
    station: int
    command: str
    data: str

    def encode(self) -> bytes:
        return build_frame(self.station, self.command, self.data)


def build_frame(station: int, command: str, data: str = "") -> bytes:
    if not 0 <= station <= 0xFE:
        raise InvalidValue(f"station {station} outside 0–254 (0 = broadcast)")
    if len(data) > MAX_DATA:
        raise InvalidValue(f"frame data is {len(data)} characters; the protocol allows {MAX_DATA}")
    body = bytes([STX]) + f"{station:02X}{command}{data}".encode("ascii")
    return body + checksum(body) + bytes([ETX])


def split_frame(frame: bytes) -> Frame:
    """Check framing and checksum of one complete frame; return its station, command and data."""
    if len(frame) > MAX_FRAME:
        raise OverlongFrame(f"frame of {len(frame)} bytes exceeds the protocol's {MAX_FRAME}")
    if len(frame) < 8:
        raise TruncatedFrame(f"frame of {len(frame)} bytes is shorter than the minimum 8: {frame!r}")
    if frame[0] != STX:
        raise MalformedFrame(f"frame does not start with STX: {frame[:12]!r}")
    if frame[-1] != ETX:
        raise TruncatedFrame(f"frame does not end with ETX: {frame[-12:]!r}")
    body, check = frame[:-3], frame[-3:-1]
    if checksum(body) != check.upper():
        raise ChecksumError(f"checksum {check.decode('latin-1')!r} does not match "
                            f"{checksum(body).decode()!r} computed over STX…data of {frame!r}")
    try:
        text = body[1:].decode("ascii")
    except UnicodeDecodeError:
        raise MalformedFrame(f"non-ASCII bytes in {frame!r}") from None
    if not _is_hex(text[0:2]):
        raise MalformedFrame(f"station is not two hex digits in {frame!r}")
    station = int(text[0:2], 16)
    command = text[2:4].upper()
    if len(command) != 2 or any(c not in "0123456789ABCDEF" for c in command):
        raise MalformedFrame(f"command is not two hex digits in {frame!r}")
    return Frame(station, command, text[4:])


def check_reply(frame: bytes, station: int, command: str) -> str:
    """Validate a reply to (station, command); return its data after the error character.

    Raises a distinct :class:`FrameError` for framing faults and :class:`PlcErrorReply` for an error code.
    """
    reply = split_frame(frame)
    if reply.station != station:
        raise StationMismatch(f"reply from station {reply.station:02X}, expected {station:02X}")
    if reply.command != command:
        raise CommandMismatch(f"reply echoes command {reply.command}, expected {command}")
    if command == Loopback.code:
        return reply.data
    if not reply.data:
        raise TruncatedFrame(f"reply to command {command} has no error character")
    error, data = reply.data[0].upper(), reply.data[1:]
    if error != "0":
        raise PlcErrorReply(error, ERROR_CODES.get(error, "unknown error code"), f"command {command}")
    return data


class FrameAssembler:
    """Cuts a byte stream into candidate frames: hunts for STX, collects to ETX, drops what cannot be a frame.

    Used by the client (resynchronise on STX after noise) and by the emulator's servers.  ``dropped`` counts
    bytes discarded as garbage, ``overlong`` frames abandoned for running past ``MAX_FRAME``.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.dropped = 0
        self.overlong = 0

    def feed(self, data: bytes) -> list[bytes]:
        self._buf += data
        frames: list[bytes] = []
        while True:
            start = self._buf.find(STX)
            if start < 0:
                self.dropped += len(self._buf)
                self._buf.clear()
                return frames
            if start:
                self.dropped += start
                del self._buf[:start]
            # A new STX before the ETX means the earlier frame was cut short: restart from the last STX before
            # it (one search, not one per STX: a flood of STX bytes is dropped in linear time).
            end = self._buf.find(ETX, 1)
            restart = self._buf.rfind(STX, 1, end if end >= 0 else len(self._buf))
            if restart > 0:
                self.dropped += restart
                del self._buf[:restart]
                continue
            if end < 0:
                if len(self._buf) > MAX_FRAME:
                    self.overlong += 1
                    self.dropped += len(self._buf)
                    self._buf.clear()
                return frames
            frame = bytes(self._buf[:end + 1])
            del self._buf[:end + 1]
            if len(frame) > MAX_FRAME:
                self.overlong += 1
                self.dropped += len(frame)
                continue
            frames.append(frame)

    @property
    def pending(self) -> int:
        """Bytes held of a frame not yet complete."""
        return len(self._buf)

    def clear(self) -> None:
        self._buf.clear()


# --- value helpers ---------------------------------------------------------------------------------------------
def _count(n: int) -> str:
    return f"{n % 256:02X}"  # 256 is sent as 00


def _parse_count(text: str, what: str) -> int:
    if len(text) != 2 or not _is_hex(text):
        raise RequestError("4", f"{what} count {text!r} is not two hex digits")
    return int(text, 16) or 256


def _hex_width(address: Address) -> int:
    return 8 if address.width == DWORD else 4


def _format_value(address: Address, value: int) -> str:
    if address.is_bit:
        return "1" if value else "0"
    width = _hex_width(address)
    if not 0 <= value < 16 ** width:
        raise InvalidValue(f"value {value} does not fit {address} ({address.bits} bits, unsigned)")
    return f"{value:0{width}X}"


def _parse_values(text: str, address: Address, count: int) -> list[int]:
    if address.is_bit:
        if len(text) != count or any(c not in "01" for c in text):
            raise MalformedFrame(f"expected {count} bit characters, got {text!r}")
        return [int(c) for c in text]
    width = _hex_width(address)
    if len(text) != width * count:
        raise MalformedFrame(f"expected {count} values of {width} hex characters, got {len(text)} characters")
    if count and not _is_hex(text):
        raise MalformedFrame(f"non-hex characters in register data {text!r}")
    return [int(text[i:i + width], 16) for i in range(0, len(text), width)]


# Server side: which error a request with a fault gets (docs/targets.md).  The frame is
# read left to right and the first fault decides: the count field (format, 4), the element name (format 4, or
# A beyond the model), the extent the count and name give (over the command's limit 4, past the model A), then
# each value (a bit other than 0/1, a RUN/STOP or bit-action argument out of its set: 2; cut short or not hex: 4),
# then trailing characters (4).  So "45, R4200, bit 2" is A, and a 42 with action 9 on M9999 is 2.
def _take_name(data: str, pos: int) -> tuple[Address, int]:
    try:
        address, end = take_frame_name(data, pos)
    except AddressError as exc:
        # A name of the right shape but outside the model is an address error; anything else is format.
        raise RequestError("A" if "outside" in str(exc) or "multiple of 8" in str(exc) else "4", str(exc)) from None
    _check_exists(address, 1)
    return address, end


def _check_exists(address: Address, count: int) -> None:
    """Error A, at this point of the frame's order of faults, for a run an FBs does not have (the rule:
    :func:`hil.families.fbs.address.missing`; the emulator's memory refuses the same runs for any requester)."""
    reason = missing(address, count)
    if reason is not None:
        raise RequestError("A", reason)


def _check_extent(cls: type[_Run[Any]], address: Address, count: int) -> None:
    """The run a range command's count and start element give: the command's limit (4), the model (A)."""
    if cls.bits_only != address.is_bit:
        raise RequestError("4", f"command {cls.code} takes {'bit' if cls.bits_only else 'register'} names, "
                                f"not {address}")
    limit = MAX_BITS if cls.bits_only else MAX_WORDS // address.words
    if not 1 <= count <= limit:
        raise RequestError("4", f"command {cls.code} moves 1–{limit} {address.kind} elements, not {count}")
    try:
        address.offset(count - 1)
    except AddressError as exc:
        raise RequestError("A", str(exc)) from None
    _check_exists(address, count)


def _take_value(data: str, pos: int, address: Address) -> tuple[int, int]:
    width = 1 if address.is_bit else _hex_width(address)
    chunk = data[pos:pos + width]
    if len(chunk) != width:
        raise RequestError("4", f"value for {address} is cut short")
    if address.is_bit and chunk not in ("0", "1"):
        raise RequestError("2", f"bit value {chunk!r} for {address} is neither 0 nor 1")
    if not address.is_bit and not _is_hex(chunk):
        raise RequestError("4", f"value {chunk!r} for {address} is not valid")
    return int(chunk, 2 if address.is_bit else 16), pos + width


def _expect_end(data: str, pos: int) -> None:
    if pos != len(data):
        raise RequestError("4", f"{len(data) - pos} unexpected characters after the request: {data[pos:]!r}")


# --- commands --------------------------------------------------------------------------------------------------
_R = TypeVar("_R")  # what a command's reply decodes to


class Command(Generic[_R]):
    """Base of the command codecs.  ``code`` is the two-hex-digit command number; a reply decodes to ``_R``."""

    code: ClassVar[str]

    def request_data(self) -> str:
        return ""

    def decode(self, data: str) -> _R:
        """Client side: the reply's data (after the error code) as the caller's value."""
        raise NotImplementedError(f"command {self.code} has no reply decoder")

    @classmethod
    def from_request(cls, data: str) -> Command[_R]:
        _expect_end(data, 0)
        return cls()

    def encode_result(self, result: _R) -> str:
        """Server side: the reply's data for ``result`` (what the PLC did with the request)."""
        return ""

    def describe(self) -> str:
        return f"command {self.code}"


class _Acknowledged(Command[None]):
    """A command whose reply carries no data (41, 42, 45, 47, 49): the reply only says it was done."""

    def decode(self, data: str) -> None:
        if data:
            raise MalformedFrame(f"command {self.code} reply should carry no data, got {data!r}")


@dataclass
class StatusReply:
    """STATUS1 bits: b0 RUN, b1 battery low (53 only), b2 ladder checksum error, b3 ROM pack, b4 watchdog,
    b5 ID set, b6 emergency stop."""

    status1: int
    status2: int = 0
    status3: int = 0

    @property
    def running(self) -> bool:
        return bool(self.status1 & 0x01)

    @property
    def flags(self) -> list[str]:
        names = ["RUN", "battery low", "ladder checksum error", "ROM pack", "watchdog timeout", "ID set",
                 "emergency stop"]
        return [name for bit, name in enumerate(names) if self.status1 >> bit & 1]


def _parse_hex_bytes(data: str, what: str) -> list[int]:
    if len(data) % 2:
        raise MalformedFrame(f"{what}: odd number of hex characters in {data!r}")
    if data and not _is_hex(data):
        raise MalformedFrame(f"{what}: non-hex characters in {data!r}")
    return [int(data[i:i + 2], 16) for i in range(0, len(data), 2)]


@dataclass
class ShortStatus(Command[StatusReply]):
    code: ClassVar[str] = "40"

    def decode(self, data: str) -> StatusReply:
        values = _parse_hex_bytes(data, "status")
        if len(values) != 3:
            raise MalformedFrame(f"status reply should carry 3 bytes, got {len(values)}")
        return StatusReply(*values)

    def encode_result(self, result: StatusReply) -> str:
        return f"{result.status1:02X}{result.status2:02X}{result.status3:02X}"

    def describe(self) -> str:
        return "short status (40)"


DETAILED_COUNTS = ("ladder", "DI", "DO", "AI", "AO", "M", "S", "L", "R", "D", "T", "C")


@dataclass
class DetailedStatusReply:
    status1: int
    unit_type: int
    io_code: int
    os_version: int
    sizes: dict[str, int] = field(default_factory=dict)
    raw: bytes = b""

    @property
    def running(self) -> bool:
        return bool(self.status1 & 0x01)

    @property
    def os_text(self) -> str:
        return f"V{self.os_version >> 4}.{self.os_version & 0x0F:X}x"


@dataclass
class DetailedStatus(Command[DetailedStatusReply]):
    code: ClassVar[str] = "53"

    def decode(self, data: str) -> DetailedStatusReply:
        values = _parse_hex_bytes(data, "detailed status")
        if len(values) < 4 + 2 * len(DETAILED_COUNTS):
            raise MalformedFrame(f"detailed status carries {len(values)} bytes, expected at least "
                                 f"{4 + 2 * len(DETAILED_COUNTS)}")
        sizes = {name: values[4 + 2 * i] << 8 | values[5 + 2 * i] for i, name in enumerate(DETAILED_COUNTS)}
        return DetailedStatusReply(values[0], values[1], values[2], values[3], sizes, bytes(values))

    def encode_result(self, result: DetailedStatusReply) -> str:
        raw = bytearray([result.status1, result.unit_type, result.io_code, result.os_version])
        for name in DETAILED_COUNTS:
            raw += result.sizes.get(name, 0).to_bytes(2, "big")
        raw += result.raw[len(raw):64]  # the rest of STATUS1…STATUS64 as given (zeros when not)
        raw += bytes(64 - len(raw))
        return raw.hex().upper()

    def describe(self) -> str:
        return "detailed status (53)"


@dataclass
class RunStop(_Acknowledged):
    code: ClassVar[str] = "41"
    run: bool = True

    def request_data(self) -> str:
        return "1" if self.run else "0"

    @classmethod
    def from_request(cls, data: str) -> RunStop:
        if len(data) != 1:
            raise RequestError("4", f"RUN/STOP wants one character, '1' or '0', got {data!r}")
        if data not in ("0", "1"):
            raise RequestError("2", f"RUN/STOP wants '1' or '0', got {data!r}")
        return cls(data == "1")

    def describe(self) -> str:
        return "RUN (41)" if self.run else "STOP (41)"


BIT_ACTIONS = {1: "disable", 2: "enable", 3: "set", 4: "reset"}


@dataclass
class BitAction(_Acknowledged):
    code: ClassVar[str] = "42"
    action: int = 3
    address: Address = field(default_factory=lambda: parse("M0"))

    def __post_init__(self) -> None:
        self.address = parse(self.address)
        if self.action not in BIT_ACTIONS:
            raise InvalidValue(f"bit action must be one of {BIT_ACTIONS}, not {self.action}")
        if not self.address.is_bit:
            raise InvalidValue(f"command 42 acts on a bit, not {self.address}")

    def request_data(self) -> str:
        return f"{self.action}{self.address.fatek_name}"

    @classmethod
    def from_request(cls, data: str) -> BitAction:
        if not data:
            raise RequestError("4", "command 42 needs an action and a bit")
        if data[0] not in "1234":
            raise RequestError("2", f"bit action {data[:1]!r} is not 1–4")
        address, end = _take_name(data, 1)
        _expect_end(data, end)
        if not address.is_bit:
            raise RequestError("4", f"command 42 needs a bit, got {address}")
        return cls(int(data[0]), address)

    def describe(self) -> str:
        return f"{BIT_ACTIONS[self.action]} {self.address} (42)"


class _Run(Command[_R]):
    """What the range commands 43–47 share: a run of ``count`` elements from ``address``, all bits or all registers
    as ``bits_only`` says."""

    address: Address
    bits_only: ClassVar[bool] = True

    def _check_run(self, count: int) -> None:
        """Client side: the run fits the command (InvalidValue) and its bank (AddressError)."""
        if self.bits_only != self.address.is_bit:
            raise InvalidValue(f"command {self.code} takes {'bit' if self.bits_only else 'register'} names, "
                             f"not {self.address}")
        limit = MAX_BITS if self.bits_only else MAX_WORDS // self.address.words
        if not 1 <= count <= limit:
            raise InvalidValue(f"command {self.code} moves 1–{limit} {self.address.kind} elements, not {count}")
        # Raises AddressError when the run leaves the bank.
        self.address.offset(count - 1)


_C = TypeVar("_C", bound=Command[Any])


def _as_request_error(build: Callable[[], _C]) -> _C:
    """Server side: a command built from a request, its client-side refusals turned into the error a PLC answers
    (A: the run leaves its bank, 4: any other bad value)."""
    try:
        return build()
    except AddressError as exc:
        raise RequestError("A", str(exc)) from None
    except ValueError as exc:
        raise RequestError("4", str(exc)) from None


@dataclass
class _RangeCommand(_Run[list[int]]):
    """Shared shape of 43/44/46: N then a start element."""

    address: Address = field(default_factory=lambda: parse("R0"))
    count: int = 1

    def __post_init__(self) -> None:
        self.address = parse(self.address)
        self._check_run(self.count)

    def request_data(self) -> str:
        return _count(self.count) + self.address.fatek_name

    @classmethod
    def from_request(cls, data: str) -> _RangeCommand:
        count = _parse_count(data[:2], f"command {cls.code}")
        address, end = _take_name(data, 2)
        _check_extent(cls, address, count)
        _expect_end(data, end)
        return _as_request_error(lambda: cls(address, count))

    def decode(self, data: str) -> list[int]:
        return _parse_values(data, self.address, self.count)

    def encode_result(self, result: Sequence[int]) -> str:
        return "".join(_format_value(self.address, v) for v in result)

    def describe(self) -> str:
        return f"{self.describe_verb()} {self.count} from {self.address} ({self.code})"

    def describe_verb(self) -> str:
        return "read"


@dataclass
class ReadEnableState(_RangeCommand):
    code: ClassVar[str] = "43"

    def describe_verb(self) -> str:
        return "read disable state of"


@dataclass
class ReadBits(_RangeCommand):
    code: ClassVar[str] = "44"


@dataclass
class ReadRegisters(_RangeCommand):
    code: ClassVar[str] = "46"
    bits_only: ClassVar[bool] = False


@dataclass
class _WriteRange(_Acknowledged, _Run[None]):
    """Shared shape of 45/47: N, start element, N values."""

    address: Address = field(default_factory=lambda: parse("R0"))
    values: list[int] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.address = parse(self.address)
        self.values = [int(v) for v in self.values]
        self._check_run(self.count)
        for v in self.values:
            _format_value(self.address, v)  # range check before anything is sent

    @property
    def count(self) -> int:
        return len(self.values)

    def request_data(self) -> str:
        return _count(self.count) + self.address.fatek_name + "".join(
            _format_value(self.address, v) for v in self.values)

    @classmethod
    def from_request(cls, data: str) -> _WriteRange:
        count = _parse_count(data[:2], f"command {cls.code}")
        address, pos = _take_name(data, 2)
        _check_extent(cls, address, count)
        values = []
        for _ in range(count):
            value, pos = _take_value(data, pos, address)
            values.append(value)
        _expect_end(data, pos)
        return _as_request_error(lambda: cls(address, values))

    def describe(self) -> str:
        return f"write {self.count} to {self.address} ({self.code})"


@dataclass
class WriteBits(_WriteRange):
    code: ClassVar[str] = "45"


@dataclass
class WriteRegisters(_WriteRange):
    code: ClassVar[str] = "47"
    bits_only: ClassVar[bool] = False


@dataclass
class MixedRead(Command[list[int]]):
    code: ClassVar[str] = "48"
    addresses: list[Address] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.addresses = [parse(a) for a in self.addresses]
        cost = sum(a.words for a in self.addresses)
        if not self.addresses or cost > MAX_WORDS:
            raise InvalidValue(f"command 48 reads 1–{MAX_WORDS} words (bit = 1, 32-bit = 2), not {cost}")

    def request_data(self) -> str:
        return _count(len(self.addresses)) + "".join(a.fatek_name for a in self.addresses)

    @classmethod
    def from_request(cls, data: str) -> MixedRead:
        count = _parse_count(data[:2], "command 48")
        pos, names = 2, []
        for _ in range(count):
            address, pos = _take_name(data, pos)
            names.append(address)
        _expect_end(data, pos)
        try:
            return cls(names)
        except ValueError as exc:
            raise RequestError("4", str(exc)) from None

    def decode(self, data: str) -> list[int]:
        pos, values = 0, []
        for address in self.addresses:
            width = 1 if address.is_bit else _hex_width(address)
            values += _parse_values(data[pos:pos + width], address, 1)
            pos += width
        if pos != len(data):
            raise MalformedFrame(f"mixed read reply is {len(data)} characters, expected {pos}")
        return values

    def encode_result(self, result: Sequence[int]) -> str:
        return "".join(_format_value(a, v) for a, v in zip(self.addresses, result))

    def describe(self) -> str:
        names = ",".join(str(a) for a in self.addresses[:6]) + ("…" if len(self.addresses) > 6 else "")
        return f"mixed read {names} (48)"


@dataclass
class MixedWrite(_Acknowledged):
    code: ClassVar[str] = "49"
    items: list[tuple[Address, int]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.items = [(parse(a), int(v)) for a, v in self.items]
        cost = sum(a.words for a, _ in self.items)
        if not self.items or cost > MAX_MIXED_WRITE_WORDS:
            raise InvalidValue(f"command 49 writes 1–{MAX_MIXED_WRITE_WORDS} words, not {cost}")
        for a, v in self.items:
            _format_value(a, v)

    def request_data(self) -> str:
        return _count(len(self.items)) + "".join(a.fatek_name + _format_value(a, v) for a, v in self.items)

    @classmethod
    def from_request(cls, data: str) -> MixedWrite:
        count = _parse_count(data[:2], "command 49")
        pos, items = 2, []
        for _ in range(count):
            address, pos = _take_name(data, pos)
            value, pos = _take_value(data, pos, address)
            items.append((address, value))
        _expect_end(data, pos)
        try:
            return cls(items)
        except ValueError as exc:
            raise RequestError("4", str(exc)) from None

    def describe(self) -> str:
        names = ",".join(f"{a}={v}" for a, v in self.items[:4]) + ("…" if len(self.items) > 4 else "")
        return f"mixed write {names} (49)"


@dataclass
class Loopback(Command[str]):
    code: ClassVar[str] = "4E"
    text: str = ""

    def __post_init__(self) -> None:
        if len(self.text) > 256:
            raise InvalidValue("loop-back text is limited to 256 characters")

    def request_data(self) -> str:
        return self.text

    @classmethod
    def from_request(cls, data: str) -> Loopback:
        if len(data) > 256:  # the dataclass check raises ValueError; a server must answer error 4 instead
            raise RequestError("4", f"loop-back text of {len(data)} characters exceeds 256")
        return cls(data)

    def decode(self, data: str) -> str:
        if data != self.text:
            raise MalformedFrame(f"loop-back echoed {data!r}, sent {self.text!r}")
        return data

    def describe(self) -> str:
        return "loop-back (4E)"


COMMANDS: dict[str, type[Command[Any]]] = {c.code: c for c in (
    ShortStatus, RunStop, BitAction, ReadEnableState, ReadBits, WriteBits, ReadRegisters, WriteRegisters,
    MixedRead, MixedWrite, Loopback, DetailedStatus)}


def encode_request(station: int, command: Command[Any]) -> bytes:
    return build_frame(station, command.code, command.request_data())


def decode_request(frame: Frame) -> Command[Any]:
    """Server side: rebuild the command from a request frame (raises RequestError with the code to answer)."""
    cls = COMMANDS.get(frame.command)
    if cls is None:
        raise RequestError("4", f"unknown command {frame.command}")
    return cls.from_request(frame.data)


def encode_reply(station: int, command: Command[Any], result: object = None, error: str = "0") -> bytes:
    if isinstance(command, Loopback):
        return build_frame(station, command.code, command.text)
    data = error if error != "0" else "0" + command.encode_result(result)
    return build_frame(station, command.code, data)


def encode_error(station: int, command_code: str, error: str) -> bytes:
    return build_frame(station, command_code, error)


def show_frame(frame: bytes) -> str:
    """Printable ASCII and hex of a frame, for messages: ``<STX>01400<ETX> [02 30 31 …]``."""
    text = "".join(chr(b) if 0x20 <= b < 0x7F else {STX: "<STX>", ETX: "<ETX>"}.get(b, f"<{b:02X}>") for b in frame)
    return f"{text} [{frame.hex(' ').upper()}]"


def describe_frame(frame: bytes, *, reply: bool = False) -> str:
    """Human reading of a frame for traces and error messages (never raises)."""
    try:
        parsed = split_frame(frame)
    except FrameError as exc:
        return f"unreadable frame ({exc.__class__.__name__})"
    cls = COMMANDS.get(parsed.command)
    name = cls.__name__ if cls else f"command {parsed.command}"
    if reply:
        if parsed.command == Loopback.code:
            return f"station {parsed.station:02X} {name} echo"
        error = parsed.data[:1]
        return f"station {parsed.station:02X} {name} reply, error {error} ({ERROR_CODES.get(error, '?')})"
    if cls is None:
        return f"station {parsed.station:02X} {name}"
    try:
        return f"station {parsed.station:02X} {cls.from_request(parsed.data).describe()}"
    except (RequestError, ValueError):
        return f"station {parsed.station:02X} {name} (malformed data)"


__all__ = [name for name in dir() if not name.startswith("_")]
