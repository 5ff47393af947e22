"""The core sections of a bench profile, declared once (:mod:`hil.bench.schema`): [bench], [safety], [emulator],
[wire_faults] and [history] (and [labgrid], declared by the lab in :mod:`hil.bench.lab.spec`).  The families
declare theirs beside their parsers ([rtc], [s7], …)."""

from __future__ import annotations

from typing import Any

from hil.bench.capabilities import DECLARABLE
from hil.bench.family_registry import installed
from hil.bench.lab.spec import LABGRID
from hil.bench.schema import Key, Section
from hil.io.url import parse_target
from hil.sim.pacing import LineRate
from hil.sim.timing import MODES as TIMING_MODES
from hil.sim.wire_faults import KINDS

ELEMENT = r"[A-Z]+[0-9]+"


def _target(value: str) -> bool:
    parse_target(value)  # a TargetError names the forms that are understood
    return True


def _scan_range(value: list) -> bool | str:
    """``[MIN, MAX]`` in ms, 0.1 ≤ MIN ≤ MAX ≤ 1000 (the range of ``scan_time_ms``)."""
    if len(value) != 2 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        return "must be [MIN, MAX], two numbers of milliseconds"
    low, high = value
    return (0.1 <= low <= high <= 1000) or "must have 0.1 ≤ MIN ≤ MAX ≤ 1000 ms"


def _script(kinds: list) -> list[Any]:
    return [None if kind == "none" else kind for kind in kinds]


STRINGS = {"type": "array", "items": {"type": "string"}}

BENCH = Section("bench", "Which PLC, over which wire, and how the harness paces itself on it.", (
    Key("name", str, "The bench's name, in reports and locks; benches in one run must differ.", required=True,
        example="oven-line-1"),
    Key("target", str, "The URL that reaches the PLC (docs/targets.md): emulator, or SCHEME://HOST:PORT of a wire "
        "an installed family speaks (hil emulate --help lists them).", "emulator",
        check=_target),
    Key("station", int, "The PLC's address on its wire (the station or unit id its protocol takes), used on every "
        "wire and command; a target URL naming another is refused.", None, low=1, high=254,
        default_doc="the one the target names, else 1"),
    Key("time_scale", float, "Bench seconds per wall second: > 1 only for an accelerated external emulator "
        "(hil emulate --time-scale).", 1.0, above=0),
    Key("settle_scans", int, "Status round trips after a write before reading its effect (raise it on port 2, "
        "which answers within a scan).", 2, low=1),
    Key("timeout", float, "Seconds to wait for each reply.", 2.0, above=0, unit="s"),
    Key("family", str, "The controller family plug-in: picks the device layer, the emulator and the suites.",
        choices=lambda: sorted(installed()), default_doc="the installed default family"),
    Key("scan_counter", str, "A word register the bench ladder adds 1 to every scan (fixtures/ladder.md): proves "
        "scans from the PLC's side.", pattern=ELEMENT, hint="must name one word register (letters, then digits)"),
    Key("answers_at_scan_end", bool, "The wire reaches a port that services each request at a scan's end (the "
        "family's manual says which ports do): settles rely on that rule, a round trip per scan, rather than prove "
        "each scan with two reads of the scan counter (which still brackets what counts scans). Leave it out for "
        "the Ethernet modules, which may answer within a scan.", False),
    Key("scratch", list, "Element ranges nobody else uses, for the smoke suite (add them to [safety] writable).",
        [], pattern=rf"{ELEMENT}(-{ELEMENT})?", hint="must be a list of element ranges (FIRST-LAST)",
        convert=tuple, json={"items": {"type": "string"}}),
    Key("offers", list, "What no wire can detect and the bench's owner vouches for: "
        + "; ".join(f"{name}: {why}" for name, why in DECLARABLE.items()) + ".", [], choices=tuple(DECLARABLE),
        convert=tuple, json={"items": {"type": "string"}}),
    Key("plc_id", str, "The PLC's name on this site: one lock and one journal whatever wire reaches it.",
        pattern=r"[A-Za-z0-9][A-Za-z0-9._:/-]{0,63}",
        hint="must be a name of 1–64 letters, digits and . _ : / - (e.g. \"line-3-plc-2\")", example="line-3-plc-2"),
))

SAFETY = Section("safety", "What the harness may write: anything else is refused before a byte is sent.", (
    Key("writable", list, "Element ranges the tests may write (FIRST-LAST in the family's address model): "
        "journaled first, put back and read back after each test.", [], convert=tuple, json=STRINGS),
    Key("volatile", list, "Values the PLC rewrites itself: never journaled nor restored.", convert=tuple,
        default_doc="the family's own (its clock's read-out)", json=STRINGS),
    Key("allow_destructive", bool, "Allow RUN/STOP and other actions that change what the PLC does.", False),
))

EMULATOR = Section("emulator", "The emulated PLC (emulator targets only).", (
    Key("scan_time_ms", float, "Length of one scan.", 10.0, low=0.1, high=1000, unit="ms", live=False),
    Key("seed", int, "Seeds the plant's noise and bench timing: one number replays the emulated PLC.", 0, live=False),
    Key("line", str, "The pace of the emulator's pty wires, e.g. \"9600 7E1\"; unpaced without.", live=False,
        convert=LineRate.parse, example="9600 7E1"),
    Key("timing", str, "\"bench\": what the manual lets happen later happens later, at phases drawn from seed; "
        "\"instant\": at once.", "instant", choices=TIMING_MODES, live=False),
    Key("scan_time_range", list, "[MIN, MAX] ms: each scan's length drawn from it (bench timing only).",
        attr="scan_time_range_ms", check=_scan_range, convert=tuple, live=False,
        example=[5.0, 15.0], json={"items": {"type": "number"}, "minItems": 2, "maxItems": 2}),
))

PROBABILITY = "must be a probability 0–1"
WIRE_FAULTS = Section("wire_faults", "Faults the emulator's servers put on the wire (emulator+… targets only).", (
    Key("seed", int, "Seeds the faults' draws.", 0, live=False),
    Key("delay_seconds", float, "How long a \"delay\" holds a reply.", 1.0, low=0, high=60, unit="s", live=False),
    Key("split_gap", float, "Seconds between the halves of a \"split\" reply.", 0.005, low=0, high=5, unit="s",
        live=False),
    Key("script", list, "Faults in order, one per reply (\"none\": no fault), before the probabilities apply.", [],
        choices=(*KINDS, "none"), convert=_script, live=False, json={"items": {"type": "string"}}),
    *(Key(kind, float, f"Probability that a reply is hit by \"{kind}\".", 0.0, low=0, high=1, hint=PROBABILITY,
          live=False) for kind in KINDS),
))

HISTORY = Section("history", "Where this bench records its runs (hil history).", (
    Key("url", str, "The run-history store: sqlite:///PATH, postgresql://… or \"off\"; the default store "
        "without.", attr="history_url", pattern=r".*\S.*",
        hint="must be a URL (sqlite:///PATH, postgresql://…) or 'off'", example="sqlite:///runs.db"),
))


#: every core section, in the order the docs and the template show them
CORE = (BENCH, SAFETY, EMULATOR, WIRE_FAULTS, HISTORY, LABGRID)
