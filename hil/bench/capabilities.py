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
    "power_cycle": "switching the CPU off and on on demand",
    "spec_choices": "the behaviour the spec fixes as [our choice] where the manual is silent",
    "scan_counter": "a ladder scan counter read in the same requests as the values ([bench] scan_counter, "
                    "fixtures/ladder.md)",
}


#: what a bench profile may declare it offers (``[bench] offers = [...]``): what no wire can detect, the bench's
#: owner vouches for — and how a bench earns it (the skip reason quotes it)
DECLARABLE: dict[str, str] = {
    "power_on_state": "the bench powers its PLC on afresh before each run (a CI job's power relay, a smart plug); "
                      "the tests that need it run first in the session",
    "spec_choices": "the bench's PLC has been seen to make the spec's choices where the manual is silent",
}


def bench_capabilities(target: Target, scan_counter: str | None = None,
                       declared: tuple[str, ...] = ()) -> frozenset[str]:
    """What the bench reached through ``target`` offers.  A declared ladder scan counter
    (``[bench] scan_counter``) is offered wherever it is declared, and so is what ``[bench] offers`` declares;
    the in-process emulator offers everything (without a declared counter it has none to read, and the tests
    that need one skip saying so)."""
    counter = {"scan_counter"} if scan_counter else set()
    if target.in_process:
        return frozenset(set(CAPABILITIES) - {"scan_counter"} | counter)
    return frozenset(counter | set(declared))


def how_to_offer(name: str) -> str:
    """What a bench profile does to offer ``name``, or why none can."""
    if name == "scan_counter":
        return 'declare the bench ladder\'s counter: [bench] scan_counter = "R…" (fixtures/ladder.md)'
    if name in DECLARABLE:
        return f'declare [bench] offers = ["{name}"] when {DECLARABLE[name]}'
    return "only the in-process emulator offers it"


def unknown(names: tuple[str, ...]) -> list[str]:
    return [n for n in names if n not in CAPABILITIES]
