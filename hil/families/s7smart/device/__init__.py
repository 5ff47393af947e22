"""The S7-200 SMART as a test sees it: the clock test program's procedures (``bench.plc``), not byte math."""
