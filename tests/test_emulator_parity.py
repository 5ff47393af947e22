"""The in-process emulator answers as the wire does (issue 24): the same requests — every address class at and past
each limit, the elements an FBs does not have, bad values — through ``emulator`` and each emulator wire, and the
same outcome (refused, or the same value) from each.  A test that passes in process and fails on a PLC is the trap
the in-process emulator must never set."""

from __future__ import annotations

from functools import partial

import pytest

from hil.core.errors import HilError
from hil.families.fbs.address import (
    BIT_BANKS,
    COUNTER32_FIRST,
    COUNTER32_LAST,
    PACKED_16,
    PACKED_32,
    PAIRED_32,
    WORD_BANKS,
)
from hil.families.fbs.transport.factory import open_transport

WIRES = ["emulator+fatek-tcp", "emulator+fatek-serial", "emulator+modbus-tcp", "emulator+modbus-rtu"]


def _edges() -> list[tuple[str, str, int]]:
    """(operation, element, count): each class's first and last element, one past its last, runs over its end."""
    reads: list[tuple[str, str, int]] = []
    for kind, size in BIT_BANKS.items():
        reads += [("bits", f"{kind}0", 1), ("bits", f"{kind}{size - 1}", 1), ("bits", f"{kind}{size}", 1),
                  ("bits", f"{kind}{size - 2}", 2), ("bits", f"{kind}{size - 2}", 3)]
    for kind, size in WORD_BANKS.items():
        reads += [("words", f"{kind}0", 1), ("words", f"{kind}{size - 1}", 1), ("words", f"{kind}{size}", 1),
                  ("words", f"{kind}{size - 1}", 2)]
    for kind, bank in {**PACKED_16, **PACKED_32}.items():
        span = 16 if kind in PACKED_16 else 32
        last = (BIT_BANKS[bank] - span) // 8 * 8
        reads += [("words", f"{kind}0", 1), ("words", f"{kind}{last}", 1), ("words", f"{kind}{last + 8}", 1),
                  ("words", f"{kind}4", 1)]
    for kind, bank in PAIRED_32.items():
        last = WORD_BANKS[bank] - 2
        reads += [("words", f"{kind}0", 1), ("words", f"{kind}{last}", 1), ("words", f"{kind}{last + 1}", 1)]
    reads += [("words", f"DRC{COUNTER32_FIRST}", 1), ("words", f"DRC{COUNTER32_LAST}", 1),
              ("words", f"DRC{COUNTER32_FIRST - 1}", 1), ("words", f"DRC{COUNTER32_LAST + 1}", 1)]
    # the R registers an FBs does not have (R4168–R4999), at and past both edges, alone, in runs and as halves
    reads += [("words", "R4167", 1), ("words", "R4168", 1), ("words", "R4500", 1), ("words", "R4999", 1),
              ("words", "R5000", 1), ("words", "R4160", 8), ("words", "R4160", 9), ("words", "R4990", 10),
              ("words", "R4999", 2), ("words", "DR4166", 1), ("words", "DR4167", 1), ("words", "DR4998", 1),
              ("words", "DR4999", 1), ("words", "DR5000", 1), ("many", "R4167", 1), ("many", "R4168", 1),
              ("many", "DR4167", 1)]
    return reads


REQUESTS = _edges()
#: writes: the value each element already holds (a write that changes nothing), then values that do not fit
WRITES = [("R4167", None), ("R4168", None), ("R4999", None), ("R5000", None), ("DR4166", None), ("DR4167", None),
          ("D4095", None), ("M2001", None), ("Y255", None), ("R100", 0x10000), ("R100", -1), ("M0", 2),
          ("DR100", 1 << 32), ("WM0", 0x10000), ("D0", 1.5)]


def _outcome(call):
    try:
        return ("value", call())
    except HilError:
        return ("refused",)


def _run(transport) -> dict:
    outcomes: dict = {}
    for op, name, count in REQUESTS:
        if op == "bits":
            call = partial(transport.read_bits, name, count)
        elif op == "words":
            call = partial(transport.read_words, name, count)
        else:
            call = partial(transport.read_many, [name])
        outcomes[(op, name, count)] = _outcome(call)
    for name, value in WRITES:
        held = _outcome(partial(transport.read, name))
        if value is None and held[0] == "refused":
            value = 0
        elif value is None:
            value = held[1]
        outcomes[("write", name, value)] = _outcome(partial(transport.write, name, value))
    return outcomes


def _reachable(transport, key) -> bool:
    """Whether the wire's address map can name every element of the request (the default Modbus map reaches no
    R4168–R4999, R5999+, D2999+ …: such a request is refused by the client, and is compared only as refused)."""
    op, name, count = key
    try:
        from hil.families.fbs.address import span
        elements = span(name, count if op != "write" else 1)
    except HilError:
        return True  # not an element name at all: every target refuses it alike
    return all(transport.unreachable_reason(e) is None for e in elements)


def test_the_in_process_emulator_refuses_what_an_fbs_does_not_have() -> None:
    with open_transport("emulator") as transport:
        for name in ("R4168", "R4500", "R4999"):
            with pytest.raises(HilError, match="error A"):
                transport.read(name)
            with pytest.raises(HilError, match="error A"):
                transport.write(name, 0)
        assert transport.read_words("R4160", 8) == [0] * 8
        assert transport.read("R5000") == 0


@pytest.mark.parametrize("wire", WIRES)
def test_each_emulator_wire_answers_as_the_in_process_emulator(wire: str) -> None:
    with open_transport("emulator") as local:
        expected = _run(local)
    assert ("refused",) in expected.values() and any(o[0] == "value" for o in expected.values())
    with open_transport(wire) as transport:
        got = _run(transport)
        differences = []
        for key, outcome in expected.items():
            if not _reachable(transport, key):
                if got[key] != ("refused",):
                    differences.append(f"{key}: {wire} gave {got[key]} for what its map cannot reach")
            elif got[key] != outcome:
                differences.append(f"{key}: in process {outcome}, {wire} {got[key]}")
    assert not differences, "\n".join(differences)
