"""D4054 (S-35390A rate code): the manual's Table 1 lookup and the exact decoder."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from hil.families.fbs.d4054 import (
    COARSE_STEP,
    FINE_STEP,
    MISPRINTS,
    TABLE,
    RateCode,
    code_for_rate,
    code_for_steps,
    rate_for_code,
)
from hil.families.fbs.d4054_table import ROWS

# The manual's Table 1 with our decoding of every code (a copy of shared/data/d4054_s35390a.csv), kept with the
# tests so that the check of every row runs wherever the tests do.
CSV = Path(__file__).resolve().parent / "data" / "d4054_s35390a.csv"


def _csv_rows() -> list[dict[str, str]]:
    with CSV.open(newline="") as f:
        return list(csv.DictReader(f))


def test_csv_has_214_rows_and_matches_the_embedded_table() -> None:
    rows = _csv_rows()
    assert len(rows) == 214
    assert [(float(r["rate_s_per_day"]), int(r["d4054_hex"], 16)) for r in rows] == list(ROWS)


def test_every_consistent_row_is_reproduced() -> None:
    consistent = [r for r in _csv_rows() if not r["note"]]
    assert len(consistent) == 212
    for row in consistent:
        assert code_for_rate(float(row["rate_s_per_day"])) == int(row["d4054_hex"], 16), row


def test_every_code_decodes_exactly_as_the_csv_says() -> None:
    for row in _csv_rows():
        decoded = rate_for_code(int(row["d4054_hex"], 16))
        assert decoded.mode == row["mode"], row
        assert decoded.steps == int(row["steps"]), row
        # the CSV rounds to 4 places
        assert decoded.s_per_day == pytest.approx(float(row["decoded_s_per_day"]), abs=6e-5), row


def test_manual_worked_examples() -> None:
    assert code_for_rate(3.38) == 0x56E5  # PLC fast by 3.38 s/day
    assert code_for_rate(-5.62) == 0x5603  # PLC slow by 5.62 s/day
    assert code_for_rate(0.0) == 0x0000


def test_misprints_return_the_consistent_codes() -> None:
    assert code_for_rate(2.05) == 0x5619
    assert code_for_rate(1.63) == 0x56C9
    assert rate_for_code(0x5619) == RateCode("fine", 24, 24 * FINE_STEP)
    assert rate_for_code(0x56C9).steps == 19 and rate_for_code(0x56C9).mode == "fine"
    assert MISPRINTS == {2.05: (0x5618, 0x5619), 1.63: (0x56C8, 0x56C9)}
    assert dict(ROWS)[2.05] == 0x5618 and dict(TABLE)[2.05] == 0x5619  # printed vs corrected
    # the fine-mode run of the corrected table steps by exactly one at every row
    fine = [rate_for_code(code).steps for _, code in TABLE if rate_for_code(code).mode == "fine"]
    assert fine == list(range(63, 0, -1)) + list(range(-1, -65, -1))


def test_nearest_listed_rate_and_deterministic_ties() -> None:
    assert code_for_rate(3.37) == 0x56E5  # nearest listed: 3.38
    assert code_for_rate(3.34) == 0x56E5  # 3.38 is 0.04 away, 3.29 is 0.05
    assert code_for_rate(3.33) == 0x5665  # 3.29 is 0.04 away, 3.38 is 0.05
    assert code_for_rate(0.04) == 0x0000
    assert code_for_rate(0.05) == 0x5681
    assert code_for_rate(0.045) == 0x0000  # halfway: the smaller correction
    assert code_for_rate(-0.045) == 0x0000
    assert code_for_rate(5.55) == 0x56FD  # halfway between 5.54 (fine) and 5.56 (coarse)
    assert code_for_rate(16.61) == 0x56FC and code_for_rate(-16.88) == 0x5602  # range edges inclusive
    assert code_for_rate(3.3800000000001) == code_for_rate(3.38)


@pytest.mark.parametrize("rate", [16.62, -16.89, 100.0, float("inf"), float("nan")])
def test_out_of_range_rates_raise(rate: float) -> None:
    with pytest.raises(ValueError, match="s/day"):
        code_for_rate(rate)


@pytest.mark.parametrize("code", [0x5700, 0x0056, 0x1234, 0xFFFF, 0x10000, -1, "56E5", 3.0, True])
def test_malformed_codes_raise(code: object) -> None:
    with pytest.raises(ValueError, match="D4054"):
        rate_for_code(code)  # type: ignore[arg-type]


def test_decoder_covers_every_56xx_code_exactly() -> None:
    seen = set()
    for low in range(256):
        code = 0x5600 | low
        decoded = rate_for_code(code)
        assert decoded.mode in ("fine", "coarse")
        assert -64 <= decoded.steps <= 63
        step = FINE_STEP if decoded.mode == "fine" else COARSE_STEP
        assert decoded.s_per_day == decoded.steps * step  # exact: the steps are binary fractions
        assert code_for_steps(decoded.mode, decoded.steps) == code
        seen.add((decoded.mode, decoded.steps))
    assert len(seen) == 256
    assert rate_for_code(0x0000).s_per_day == 0.0


def test_decoding_example_bits() -> None:
    # 56E5H: low byte 11100101 reversed = 10100111: fine, steps 0100111 = +39 → 3.427734375 s/day
    assert rate_for_code(0x56E5) == RateCode("fine", 39, 39 * FINE_STEP)
    # 5603H: 00000011 reversed = 11000000: fine, steps 1000000 = −64
    assert rate_for_code(0x5603).steps == -64 and rate_for_code(0x5603).s_per_day == -5.625
    assert rate_for_code(0x56FC) == RateCode("coarse", 63, 63 * COARSE_STEP)


def test_code_for_steps_rejects_bad_input() -> None:
    with pytest.raises(ValueError):
        code_for_steps("medium", 1)
    with pytest.raises(ValueError):
        code_for_steps("fine", 64)
