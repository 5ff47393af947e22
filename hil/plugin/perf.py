"""Round trips and wire bytes per test, as JUnit testcase properties (loaded by :mod:`hil.plugin.pytest_plugin`).

Every bench test gets:

* ``hil_requests`` — protocol requests (round trips) from the start of its setup to the end of its teardown,
  restores included (they are part of what a test costs on a bench);
* ``hil_wire_bytes`` — bytes sent plus received on the wire (FATEK and Modbus wires; absent without a wire);
* ``hil_virtual_s`` — bench time that passed, on the in-process emulator (waits and one scan per request);
* ``hil_line_9600_s`` — on a FATEK wire: what the test would take on port 0 at 9600 bit/s 7E1 (10 bits a
  character), i.e. wire bytes × 10 / 9600 plus the bench time above; on Modbus RTU the same at 8E1 (11 bits).

:class:`WireCounter` is usable on its own (the benchmarks count bytes with it).

PYTEST_DONT_REWRITE (no asserts here: see ``pytest_plugins`` in :mod:`hil.plugin.pytest_plugin`)."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import Any

import pytest

from hil.bench.base import BenchBase
from hil.io.trace import CHAR_BITS
from hil.plugin.stash import BENCH_SESSION

BAUD = 9600


class WireCounter:
    """Counts bytes each way on a transport's wire: FATEK observers, or pymodbus's ``trace_packet`` (chained,
    so other recorders such as :class:`hil.io.trace.WireTrace` keep working)."""

    def __init__(self) -> None:
        self.tx = 0
        self.rx = 0
        self.frames = 0
        self.kind = "none"
        self.transport: Any = None  # what it counts on (a reopened bench's raw link is a new one: count anew)
        self._detach: list[Callable[[], None]] = []

    @property
    def total(self) -> int:
        return self.tx + self.rx

    def attach(self, transport: Any) -> WireCounter:
        if self._detach:
            return self
        self.transport = transport
        observers = getattr(transport, "observers", None)  # every frame of a FATEK or Modbus wire
        if isinstance(observers, list):
            self.kind = getattr(transport, "trace_kind", "frames")

            def observe(direction: str, frame: bytes) -> None:
                self._add(direction == "tx", len(frame))
            observers.append(observe)
            self._detach.append(lambda: observers.remove(observe))
        return self

    def _add(self, sending: bool, size: int) -> None:
        self.frames += 1
        if sending:
            self.tx += size
        else:
            self.rx += size

    def detach(self) -> None:
        while self._detach:
            self._detach.pop()()


@dataclass
class _Mark:
    requests: int
    wire: int
    virtual: float | None


def line_seconds(kind: str, wire_bytes: int, bench_seconds: float) -> float | None:
    """Time on a 9600 bit/s line: the characters plus the bench time (waits, a scan per request)."""
    bits = CHAR_BITS.get(kind)
    return None if bits is None else wire_bytes * bits / BAUD + bench_seconds


_MARK = pytest.StashKey[_Mark]()
_COUNTER = pytest.StashKey[WireCounter]()


def _bench(config: pytest.Config) -> BenchBase | None:
    """The open bench, or None."""
    state = config.stash.get(BENCH_SESSION, None)
    return None if state is None else state.bench


def _mark(config: pytest.Config, bench: BenchBase) -> _Mark:
    raw = bench.raw
    counter = config.stash.get(_COUNTER, None)
    if counter is None or counter.transport is not raw:  # re-attach if the bench was reopened
        counter = WireCounter().attach(raw)
        config.stash[_COUNTER] = counter
    emulator = raw.emulator
    return _Mark(raw.requests, counter.total, emulator.now if emulator is not None else None)


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    if "bench" not in getattr(item, "fixturenames", ()):
        return
    bench = _bench(item.config)
    if bench is not None and hasattr(bench, "raw"):
        item.stash[_MARK] = _mark(item.config, bench)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item,
                              call: pytest.CallInfo[None]) -> Generator[None, pytest.TestReport, pytest.TestReport]:
    if call.when == "teardown":
        start = item.stash.get(_MARK, None)
        bench = _bench(item.config)
        if start is not None and bench is not None:
            with contextlib.suppress(Exception):  # counting never breaks a test
                _record(item, start, _mark(item.config, bench))
    return (yield)


def _record(item: pytest.Item, start: _Mark, end: _Mark) -> None:
    props = item.user_properties
    props.append(("hil_requests", end.requests - start.requests))
    counter = item.config.stash[_COUNTER]
    if counter.kind != "none":
        props.append(("hil_wire_bytes", end.wire - start.wire))
    bench_s = 0.0
    if start.virtual is not None and end.virtual is not None:
        bench_s = end.virtual - start.virtual
        props.append(("hil_virtual_s", round(bench_s, 3)))
    line = line_seconds(counter.kind, end.wire - start.wire, bench_s)
    if line is not None and start.virtual is not None:
        props.append(("hil_line_9600_s", round(line, 3)))


__all__ = ["WireCounter", "line_seconds"]
