"""Junk floods: how fast the emulator drops them and how much they slow another client — the speeds that
tests/test_flood.py used to bound and now only counts.  ``python benchmarks/bench_floods.py`` (from the project
directory; about a minute; ``--quick`` for a smoke run, ``--no-emulate`` to leave out the runs against ``hil
emulate``).

Not pass/fail (timings are noisy on shared machines): a rich table on the terminal and ``reports/bench_floods.json``,
every figure against a baseline measured in the same run:

1. the FATEK frame assembler dropping 1000 MB of STX (02H) bytes in 64 kB reads, against the same assembler
   dropping 1000 MB with no STX at all (one search a read: its cheapest path) — target ≤ 3×;
2. the Modbus RTU gate's CPU time (``thread_time``: another process taking the core does not count) for 64 MB of
   junk with no valid CRC, against 8 MB through the same gate — linear is 8×, target < 16× (it was quadratic);
3. another client's median round trip while 100 MB of junk pours into ``hil emulate`` on one connection (STX on
   FATEK/TCP, bogus MBAP headers on Modbus/TCP, no valid CRC on the Modbus RTU pty), against its idle median either
   side of the flood — target ≤ 2×.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

from hil.families.fbs.protocol.fatek import ETX, FrameAssembler, Loopback, encode_request  # noqa: E402
from hil.sim.rtu_gate import RtuGate  # noqa: E402

BENCH = ROOT / "fixtures" / "benches" / "emulator.toml"
console = Console()

FLOOD_MB = 100
FATEK_FLOOD = f"""
import socket, sys
host, port = sys.argv[1].rsplit(":", 1)
s = socket.create_connection((host, int(port)))
chunk = b"\\x02" * (1 << 20)
print("go", flush=True)
for _ in range({FLOOD_MB}):
    s.sendall(chunk)
s.shutdown(socket.SHUT_WR)
s.recv(1)
"""
# Sent at 100 MB/s, faster than a PLC Ethernet module's 100 Mbit/s port can carry (unpaced, pymodbus drops it
# within a twentieth of a second: too short to measure anybody's latency during it).
MODBUS_FLOODS = {
    "tcp": f"""
import random, socket, sys, time
host, port = sys.argv[1].rsplit(":", 1)
s = socket.create_connection((host, int(port)))
rng = random.Random(1)
bogus = b"\\x00\\x01\\x00\\x00\\xff\\xff\\x01\\x03"  # an MBAP header announcing 65535 bytes
chunk = b"".join(bogus + bytes(rng.randrange(256) for _ in range(rng.randrange(300))) for _ in range(8000))
chunk = chunk[:1 << 20]
print("go", flush=True)
for n in range({FLOOD_MB}):
    s.sendall(chunk)
    time.sleep(0.01)
s.shutdown(socket.SHUT_WR)
s.recv(1)
""",
    "rtu": f"""
import os, sys, time, tty
fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
tty.setraw(fd)
chunk = bytes((i * 7 + 3) & 0xFF for i in range(1 << 20))  # no valid CRC anywhere
print("go", flush=True)
for _ in range({FLOOD_MB}):
    view = memoryview(chunk)
    while view:
        view = view[os.write(fd, view):]
    time.sleep(0.01)
os.close(fd)
""",
}


# -- 1. the STX flood -------------------------------------------------------------------------------------------------
def assembler_drop(megabytes: int, byte: int) -> float:
    """Wall seconds for a frame assembler to drop ``megabytes`` of ``byte`` in 64 kB reads, then find a frame."""
    assembler = FrameAssembler()
    block = bytes([byte]) * 65536
    start = time.perf_counter()
    for _ in range(megabytes * 16):
        assembler.feed(block)
    frames = assembler.feed(encode_request(1, Loopback("OK")))
    elapsed = time.perf_counter() - start
    assert len(frames) == 1 and assembler.dropped >= megabytes << 20
    return elapsed


def stx_flood(rounds: int, megabytes: int) -> dict:
    """STX against no-STX junk, interleaved (each STX run set against the baseline run next to it)."""
    stx, plain = [], []
    for r in range(rounds):
        for kind in (("stx", "plain") if r % 2 == 0 else ("plain", "stx")):
            (stx if kind == "stx" else plain).append(assembler_drop(megabytes, 0x02 if kind == "stx" else 0x41))
    ratios = sorted(a / b for a, b in zip(stx, plain))
    return {"megabytes": megabytes, "stx_s": min(stx), "no_stx_s": min(plain), "ratio": ratios[len(ratios) // 2],
            "ratio_range": [ratios[0], ratios[-1]], "rounds": rounds, "target_ratio": 3.0}


# -- 2. the RTU gate --------------------------------------------------------------------------------------------------
def gate_cpu(megabytes: int) -> float:
    """CPU seconds of this thread for the RTU gate to drop ``megabytes`` of junk with no valid CRC."""
    chunk = bytes((i * 7 + 3) & 0xFF for i in range(4096))
    loop = asyncio.new_event_loop()
    try:
        forwarded: list[bytes] = []
        gate = RtuGate(loop, forwarded.append)
        start = time.thread_time()
        for _ in range(megabytes * 256):
            gate.feed(chunk)
        gate._flush()  # noqa: SLF001 - the silence that ends the flood, without waiting for it
        elapsed = time.thread_time() - start
        gate.close()
    finally:
        loop.close()
    assert forwarded == [] and gate.stats["rtu_noise_bytes"] == megabytes << 20
    return elapsed


def rtu_gate(rounds: int) -> dict:
    gate_cpu(8)  # warm up
    small = min(gate_cpu(8) for _ in range(rounds))
    large = min(gate_cpu(64) for _ in range(rounds))
    return {"cpu_s_8_mb": small, "cpu_s_64_mb": large, "ratio": large / small, "linear_ratio": 8.0,
            "target_ratio": 16.0, "rounds": rounds}


# -- 3. another client's latency during a flood -----------------------------------------------------------------------
def _fatek_ping() -> tuple[bytes, Callable[[bytes], bool]]:
    return encode_request(1, Loopback("PING")), lambda got: got.endswith(bytes([ETX]))


def _modbus_read() -> tuple[bytes, Callable[[bytes], bool]]:
    """FC03 of R0 (the emulator answers at the end of a scan, as the FATEK loop-back above)."""
    return (bytes.fromhex("000100000006010300000001"),
            lambda got: len(got) >= 6 and len(got) >= 6 + int.from_bytes(got[4:6], "big"))


def _latency(sock: socket.socket, n: int, until=None, request=_fatek_ping) -> list[float]:
    frame, complete = request()
    out = []
    for _ in range(n):
        if until is not None and until():
            break
        started = time.perf_counter()
        sock.sendall(frame)
        got = b""
        while not complete(got):
            got += sock.recv(4096)
        out.append(time.perf_counter() - started)
    return out


def flood_latency(label: str, wires: dict[str, str], client_wire: str, flood_script: str, flood_wire: str,
                  request, idle_n: int) -> dict:
    from tests.external import emulate_process
    with tempfile.TemporaryDirectory() as tmp:
        profile = Path(tmp) / "emulated.toml"
        profile.write_text(BENCH.read_text())
        with emulate_process(profile, 1, wires) as where:
            host, port = where[client_wire].rsplit(":", 1)
            sock = socket.create_connection((host, int(port)), timeout=60)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            try:
                _latency(sock, idle_n // 6, request=request)  # warm up
                idle = statistics.median(_latency(sock, idle_n, request=request))
                flood = subprocess.Popen([sys.executable, "-c", flood_script, where[flood_wire]],
                                         stdout=subprocess.PIPE, text=True)
                assert flood.stdout.readline().strip() == "go"
                started = time.monotonic()
                during = _latency(sock, 100000, until=lambda: flood.poll() is not None, request=request)
                flooded_for = time.monotonic() - started
                flood.wait(timeout=120)
                idle_after = statistics.median(_latency(sock, idle_n, request=request))
            finally:
                sock.close()
    baseline = max(idle, idle_after)  # the machine is shared: the idle figure either side of the flood
    median = statistics.median(during) if during else float("nan")
    return {"flood": label, "idle_ms": idle * 1e3, "idle_after_ms": idle_after * 1e3, "during_ms": median * 1e3,
            "requests_during": len(during), "flooded_s": flooded_for, "ratio": median / baseline,
            "target_ratio": 2.0}


def latencies(quick: bool) -> list[dict]:
    idle_n = 60 if quick else 300
    return [
        flood_latency("FATEK/TCP: STX", {"fatek-tcp": "--fatek-tcp"}, "fatek-tcp", FATEK_FLOOD, "fatek-tcp",
                      _fatek_ping, idle_n),
        flood_latency("Modbus/TCP: bogus MBAP headers", {"modbus-tcp": "--modbus-tcp"}, "modbus-tcp",
                      MODBUS_FLOODS["tcp"], "modbus-tcp", _modbus_read, idle_n // 3),
        flood_latency("Modbus RTU pty: no valid CRC", {"modbus-tcp": "--modbus-tcp", "modbus-rtu": "--modbus-rtu"},
                      "modbus-tcp", MODBUS_FLOODS["rtu"], "modbus-rtu", _modbus_read, idle_n // 3),
    ]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer rounds (a smoke run)")
    parser.add_argument("--no-emulate", action="store_true", help="leave out the latencies against hil emulate")
    parser.add_argument("--json", default=str(ROOT / "reports" / "bench_floods.json"), help="where the JSON goes")
    args = parser.parse_args(argv)
    rounds = 3 if args.quick else 7
    results: dict = {"when": time.strftime("%Y-%m-%dT%H:%M:%S")}

    results["stx_flood"] = stx = stx_flood(rounds, FLOOD_MB if args.quick else 10 * FLOOD_MB)
    console.print(f"FATEK assembler: {stx['megabytes']} MB of STX dropped in {stx['stx_s']:.3f} s at best, "
                  f"{stx['megabytes']} MB with no STX in {stx['no_stx_s']:.3f} s: median of {rounds} paired rounds "
                  f"[bold]{stx['ratio']:.2f}×[/] (range {stx['ratio_range'][0]:.2f}–{stx['ratio_range'][1]:.2f}×; "
                  f"target ≤ {stx['target_ratio']:g}×)")

    results["rtu_gate"] = gate = rtu_gate(rounds)
    console.print(f"Modbus RTU gate: 64 MB of junk {gate['cpu_s_64_mb'] * 1e3:.0f} ms CPU, 8 MB "
                  f"{gate['cpu_s_8_mb'] * 1e3:.0f} ms: [bold]{gate['ratio']:.1f}×[/] for 8× the junk "
                  f"(target < {gate['target_ratio']:g}×)")

    if not args.no_emulate:
        results["latency"] = rows = latencies(args.quick)
        t = Table(title=f"Another client's median round trip while {FLOOD_MB} MB of junk pour into hil emulate "
                        f"(target ≤ 2× idle)")
        for col in ("flood", "idle ms", "idle after ms", "during ms", "requests during", "flood s", "ratio"):
            t.add_column(col, justify="left" if col == "flood" else "right")
        for r in rows:
            t.add_row(r["flood"], f"{r['idle_ms']:.2f}", f"{r['idle_after_ms']:.2f}", f"{r['during_ms']:.2f}",
                      str(r["requests_during"]), f"{r['flooded_s']:.1f}", f"{r['ratio']:.2f}×")
        console.print(t)

    out = Path(args.json)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2) + "\n")
    console.print(f"JSON: {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
