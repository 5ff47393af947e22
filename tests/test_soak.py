"""Soak: thousands of mixed reads and writes over every emulator wire with random wire faults injected.

The claim under test: an answer is either right or a raised error — never a wrong value — no call runs past its
timeout budget, and at the end the emulator holds exactly what was intended.  A shadow model keeps, for each
scratch element, the set of values it may hold: a write that succeeded pins it, a write that raised (outcome
unknown, or failed part-way) may or may not have landed, so both stay possible; a successful read must return a
possible value and then pins it.

Replies repeated 1–50 ms later ("echo") are in the plan too: a late or repeated reply is never taken for the
answer to a later request (transaction ids on Modbus/TCP, a fence after every read on FATEK and Modbus RTU).  One
double fault no client can see through without transaction ids is kept apart: a reply that never comes (``drop``;
``close``, which on a pty is silence) while a repeated copy of an earlier reply of the same shape arrives in its
place — on FATEK or RTU that copy is the answer, byte for byte (docs/safety.md).  So on those wires the soak runs
its first half with every in-order fault, its second with echo and every fault but the losses; Modbus/TCP runs
them all at once throughout.
"""

from __future__ import annotations

import collections
import random
import time

import pytest

from hil.core.errors import HilError
from hil.families.fbs.address import parse
from hil.families.fbs.transport.factory import open_transport
from hil.sim.wire_faults import KINDS, WireFaults

WIRES = ("emulator+fatek-tcp", "emulator+fatek-udp", "emulator+fatek-serial", "emulator+modbus-tcp",
         "emulator+modbus-rtu")
RATES = {"drop": 0.006, "delay": 0.004, "corrupt": 0.006, "split": 0.02, "late": 0.006, "duplicate": 0.008,
         "garbage": 0.015, "close": 0.003}
ECHO = {"echo": 0.03}
LOSSES = ("drop", "close")
TIMEOUT = 0.1
SECONDS_PER_WIRE = 9.0  # the whole file stays well under 60 s
MAX_CALLS = 3000
WORDS = [f"R{1000 + i}" for i in range(24)]
BITS = [f"M{1000 + i}" for i in range(24)]
SLACK = 0.25  # s over the transport's own budget: thread scheduling on a loaded CI runner


class Shadow:
    def __init__(self, names: list[str]) -> None:
        self.possible: dict[str, set[int]] = {n: {0} for n in names}
        self.wrong: list[str] = []

    def wrote(self, items: list[tuple[str, int]], landed: bool | None) -> None:
        """landed: True (acknowledged), None (may or may not have)."""
        for name, value in items:
            if landed:
                self.possible[name] = {value}
            else:
                self.possible[name].add(value)

    def read(self, names: list[str], values: list[int], how: str) -> None:
        for name, value in zip(names, values):
            if value not in self.possible[name]:
                self.wrong.append(f"{how}: {name} = {value}, expected one of {sorted(self.possible[name])}")
            self.possible[name] = {value}


def phases(fenced: bool) -> list[dict[str, float]]:
    """The fault rates of each phase of a wire's soak (module docstring); ``fenced``: a wire without transaction
    ids, whose reads the transport fences (more than one request per read)."""
    if not fenced:
        return [RATES | ECHO]
    return [RATES, {kind: p for kind, p in RATES.items() if kind not in LOSSES} | ECHO]


def _soak(wire: str, seed: int) -> dict:
    faults = WireFaults(rates=dict(RATES), seed=seed, delay=TIMEOUT * 1.6, split_gap=0.003)
    rng = random.Random(seed)
    shadow = Shadow(WORDS + BITS)
    figures: dict = {"wire": wire, "calls": 0, "errors": collections.Counter(), "over_budget": []}
    with open_transport(wire, timeout=TIMEOUT, wire_faults=faults) as plc:
        read_budget, write_budget = plc.budget(False), plc.budget(True)
        plan = phases(plc.requests_per_read > 1)
        assert read_budget and write_budget
        began = time.monotonic()
        while (elapsed := time.monotonic() - began) < SECONDS_PER_WIRE and figures["calls"] < MAX_CALLS:
            done = max(elapsed / SECONDS_PER_WIRE, figures["calls"] / MAX_CALLS)  # by time or calls: the further
            faults.rates = plan[int(done * len(plan))]
            op = rng.choice(("rw", "ww", "rb", "wb", "rm", "wm"))
            bank = WORDS if op in ("rw", "ww") else BITS
            n = rng.randint(1, 4)
            start = rng.randrange(len(bank) - n + 1)
            names = bank[start:start + n]
            if op in ("rm", "wm"):
                names = rng.sample(WORDS, rng.randint(1, 3)) + rng.sample(BITS, rng.randint(1, 3))
                rng.shuffle(names)
            is_write = op.startswith("w")
            items = [(a, rng.randrange(0x10000) if a.startswith("R") else rng.randint(0, 1)) for a in names]
            # Modbus splits a mixed request into one request per table: the budget counts each.
            requests = 2 if op in ("rm", "wm") and "modbus" in wire else 1
            budget = (write_budget if is_write else read_budget) * requests + SLACK
            started = time.monotonic()
            try:
                if op == "rw":
                    shadow.read(names, plc.read_words(names[0], n), op)
                elif op == "rb":
                    shadow.read(names, plc.read_bits(names[0], n), op)
                elif op == "rm":
                    shadow.read(names, plc.read_many(names), op)
                elif op == "ww":
                    plc.write_words(names[0], [v for _, v in items])
                elif op == "wb":
                    plc.write_bits(names[0], [v for _, v in items])
                else:
                    plc.write_many(items)
                if is_write:
                    shadow.wrote(items, True)
            except HilError as exc:
                figures["errors"][type(exc).__name__] += 1
                if is_write:
                    shadow.wrote(items, None)  # may have landed (or part of it, for a split request)
            elapsed = time.monotonic() - started
            if elapsed > budget:
                figures["over_budget"].append(f"{op} {names}: {elapsed:.3f} s > {budget:.3f} s")
            figures["calls"] += 1
        figures["requests"] = plc.requests
        figures["resyncs"] = getattr(plc, "resyncs", 0)
        figures["reconnects"] = getattr(plc, "reconnects", 0)
        # The end: the wire is clean again; memory must be a value the test intended for every element.
        faults.enabled = False
        faults.queue.clear()
        memory = plc.emulator.memory
        for name in WORDS + BITS:
            value = memory.get(parse(name))
            if value not in shadow.possible[name]:
                shadow.wrong.append(f"end: emulator {name} = {value}, intended one of {sorted(shadow.possible[name])}")
        final = plc.read_many(WORDS[:8] + BITS[:8])  # a clean read over the wire agrees with memory
        assert final == [memory.get(parse(n)) for n in WORDS[:8] + BITS[:8]]
        figures["internal_errors"] = {k: v for k, v in plc.emulator.stats.items() if "internal" in k}
    figures["injected"] = dict(faults.injected)
    figures["replies"] = faults.replies
    figures["wrong"] = shadow.wrong
    return figures


@pytest.mark.matrix  # a soak: thousands of calls a wire in real time (the gate has the faults one by one)
@pytest.mark.timeout(120)
@pytest.mark.parametrize("wire", WIRES)
def test_soak_wire_faults(wire: str, capsys: pytest.CaptureFixture[str]) -> None:
    figures = _soak(wire, seed=sum(map(ord, wire)))
    injected = figures["injected"]
    with capsys.disabled():
        print(f"\nsoak {wire}: {figures['calls']} calls, {figures['requests']} requests, "
              f"{figures['replies']} replies through the fault plan, "
              f"faults injected {sum(injected.values())} "
              f"({', '.join(f'{k} {injected.get(k, 0)}' for k in KINDS)}), "
              f"errors raised {sum(figures['errors'].values())} ({dict(figures['errors'])}), "
              f"resyncs {figures['resyncs']}, reconnects {figures['reconnects']}, "
              f"over budget {len(figures['over_budget'])}, wrong values = {len(figures['wrong'])}")
    assert figures["wrong"] == []
    assert figures["over_budget"] == []
    assert figures["internal_errors"] == {}
    assert figures["calls"] >= 150  # Modbus RTU over a pty is the slowest wire (≈ 25 ms a call: fenced reads)
    assert sum(injected.values()) >= 10
