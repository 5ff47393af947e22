"""Which FATEK frames carry a read or write of many named elements: the fewest bytes on the line.

A mixed read (48) or write (49) names every element (5–6 characters each, plus the value on a write); a range
read (44/46) or write (45/47) names only the first.  So a run of adjacent elements goes in a range frame when that
costs fewer characters than naming them — a frame's own characters and one more round trip (port 0 answers at the
end of a scan: a round trip costs about a scan more than its bytes, :data:`ROUND_TRIP` characters) included — and
the scattered rest in as few mixed frames as their limit allows.

Requests that fit one mixed frame stay in one frame (one range frame when they are a single run): one frame is
serviced in one scan, and callers rely on that (the RTC's time with its flags, a set's M1952 with the time) —
unless the caller says it does not (``one_scan=False``: the guard's originals, restores and read-backs).  The rest
is planned; writes keep their order (a restore writes what it must first).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from hil.core.errors import AddressError
from hil.families.fbs.address import Address
from hil.families.fbs.protocol.fatek import ReadBits, ReadRegisters, WriteBits, WriteRegisters, encode_request
from hil.families.fbs.transport.base import Limits, word_groups

#: characters a round trip costs beyond its frames' own: about a scan (10 ms ≈ 10 characters at 9600 bit/s)
ROUND_TRIP = 10
_REPLY = 9  # STX, station, command, error code, checksum, ETX around a reply's data


@dataclass(frozen=True)
class Piece:
    """One frame: the caller's positions it carries, and whether it is a range frame (from the first element)."""

    positions: tuple[int, ...]
    run: bool


def _value_chars(address: Address) -> int:
    return 1 if address.is_bit else 4 * address.words


def _range_limit(address: Address, limits: Limits) -> int:
    return limits.bits if address.is_bit else max(1, limits.words // address.words)


def _after(address: Address) -> Address | None:
    try:
        return address.offset(1)
    except (AddressError, ValueError):
        return None


def _runs(addresses: Sequence[Address]) -> list[list[int]]:
    """Positions split where the next element is not the one right after the previous (in the caller's order)."""
    runs: list[list[int]] = []
    for i, address in enumerate(addresses):
        if runs and _after(addresses[runs[-1][-1]]) == address:
            runs[-1].append(i)
        else:
            runs.append([i])
    return runs


def _chunks(run: list[int], size: int) -> Iterable[list[int]]:
    for start in range(0, len(run), size):
        yield run[start:start + size]


def _range_pays(addresses: Sequence[Address], run: list[int], limits: Limits, values: Sequence[int] | None) -> bool:
    """Does a range frame (or frames) carry this run in fewer characters than naming its elements would?"""
    first = addresses[run[0]]
    named = sum(len(addresses[i].fatek_name) + _value_chars(addresses[i]) for i in run)
    framed = 0
    for chunk in _chunks(run, _range_limit(first, limits)):
        start = addresses[chunk[0]]
        if values is None:
            read = (ReadBits if start.is_bit else ReadRegisters)(start, len(chunk))
            framed += len(encode_request(1, read)) + _REPLY + len(chunk) * _value_chars(start)
        else:
            write = (WriteBits if start.is_bit else WriteRegisters)(start, [values[i] for i in chunk])
            framed += len(encode_request(1, write)) + _REPLY
        framed += ROUND_TRIP
    return framed < named


def plan(addresses: Sequence[Address], limits: Limits, values: Sequence[int] | None = None, *,
         one_scan: bool = True) -> list[Piece]:
    """The frames for reading ``addresses`` (``values`` None) or writing ``values`` to them; ``one_scan``: keep
    what fits one frame in one frame (False: the caller does not need one scan — the guard's originals)."""
    if not addresses:
        return []
    mixed_limit = limits.mixed_read_words if values is None else limits.mixed_write_words
    runs = _runs(addresses)
    if values is None and not one_scan and len(runs) > 1:
        # a read that need not be one scan (the guard's originals, restores, read-backs) comes back by position:
        # its runs are found in address order, so blocks named apart (a test's own, then FUN86's) share frames
        order = sorted(range(len(addresses)), key=lambda i: (addresses[i].kind, addresses[i].index))
        runs = [[order[i] for i in run] for run in _runs([addresses[i] for i in order])]
    everything = tuple(range(len(addresses)))
    if len(runs) == 1 and len(addresses) <= _range_limit(addresses[runs[0][0]], limits):
        return [Piece(tuple(runs[0]), True)]  # one run: one range frame, never dearer than naming its elements
    if one_scan and sum(a.words for a in addresses) <= mixed_limit:
        return [Piece(everything, False)]  # one frame: one scan
    pieces: list[Piece] = []
    pending: list[int] = []

    def flush() -> None:
        for group in word_groups(pending, mixed_limit, key=lambda i: addresses[i]):
            pieces.append(Piece(tuple(group), False))
        pending.clear()

    for run in runs:
        if len(run) > 1 and _range_pays(addresses, run, limits, values):
            if values is not None:
                flush()  # writes keep the caller's order
            pieces += [Piece(tuple(chunk), True) for chunk in _chunks(run, _range_limit(addresses[run[0]], limits))]
        else:
            pending += run
    flush()
    return pieces


__all__ = ["Piece", "plan", "ROUND_TRIP"]
