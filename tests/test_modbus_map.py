"""The default FBs Modbus map (spec: "Modbus on an FBs PLC (default map)"), both ways, and its refusals."""

from __future__ import annotations

import pytest

from hil.core.errors import AddressError, UnreachableAddress
from hil.families.fbs.address import parse
from hil.families.fbs.protocol.modbus_map import (
    MAP_NAME,
    ModbusRef,
    Run,
    coalesce,
    coalesce_writes,
    decode,
    encode,
    from_modbus,
    locate,
    to_modbus,
    unmapped_in,
)

# Every row of the spec's table: (first element, last element, table, first pdu, last pdu).
ROWS = [
    ("Y0", "Y255", "coil", 0, 255),
    ("X0", "X255", "coil", 1000, 1255),
    ("M0", "M2001", "coil", 2000, 4001),
    ("S0", "S999", "coil", 6000, 6999),
    ("T0", "T255", "coil", 9000, 9255),
    ("C0", "C255", "coil", 9500, 9755),
    ("R0", "R4167", "holding", 0, 4167),
    ("R5000", "R5998", "holding", 5000, 5998),
    ("D0", "D2998", "holding", 6000, 8998),
    ("RT0", "RT255", "holding", 9000, 9255),
    ("RC0", "RC199", "holding", 9500, 9699),
]


@pytest.mark.parametrize("first,last,table,pdu_first,pdu_last", ROWS)
def test_every_row_both_ways(first: str, last: str, table: str, pdu_first: int, pdu_last: int) -> None:
    assert to_modbus(first) == ModbusRef(table, pdu_first)
    assert to_modbus(last) == ModbusRef(table, pdu_last)
    assert from_modbus(table, pdu_first) == parse(first)
    assert from_modbus(table, pdu_last) == parse(last)
    # every element in between, both ways
    a = parse(first)
    for n in range(pdu_last - pdu_first + 1):
        element = parse(f"{a.kind}{a.index + n}")
        assert to_modbus(element).pdu == pdu_first + n
        assert from_modbus(table, pdu_first + n) == element


def test_spec_examples() -> None:
    assert to_modbus("M1952") == ModbusRef("coil", 3952)
    assert to_modbus("R4128") == ModbusRef("holding", 4128)
    # FC03 at 0x1020 quantity 7 reads R4128–R4134
    assert [str(from_modbus("holding", 0x1020 + i)) for i in range(7)] == [f"R{4128 + i}" for i in range(7)]


def test_32bit_counters_take_two_registers_low_word_first() -> None:
    assert to_modbus("DRC200") == ModbusRef("holding", 9700, 2)
    assert to_modbus("DRC255") == ModbusRef("holding", 9810, 2)
    assert from_modbus("holding", 9700) == parse("DRC200")
    assert from_modbus("holding", 9701) == parse("DRC200")
    assert locate("holding", 9701) == (parse("DRC200"), 1)
    assert from_modbus("holding", 9811) == parse("DRC255")
    assert encode("DRC201", 0x12345678) == [(("holding", 9702), 0x5678), (("holding", 9703), 0x1234)]
    assert decode("DRC201", {("holding", 9702): 0x5678, ("holding", 9703): 0x1234}) == 0x12345678


def test_paired_and_packed_elements() -> None:
    assert to_modbus("DR0") == ModbusRef("holding", 0, 2)
    assert to_modbus("DD10") == ModbusRef("holding", 6010, 2)
    assert to_modbus("DRT4") == ModbusRef("holding", 9004, 2)
    assert to_modbus("DR5000") == ModbusRef("holding", 5000, 2)
    assert to_modbus("WM1952") == ModbusRef("coil", 3952, 16)
    assert to_modbus("WX8") == ModbusRef("coil", 1008, 16)
    assert to_modbus("DWY0") == ModbusRef("coil", 0, 32)
    assert encode("WY0", 0x8001)[:2] == [(("coil", 0), 1), (("coil", 1), 0)]
    assert encode("WY0", 0x8001)[15] == (("coil", 15), 1)
    assert decode("DR10", {("holding", 10): 2, ("holding", 11): 1}) == 0x10002


@pytest.mark.parametrize("name", ["D4054", "D4053", "R4168", "R6000", "D2999", "R4999", "R5999", "D4095",
                                  "DR4167", "DD2998", "DR5998"])
def test_unreachable_names_the_address_the_map_and_a_remedy(name: str) -> None:
    with pytest.raises(UnreachableAddress) as info:
        to_modbus(name)
    message = str(info.value)
    assert info.value.address == name
    assert info.value.via == MAP_NAME
    assert name in message and "default FBs Modbus map" in message
    assert "R3968" in message and "FATEK target" in message


def test_nonexistent_elements_are_address_errors() -> None:
    with pytest.raises(AddressError):
        to_modbus("M2002")  # an FBs has M0–M2001


@pytest.mark.parametrize("table,pdu", [("coil", 256), ("coil", 999), ("coil", 1256), ("coil", 4002),
                                       ("coil", 7000), ("coil", 9756), ("holding", 4168), ("holding", 4999),
                                       ("holding", 5999), ("holding", 8999), ("holding", 9256),
                                       ("holding", 9812), ("holding", 65535)])
def test_from_modbus_outside_the_map_raises(table: str, pdu: int) -> None:
    with pytest.raises(AddressError, match=f"{table} {pdu} is not in the default FBs Modbus map"):
        from_modbus(table, pdu)


def test_unknown_table_is_refused() -> None:
    with pytest.raises(ValueError, match="unknown Modbus table"):
        from_modbus("input", 0)


def test_unmapped_in_finds_the_first_hole() -> None:
    assert unmapped_in("coil", 1000, 256) is None
    assert unmapped_in("coil", 990, 20) == 990
    assert unmapped_in("coil", 1250, 10) == 1256
    assert unmapped_in("holding", 4160, 10) == 4168
    assert unmapped_in("holding", 9690, 122) is None  # RC and DRC are adjacent
    assert unmapped_in("holding", 9800, 13) == 9812


def test_coalesce_reads_merges_contiguous_units_per_table() -> None:
    runs = coalesce(["R3", "R1", "R2", "M0", "WM0", "DRC200", "RC199", "R1"])
    assert runs == [Run("coil", 2000, 16), Run("holding", 1, 3), Run("holding", 9699, 3)]


def test_coalesce_splits_at_the_limit() -> None:
    runs = coalesce([f"R{i}" for i in range(300)], limits={"coil": 2000, "holding": 125})
    assert runs == [Run("holding", 0, 125), Run("holding", 125, 125), Run("holding", 250, 50)]


def test_coalesce_refuses_before_returning_anything() -> None:
    with pytest.raises(UnreachableAddress, match="D4054"):
        coalesce(["R0", "D4054"])


def test_coalesce_writes_keeps_the_callers_order() -> None:
    out = coalesce_writes([("R0", 1), ("R1", 2), ("M1952", 1), ("R2", 3), ("DRC200", 0x10002)])
    assert out == [(Run("holding", 0, 2), [1, 2]), (Run("coil", 3952, 1), [1]), (Run("holding", 2, 1), [3]),
                   (Run("holding", 9700, 2), [2, 1])]
