"""FBs element names: parse, format (for humans and for FATEK frames), and the ranges of a main unit.

An element is a bank plus an index.  Three widths exist:

* bits        X Y M S T C                      frame form: letter + 4 digits     ``M1952``
* 16-bit      R D (5 digits) RT RC WX WY WM WS WT WC (4 digits)                  ``R04128`` ``WM0800``
* 32-bit      DR DD (5 digits) DRT DRC DWX DWY DWM DWS DWT DWC (4 digits)         ``DR00000``

W* names pack 16 consecutive bits starting at a multiple of 8; DW* pack 32.  DR/DD/DRT are two consecutive
16-bit words.  The word order of 32-bit values is unconfirmed in FATEK's documents; we take the low word at the
lower address (see ``LOW_WORD_FIRST``) and keep that choice here only.

C200–C255 are 32-bit counters on an FBs: their values are read as ``DRC200``…; ``RC`` covers C0–C199.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

from hil.core.errors import AddressError

LOW_WORD_FIRST = True  # [our choice] word order of DR/DD/DRT values

# Sizes of an FBs main unit (the largest model: FBs-MA/MC/MN).  R is modelled as one block R0–R8071
# (user, special R3840–R4167, R4168–R4999, ROR R5000–R8071); D0–D4095 includes the special D4000+.
BIT_BANKS: dict[str, int] = {"X": 256, "Y": 256, "M": 2002, "S": 1000, "T": 256, "C": 256}
WORD_BANKS: dict[str, int] = {"R": 8072, "D": 4096, "RT": 256, "RC": 200}
#: Registers inside the R block that an FBs does not have: a request that touches them gets error A (FATEK) and
#: they have no Modbus address.  Memory keeps the slots (one flat block is simpler); requests never reach them.
MISSING_R = (4168, 4999)
COUNTER32_FIRST = 200  # DRC200–DRC255: 32-bit counters
COUNTER32_LAST = 255

PACKED_16 = {"WX": "X", "WY": "Y", "WM": "M", "WS": "S", "WT": "T", "WC": "C"}
PACKED_32 = {"DWX": "X", "DWY": "Y", "DWM": "M", "DWS": "S", "DWT": "T", "DWC": "C"}
PAIRED_32 = {"DR": "R", "DD": "D", "DRT": "RT"}

BIT, WORD, DWORD = "bit", "word", "dword"

# Digits in the frame form of each kind (the name is 5, 6 or 7 characters long).
_FRAME_DIGITS: dict[str, int] = dict.fromkeys(BIT_BANKS, 4)
_FRAME_DIGITS.update({"R": 5, "D": 5, "RT": 4, "RC": 4})
_FRAME_DIGITS.update(dict.fromkeys(PACKED_16, 4))
_FRAME_DIGITS.update({"DR": 5, "DD": 5, "DRT": 4, "DRC": 4})
_FRAME_DIGITS.update(dict.fromkeys(PACKED_32, 4))

# Longest prefixes first so that "DRT" is not read as "DR" + "T…".
_KINDS = sorted(_FRAME_DIGITS, key=len, reverse=True)


@dataclass(frozen=True, order=True)
class Address:
    """One FBs element: ``Address("R", 4128)``.  Construct with :func:`parse`, which validates."""

    kind: str
    index: int

    @property
    def width(self) -> str:
        if self.kind in BIT_BANKS:
            return BIT
        if self.kind in PACKED_32 or self.kind in PAIRED_32 or self.kind == "DRC":
            return DWORD
        return WORD

    @property
    def is_bit(self) -> bool:
        return self.width == BIT

    @property
    def bits(self) -> int:
        """Value width in bits: 1, 16 or 32."""
        return {BIT: 1, WORD: 16, DWORD: 32}[self.width]

    @property
    def words(self) -> int:
        """Cost in 16-bit words inside a FATEK mixed read (bit = 1, 16-bit = 1, 32-bit = 2)."""
        return 2 if self.width == DWORD else 1

    @property
    def fatek_name(self) -> str:
        """The name as it appears inside a FATEK frame: ``R04128``, ``M1952``, ``DWM0000``."""
        return f"{self.kind}{self.index:0{_FRAME_DIGITS[self.kind]}d}"

    def __str__(self) -> str:
        return f"{self.kind}{self.index}"

    def offset(self, n: int) -> Address:
        """The element ``n`` places on in the same kind (validated)."""
        # Step by whole values so consecutive elements never overlap: WM800, WM816 …; DR0, DR2 ….
        step = self.bits if self.kind in PACKED_16 or self.kind in PACKED_32 else 2 if self.kind in PAIRED_32 else 1
        return parse(f"{self.kind}{self.index + n * step}")

    def elements(self) -> Iterator[Address]:
        """The underlying bits or 16-bit words this element covers (itself for plain bits and words)."""
        if self.kind in PACKED_16 or self.kind in PACKED_32:
            bank = PACKED_16.get(self.kind) or PACKED_32[self.kind]
            for i in range(self.bits):
                yield Address(bank, self.index + i)
        elif self.kind in PAIRED_32:
            yield Address(PAIRED_32[self.kind], self.index)
            yield Address(PAIRED_32[self.kind], self.index + 1)
        else:
            yield self


def parse(name: str | Address) -> Address:
    """Parse ``"R4128"``, ``"r04128"``, ``"M1952"``, ``"WM800"``, ``"DR0"`` … and check the model's ranges."""
    if isinstance(name, Address):
        return name
    if not isinstance(name, str):
        raise AddressError(f"an FBs element name must be a string like 'R4128', not {name!r}")
    return _parse_text(name)


def _ascii_digits(text: str) -> bool:
    """0–9 only: str.isdigit() also takes '¹' or '٣', which int() then refuses."""
    return text.isascii() and text.isdigit()


@functools.lru_cache(maxsize=8192)
def _parse_text(name: str) -> Address:
    # Cached: names are parsed on every request and every model access, and the answer (a frozen Address, or an
    # AddressError, which is not cached) depends on the text alone.
    text = name.strip().upper()
    kind = next((k for k in _KINDS if text.startswith(k) and _ascii_digits(text[len(k):])), None)
    if kind is None:
        raise AddressError(
            f"{name!r} is not an FBs element name: expected a bank letter (X Y M S T C R D RT RC, W…, D…) "
            f"followed by a number, e.g. 'R4128', 'M1952', 'WM800'")
    digits = text[len(kind):]
    if len(digits) > _FRAME_DIGITS[kind]:
        raise AddressError(f"{name!r}: {kind} takes at most {_FRAME_DIGITS[kind]} digits")
    index = int(digits)
    _check_range(name, kind, index)
    return Address(kind, index)


def _check_range(name: str, kind: str, index: int) -> None:
    if kind in BIT_BANKS:
        _within(name, kind, index, 0, BIT_BANKS[kind] - 1)
    elif kind in WORD_BANKS:
        _within(name, kind, index, 0, WORD_BANKS[kind] - 1)
    elif kind in PACKED_16 or kind in PACKED_32:
        bank = PACKED_16.get(kind) or PACKED_32[kind]
        span = 16 if kind in PACKED_16 else 32
        if index % 8:
            raise AddressError(f"{name!r}: a {kind} name must start at a multiple of 8 ({kind}{index - index % 8} "
                               f"or {kind}{index - index % 8 + 8})")
        _within(name, kind, index, 0, (BIT_BANKS[bank] - span) // 8 * 8)
    elif kind in PAIRED_32:
        _within(name, kind, index, 0, WORD_BANKS[PAIRED_32[kind]] - 2)
    elif kind == "DRC":
        _within(name, kind, index, COUNTER32_FIRST, COUNTER32_LAST)


def _within(name: str, kind: str, index: int, low: int, high: int) -> None:
    if not low <= index <= high:
        raise AddressError(f"{name!r} is outside the FBs range of {kind}: {kind}{low}–{kind}{high}")


def span(start: str | Address, count: int) -> list[Address]:
    """``count`` consecutive elements from ``start``; raises if the run leaves the bank."""
    first = parse(start)
    if count < 1:
        raise AddressError(f"count must be at least 1, not {count} (from {first})")
    try:
        return [first] + [first.offset(i) for i in range(1, count)]
    except AddressError as exc:
        raise AddressError(f"{count} elements from {first} run past the end of the bank: {exc}") from None


def parse_range(text: str) -> list[Address]:
    """``"R4128-R4135"`` or ``"M1952"`` → the elements it names (same kind at both ends)."""
    if "-" not in text:
        return [parse(text)]
    left, right = (part.strip() for part in text.split("-", 1))
    a, b = parse(left), parse(right)
    if a.kind != b.kind:
        raise AddressError(f"range {text!r} mixes {a.kind} and {b.kind}")
    if b.index < a.index:
        raise AddressError(f"range {text!r} runs backwards")
    return [Address(a.kind, i) for i in range(a.index, b.index + 1)]


def expand(ranges: Iterable[str]) -> frozenset[Address]:
    """Base elements (bits and 16-bit words) named by ``["R4128-R4135", "M1952", "WM800"]``."""
    out: set[Address] = set()
    for text in ranges:
        for element in parse_range(text):
            out.update(element.elements())
    return frozenset(out)


def missing(address: Address, count: int = 1) -> str | None:
    """Why a run of ``count`` elements from ``address`` touches elements an FBs does not have (R4168–R4999,
    which the flat R block keeps as slots), or None.  The one rule: the emulator's memory refuses such a request
    whoever makes it (in process or a wire server), the FATEK decoder answers it with error A in its place in the
    frame's order of faults, and the Modbus map has no addresses for them."""
    words = {"R": 1, "DR": 2}.get(address.kind)
    if words is None:
        return None
    first, last = address.index, address.index + count * words - 1
    low, high = MISSING_R
    if first <= high and last >= low:
        return f"{count} from {address} reaches R{max(first, low)}: an FBs has no R{low}–R{high}"
    return None


def is_valid(name: str) -> bool:
    try:
        parse(name)
    except AddressError:
        return False
    return True


__all__ = ["Address", "parse", "take_frame_name", "span", "parse_range", "expand", "is_valid", "BIT", "WORD", "DWORD",
           "BIT_BANKS", "WORD_BANKS", "PACKED_16", "PACKED_32", "PAIRED_32", "LOW_WORD_FIRST", "MISSING_R", "missing"]


def take_frame_name(text: str, pos: int = 0) -> tuple[Address, int]:
    """Read one frame-form name (``R04128``, ``M1952``…) starting at ``pos``; return it and the end position.

    Names inside FATEK frames are not delimited, so the kind decides how many digits follow.
    """
    for kind in _KINDS:
        end = pos + len(kind) + _FRAME_DIGITS[kind]
        if text.startswith(kind, pos) and end <= len(text) and text[pos + len(kind):end].isdigit():
            return parse(text[pos:end]), end
    raise AddressError(f"no FBs element name at position {pos} of {text!r}")
