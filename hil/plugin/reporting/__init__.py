"""Reports: the evidence a PLC is signed off on — JUnit properties and measurements, wire traces, the rich
console, and a self-contained HTML report with plots.  The pytest side lives in :mod:`hil.plugin.reporting.plugin`."""

from hil.plugin.reporting.model import Measurement, Series, TestOutcome, TestRecord

__all__ = ["Measurement", "Series", "TestOutcome", "TestRecord"]
