"""Smoke: the PLC answers, and a user register and relay round-trip through the bench's wire.

The scratch registers and relays come from the profile (``[bench] scratch``, ranges nobody else uses); without
them the round trips skip, saying so."""

import re

import pytest

from hil.families.fbs.address import WORD_BANKS

WORDS = ("R", "D")  # 16-bit registers a ladder leaves free
BITS = ("M",)


def _scratch(bench, kinds, need):
    """The first ``need`` elements of the first scratch range of one of ``kinds`` that is long enough."""
    for span in bench.profile.scratch:
        first, _, last = span.partition("-")
        kind, start = re.fullmatch(r"([A-Z]+)(\d+)", first).groups()
        end = int(re.fullmatch(r"[A-Z]+(\d+)", last or first).group(1))
        if kind in kinds and end - int(start) + 1 >= need:
            names = [f"{kind}{n}" for n in range(int(start), int(start) + need)]
            reason = bench.cannot_reach(f"{names[0]}-{names[-1]}")
            if reason:
                pytest.skip(f"the scratch range {span} cannot be used: {reason}")
            return names
    pytest.skip(f"the bench profile names no scratch {'/'.join(kinds)} range of {need} ([bench] scratch = "
                f"[\"R1000-R1099\", \"M1000-M1015\"]: elements nobody else uses, in [safety] writable)")




@pytest.mark.spec("FATEK-STAT-1")
def test_plc_answers_status(bench):
    status = bench.plc.status()
    # The suites need a PLC in RUN; None means the wire has no status command (Modbus) but the PLC answered.
    assert status.running in (True, None), f"PLC reports {status.summary()}"


@pytest.mark.spec("FATEK-REG-1")
def test_user_register_round_trip(bench):
    first = _scratch(bench, WORDS, 3)[0]
    bench.plc.io.write_words(first, [0x1234, 0xFFFF, 0])
    assert bench.plc.io.read_words(first, 3) == [0x1234, 0xFFFF, 0]


@pytest.mark.spec("FATEK-BIT-1")
def test_user_relay_round_trip(bench):
    first = _scratch(bench, BITS, 4)[0]
    bench.plc.io.write_bits(first, [1, 0, 1, 1])
    assert bench.plc.io.read_bits(first, 4) == [1, 0, 1, 1]


@pytest.mark.spec("FATEK-MIX-1")
def test_mixed_read_and_write(bench):
    word, bit = _scratch(bench, WORDS, 11)[10], _scratch(bench, BITS, 9)[8]
    bench.plc.io.write_many({word: 4321, bit: 1})
    assert bench.plc.io.read_many([word, bit]) == [4321, 1]


def _outside_allow_list(bench):
    """A register this bench's wire reaches but its profile does not let a test write: the guard's refusal is
    shown on the bench's own allow-list, never on a register we assumed nobody allows."""
    for kind in ("R", "D"):  # every R and D register of an FBs that the wire reaches
        for n in range(WORD_BANKS[kind]):
            name = f"{kind}{n}"
            if not bench.profile.can_write(name) and bench.unreachable_reason(name) is None:
                return name
    pytest.skip("every R and D register this wire reaches is in the profile's [safety] writable list: the "
                "guard has nothing to refuse here")


@pytest.mark.spec("HIL-GUARD-1")
def test_write_outside_allow_list_is_refused(bench):
    from hil.core.errors import WriteRefused
    name = _outside_allow_list(bench)
    before = bench.plc.io.read(name)
    with pytest.raises(WriteRefused, match=name):
        bench.plc.io.write_words(name, [before ^ 1])
    assert bench.plc.io.read(name) == before, f"{name} changed although the guard refused the write"
