"""A separately started ``hil emulate`` for tests of the bench path: the suites reach it only over its wires and
its fault rig, as they would a real PLC with a relay module (no back door into the emulator)."""

from __future__ import annotations

import contextlib
import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

from hil.core.registry import WIRES
from tests import processes
from tests.conftest import REPO

#: the rig's banks (hil.families.fbs.sim.rig): the fault → its first coil when the rig starts at coil 0
RIG_FIRST_COIL = {"sensor_break": 0, "heater_open": 32, "ssr_short": 64}


def _read_endpoints(proc: subprocess.Popen, kinds: set[str], timeout: float) -> dict[str, str]:
    lines: queue.Queue[str] = queue.Queue()
    threading.Thread(target=lambda: [lines.put(line) for line in proc.stdout], daemon=True).start()
    found: dict[str, str] = {}
    deadline = time.monotonic() + timeout
    while set(found) != kinds:
        try:
            line = lines.get(timeout=0.2)
        except queue.Empty:
            if proc.poll() is not None:
                raise AssertionError(f"hil emulate exited ({proc.returncode}) after printing {found}: "
                                     f"{proc.stderr.read()[-2000:]}") from None
            if time.monotonic() > deadline:
                raise AssertionError(f"hil emulate printed only {found} within {timeout} s") from None
            continue
        kind, _, address = line.strip().partition(" ")
        found[kind] = address
    return found


@contextlib.contextmanager
def hil_emulate(profile: Path, time_scale: float, *, modbus: bool = False, broken: str | None = None,
                timing: str | None = None, seed: int | None = None) -> Iterator[dict[str, str]]:
    """``hil emulate --bench profile`` on FATEK/TCP (and Modbus/TCP with ``modbus``) with the fault rig; yields
    {"fatek-tcp": addr, "rig-modbus-tcp": addr[, "modbus-tcp": addr]}.  Stops it with SIGINT (as an operator's
    Ctrl-C) and checks that it exits cleanly.  ``broken``: "MODULE:FACTORY:DEFECT" serves a deliberately broken
    emulator instead (tests/broken_emulate.py).  ``timing`` and ``seed``: ``--timing`` and ``--seed``."""
    wires = {"fatek-tcp": "--fatek-tcp", "rig-modbus-tcp": "--rig-modbus-tcp"}
    if modbus:
        wires["modbus-tcp"] = "--modbus-tcp"
    with emulate_process(profile, time_scale, wires, broken=broken, timing=timing, seed=seed) as endpoints:
        yield endpoints


@contextlib.contextmanager
def emulate_process(profile: Path, time_scale: float, wires: dict[str, str], *, broken: str | None = None,
                    timing: str | None = None, seed: int | None = None) -> Iterator[dict[str, str]]:
    """``hil emulate --bench profile`` serving each endpoint kind of ``wires`` (kind → its option, on a free
    loopback port; a pty wire's option on a pseudo-terminal); yields kind → address (or the pty's path).  Stopped
    with SIGINT; it must exit cleanly."""
    ptys = {wire.option for wire in WIRES.values() if wire.kind == "pty"}
    options = [arg for option in wires.values() for arg in (option, *(() if option in ptys else ("127.0.0.1:0",)))]
    options += [*(("--timing", timing) if timing else ()), *(("--seed", str(seed)) if seed is not None else ())]
    proc = processes.spawn(
        [sys.executable, "-m", *(["tests.broken_emulate", broken] if broken else ["hil.cli.main", "emulate"]),
         "--no-live", "--bench", str(profile), *options, "--time-scale", str(time_scale)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO,
        env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        yield _read_endpoints(proc, set(wires), timeout=120)  # hang guard: start-up takes seconds
    except BaseException:
        processes.end(proc, signal.SIGINT, grace=3)  # a failed or interrupted test: no clean exit to prove
        raise
    # hang guard: hil emulate exits at once on SIGINT
    returncode = processes.end(proc, signal.SIGINT, grace=60)
    assert returncode == 0, f"hil emulate exited with {returncode}: {proc.stderr.read()}"


def bench_over_the_wire(profile_text: str, where: dict[str, str], time_scale: float, wire: str = "fatek-tcp",
                        url: str | None = None) -> str:
    """The emulator's profile rewritten for a bench that reaches ``hil emulate`` only over the wire: FATEK/TCP (or
    Modbus/TCP, or ``url``) target, the emulator's time scale, every ``kind = "emulator"`` fault injector on the
    rig's coils."""
    url = url or (f"fatek+tcp://{where['fatek-tcp']}" if wire == "fatek-tcp"
                  else f"modbus+tcp://{where['modbus-tcp']}?unit=1")
    text = re.sub(r'(?m)^target = "emulator"', f'target = "{url}"', profile_text)
    text = re.sub(r"(?m)^time_scale = .*", f"time_scale = {time_scale}", text)
    # the reply timeout a hang guard: hil emulate shares a busy CI host with the run, and a bench's 2 s would call
    # a reply it was slow to send lost (a write's outcome then unknown, the test in error)
    assert re.search(r"(?m)^timeout = ", text) is None, "the profile names its own reply timeout"
    text = text.replace("[bench]\n", "[bench]\ntimeout = 10.0\n", 1)

    def rig(match: re.Match) -> str:
        fault = match.group(1)
        return (f'[faults.{fault}]\nkind = "modbus-coil"\ntarget = "modbus+tcp://{where["rig-modbus-tcp"]}?unit=1"\n'
                f"first_coil = {RIG_FIRST_COIL[fault]}")
    text = re.sub(r'(?m)^\[faults\.(\w+)\]\nkind = "emulator".*$', rig, text)
    assert 'kind = "emulator"' not in text and url in text, text
    return text
