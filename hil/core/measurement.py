"""Measurement records, as OpenHTF keeps them: a name, a unit and limits declared before the test runs, a value
once measured, and an outcome — UNSET until then, so a test that never got to measure cannot look like a pass."""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass


class Outcome(enum.StrEnum):
    UNSET = "UNSET"  # declared, not (yet) measured
    PASS = "PASS"
    FAIL = "FAIL"


@dataclass(frozen=True)
class Measurement:
    """One measured value with its unit and limits (inclusive); either limit may be absent; ``value`` None while
    only declared."""

    name: str
    value: float | None = None
    unit: str = ""
    low: float | None = None
    high: float | None = None

    def measured(self, value: float) -> Measurement:
        """This declaration with its value."""
        return Measurement(self.name, float(value), self.unit, self.low, self.high)

    @property
    def outcome(self) -> Outcome:
        if self.value is None:
            return Outcome.UNSET
        if isinstance(self.value, float) and math.isnan(self.value):
            return Outcome.FAIL
        inside = (self.low is None or self.value >= self.low) and (self.high is None or self.value <= self.high)
        return Outcome.PASS if inside else Outcome.FAIL

    @property
    def passed(self) -> bool:
        return self.outcome is Outcome.PASS

    def limits_text(self) -> str:
        if self.low is None and self.high is None:
            return "no limits"
        if self.low is not None and self.high is not None:
            return f"[{self.low:g}, {self.high:g}]"
        return f">= {self.low:g}" if self.low is not None else f"<= {self.high:g}"

    def describe(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        shown = "(not measured)" if self.value is None else f"{self.value:g}{unit}"
        return f"{self.name} = {shown} {self.limits_text()} {self.outcome}"

    def properties(self) -> list[tuple[str, str]]:
        """JUnit testcase properties: ``hil.measure.<name>`` = value, and .unit/.low/.high/.outcome."""
        key = f"hil.measure.{self.name}"
        out = [] if self.value is None else [(key, f"{self.value:g}")]
        if self.unit:
            out.append((f"{key}.unit", self.unit))
        if self.low is not None:
            out.append((f"{key}.low", f"{self.low:g}"))
        if self.high is not None:
            out.append((f"{key}.high", f"{self.high:g}"))
        out.append((f"{key}.outcome", str(self.outcome)))
        return out
