"""What a bench can do beyond reading and writing its PLC: the capabilities a test may need (``needs(…)``).

A test states what it needs, not which target it wants; the bench says what it offers.  The in-process
emulator offers every one; a PLC on a wire (a bench, or ``hil emulate`` in another process) offers none of them.
"""

from __future__ import annotations

from hil.io.url import Target

#: capability → what it means (the skip reason quotes it)
CAPABILITIES: dict[str, str] = {
    "virtual_time": "time that jumps (a virtual day in milliseconds)",
    "power_on_state": "a PLC straight from power-on, whose defaults nobody has changed since",
    "scan_per_request": "each request serviced after exactly one scan, so bench.wait(n × scan time) is n scans",
    "power_cycle": "switching the CPU off and on on demand",
    "spec_choices": "the behaviour the spec fixes as [our choice] where the manual is silent",
    "scan_counter": "a ladder scan counter read in the same requests as the values ([bench] scan_counter, "
                    "fixtures/ladder.md)",
}


def bench_capabilities(target: Target, scan_counter: str | None = None) -> frozenset[str]:
    """What the bench reached through ``target`` offers.  A declared ladder scan counter
    (``[bench] scan_counter``) is offered wherever it is declared; the in-process emulator offers everything
    (without a declared counter it has none to read, and the tests that need one skip saying so)."""
    if target.in_process:
        return frozenset(CAPABILITIES) if scan_counter else frozenset(CAPABILITIES) - {"scan_counter"}
    return frozenset({"scan_counter"}) if scan_counter else frozenset()


def unknown(names: tuple[str, ...]) -> list[str]:
    return [n for n in names if n not in CAPABILITIES]
