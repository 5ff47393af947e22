"""Suites reach the PLC only through the ``bench`` fixture of the hil plugin (loaded by entry point)."""
