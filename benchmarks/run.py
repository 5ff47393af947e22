"""hil benchmarks: ``python benchmarks/run.py`` (from the project directory; about ten minutes, most of
them the full PLC's 24 virtual hours).

Not pass/fail tests (timings are noisy on shared machines): a rich table on the terminal and
``reports/benchmarks.json``, every figure next to a baseline measured in the same run.

1. round trips per second and registers per second on each emulator wire, and the emulator's Modbus TCP server
   against a bare pymodbus SimDevice server serving the same registers (target ≥ 0.8× its request rate);
2. wire efficiency: FATEK bytes per device operation against the fewest the frame format allows, the RTC suites'
   bytes against the same requests each in its cheapest frame, and each suite's time on a 9600 bit/s 7E1 line;
3. virtual seconds per wall second: idle, the default bench, and a full PLC (8 temperature modules, 32 points,
   32 PID loops with the thermal plant) — 24 virtual hours of the full PLC in Python (+ numpy), reported as its
   ratio to the bare CPython arithmetic of plant + PID alone (the scalar floor, measured in the same run; no goal:
   the models scan at every measurement, one path each, and a synthetic day of 32 loops is no product figure;
   ``--virtual-time-only`` runs just this);
4. wall time of ``hil run`` per emulator target;
5. bench time: the non-slow FBs suites at time scale 1 against ``hil emulate`` in real time, per suite file, over
   FATEK/TCP and over its pty paced at port 0's 9600 7E1 (``--line``), measured, side by side
   (benchmarks/bench_time.py; target ≤ 3 min; ``--bench-time-only`` runs just this);
6. RFC 2217: a round trip over ``fatek+rfc2217://`` against a raw ``socket://`` to the same ser2net exporting the
   same pty (target ≤ 1.5×), and ``modbus+rfc2217://`` against the pty opened directly;
7. the run history: ``hil run`` on the emulator recording to its default SQLite store against the same run with the
   history off, in interleaved pairs (target ≤ 1.05×; ``--history-only`` runs just this).

``--quick`` shortens every timing (a smoke run).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

from benchmarks.figures import record as record_figure  # noqa: E402
from hil.bench.profile import load_profile, profile_from_dict  # noqa: E402
from hil.plugin.perf import WireCounter  # noqa: E402

BENCH = ROOT / "fixtures" / "benches" / "emulator.toml"
TARGETS = ["emulator", "emulator+fatek-tcp", "emulator+fatek-serial", "emulator+modbus-tcp", "emulator+modbus-rtu"]
EPOCH = dt.datetime(2024, 2, 28, 12, 0, 0)
console = Console()


def rate(fn, seconds: float) -> tuple[float, int]:
    """Calls of ``fn`` per second over about ``seconds`` (after a short warm-up)."""
    for _ in range(5):
        fn()
    n, start = 0, time.perf_counter()
    deadline = start + seconds
    while True:
        fn()
        n += 1
        if n % 16 == 0 and time.perf_counter() >= deadline:
            break
    return n / (time.perf_counter() - start), n


# -- 1. round trips ----------------------------------------------------------------------------------------------
def bench_wires(seconds: float) -> list[dict]:
    from hil.families.fbs.bench import Bench
    profile = load_profile(BENCH)
    rows = []
    for target in TARGETS:
        bench = Bench(profile, target=target)
        try:
            io = bench.raw
            small, _ = rate(lambda io=io: io.read_words("R4128", 8), seconds)
            big, _ = rate(lambda io=io: io.read_words("R0", 64), seconds)
            rows.append({"target": target, "round_trips_per_s": small, "registers_per_s_8": small * 8,
                         "registers_per_s_64": big * 64, "round_trips_per_s_64": big})
        finally:
            bench.close()
    return rows


def bench_modbus_servers(seconds: float, rounds: int = 20, models: bool = True) -> dict:
    """Same client, same request (FC03 R4128 ×8), alternating: the emulator's server and a bare SimDevice.

    ``models``: the default bench's emulator (each request runs one scan of the RTC and temperature models first,
    as every request does); False: an emulator with no models (the server's own overhead)."""

    from pymodbus.client import ModbusTcpClient
    from pymodbus.server import ModbusTcpServer
    from pymodbus.simulator import DataType, SimData, SimDevice

    from hil.families.fbs.protocol.modbus_map import COIL, HOLDING, segments
    from hil.families.fbs.sim.build import build_emulator
    from hil.families.fbs.sim.plc import Emulator
    from hil.families.fbs.sim.serve_modbus import start_modbus_tcp
    from hil.sim.runtime import LoopThread
    emulator = build_emulator(load_profile(BENCH), EPOCH) if models else Emulator()
    ours = start_modbus_tcp(emulator)
    runtime = LoopThread.shared()

    async def start_bare() -> ModbusTcpServer:
        coils = [SimData(s.pdu, values=[False] * (s.pdu_end - s.pdu), datatype=DataType.BITS)
                 for s in segments(COIL)]
        holding = [SimData(s.pdu, count=s.pdu_end - s.pdu, values=0, datatype=DataType.REGISTERS)
                   for s in segments(HOLDING)]
        device = SimDevice(id=1, simdata=(coils, [SimData(0, values=[False] * 16, datatype=DataType.BITS)],
                                          holding, [SimData(0, count=1, datatype=DataType.INVALID)]))
        server = ModbusTcpServer(device, address=("127.0.0.1", 0))
        await server.serve_forever(background=True)
        return server

    bare = runtime.run(start_bare())
    bare_port = bare.transport.sockets[0].getsockname()[1]
    our_port = int(ours.address.rsplit(":", 1)[1])
    clients = {name: ModbusTcpClient("127.0.0.1", port=port, timeout=2, retries=0)
               for name, port in (("hil", our_port), ("bare", bare_port))}
    # Timings on a shared machine swing by ±30 % from one second to the next, so the two servers are measured in
    # many short interleaved rounds.  The headline is the median of the per-round ratios (each hil round against
    # the bare round next to it, so both saw the same machine); "best" compares each server's fastest round, an
    # extreme that one lucky bare round decides (seen: 0.72× best beside a 0.90× median in one run).
    per_round: dict[str, list[float]] = defaultdict(list)
    try:
        for c in clients.values():
            c.connect()
        for r in range(rounds):
            order = list(clients.items()) if r % 2 == 0 else list(reversed(clients.items()))
            for name, client in order:
                def once(client=client) -> None:
                    rr = client.read_holding_registers(4128, count=8, device_id=1)
                    assert not rr.isError(), rr
                per_round[name].append(rate(once, seconds / rounds / 2)[0])
    finally:
        for c in clients.values():
            c.close()
        ours.stop()
        runtime.run(bare.shutdown())
    ratios = sorted(h / b for h, b in zip(per_round["hil"], per_round["bare"]))
    best = {name: max(values) for name, values in per_round.items()}
    return {"hil_requests_per_s": best["hil"], "bare_requests_per_s": best["bare"],
            "ratio": ratios[len(ratios) // 2], "best_round_ratio": best["hil"] / best["bare"],
            "round_ratio_range": [ratios[0], ratios[-1]], "rounds": rounds, "target_ratio": 0.8,
            "requests_served": emulator.stats["requests"]}


# -- 2. wire efficiency -------------------------------------------------------------------------------------------
def reply_len(data_chars: int) -> int:
    return 9 + data_chars  # STX station(2) command(2) error(1) data checksum(2) ETX


def cheapest_request(frame: bytes) -> int:
    """The shortest request frame that asks the same thing of the PLC (same elements, same values)."""
    from hil.families.fbs.protocol.fatek import (
        BitAction,
        MixedRead,
        MixedWrite,
        ReadBits,
        ReadRegisters,
        WriteBits,
        WriteRegisters,
        decode_request,
        encode_request,
        split_frame,
    )
    cmd = decode_request(split_frame(frame))
    best = len(frame)
    if isinstance(cmd, WriteBits) and len(cmd.values) == 1:
        best = min(best, len(encode_request(1, BitAction(3 if cmd.values[0] else 4, cmd.address))))
    elif isinstance(cmd, (MixedRead, MixedWrite)):
        names = cmd.addresses if isinstance(cmd, MixedRead) else [a for a, _ in cmd.items]
        first = names[0]
        contiguous = all(a.kind == first.kind and a.index == first.index + i * a.words
                         for i, a in enumerate(names))
        if contiguous and first.words == 1:
            if isinstance(cmd, MixedRead):
                read = ReadBits if first.is_bit else ReadRegisters
                best = min(best, len(encode_request(1, read(first, len(names)))))
            else:
                values = [v for _, v in cmd.items]
                write = WriteBits if first.is_bit else WriteRegisters
                best = min(best, len(encode_request(1, write(first, values))))
    return best


#: where the per-operation bytes are measured: a direct line (the PLC's Ethernet module; port 0 alike), and a line
#: that may repeat replies (every read fenced)
DEVICE_OPERATIONS_TARGET = "emulator+fatek-tcp"
DEVICE_OPERATIONS_FENCED = "emulator+fatek-serial?fence=reads"


def device_operations() -> list[dict]:
    """Bytes a device procedure puts on a FATEK wire, against the fewest its steps need: on a direct line (the
    PLC's own Ethernet module; port 0 alike) and on a line that may repeat replies, where every read is fenced."""
    rows = _device_operations(DEVICE_OPERATIONS_TARGET)
    for row, fenced in zip(rows, _device_operations(DEVICE_OPERATIONS_FENCED)):
        row.update(fenced_bytes=fenced["bytes"], fenced_ratio=fenced["ratio"])
    return rows


def device_operations_figure(*, record: bool) -> list[dict]:
    """The per-operation table on the terminal; with ``record``, also as docs/figures/device-operations.json."""
    ops = device_operations()
    t = Table(title="FATEK bytes per device operation (request + reply frames; target ≤ 1.3× the fewest)")
    for col in ("operation", "round trips", "bytes", "fewest bytes", "ratio", "ms at 9600 7E1",
                "fence=reads: bytes", "ratio"):
        t.add_column(col, justify="right" if col != "operation" else "left")
    for r in ops:
        t.add_row(r["operation"], f"{r['round_trips']} (min {r['min_round_trips']})", str(r["bytes"]),
                  str(r["min_bytes"]), f"{r['ratio']:.2f}", f"{r['line_9600_ms']:.0f}", str(r["fenced_bytes"]),
                  f"{r['fenced_ratio']:.2f}")
    console.print(t)
    if record:
        where = record_figure({"direct": DEVICE_OPERATIONS_TARGET, "fenced": DEVICE_OPERATIONS_FENCED,
                               "operations": ops}, "device-operations")
        console.print(f"recorded: {where.relative_to(ROOT)}")
    return ops


def _device_operations(url: str) -> list[dict]:
    from hil.core.timebase import EmulatorTimebase
    from hil.families.fbs.device.plc import FbsPlc
    from hil.families.fbs.protocol.fatek import (
        BitAction,
        MixedRead,
        MixedWrite,
        ReadBits,
        ReadRegisters,
        ShortStatus,
        encode_request,
    )
    from hil.families.fbs.sim.build import build_emulator
    from hil.families.fbs.transport.factory import open_transport

    profile = load_profile(BENCH)
    transport = open_transport(url, emulator_factory=lambda: build_emulator(profile, EPOCH))
    plc = FbsPlc(transport, EmulatorTimebase(transport.emulator, EPOCH), settle_scans=profile.settle_scans)
    transport.status()  # the one-off detailed status (53) out of the way
    counter = WireCounter().attach(transport)
    settle = profile.settle_scans - 1  # status round trips before the request that reads the effect
    status = len(encode_request(1, ShortStatus())) + reply_len(6)
    rtc_fields = [f"R{4128 + i}" for i in range(7)]
    set_frame = len(encode_request(1, MixedWrite([("M1952", 1)] + [(n, 0) for n in rtc_fields]))) + reply_len(0)
    # The procedures' steps, each in its cheapest frame(s): every step that must be seen by settle_scans whole scans
    # before the next one is followed by `settle` status round trips (the next request ends a scan itself).
    bit_action = len(encode_request(1, BitAction(4, "M1952"))) + reply_len(0)
    read_back = min(  # M1955 and the read-out R4128–R4134 after a set: one 48 frame, or a 44 and a 46
        len(encode_request(1, MixedRead(["M1955"] + rtc_fields))) + reply_len(1 + 28),
        len(encode_request(1, ReadBits("M1955", 1))) + reply_len(1)
        + len(encode_request(1, ReadRegisters("R4128", 7))) + reply_len(28))
    minimum = {
        "rtc.read()": len(encode_request(1, ReadRegisters("R4128", 7))) + reply_len(28),
        "rtc.read_all()": len(encode_request(1, MixedRead([f"R{4128 + i}" for i in range(8)] + ["WM1952"])))
        + reply_len(36),
        "rtc.set()": set_frame + settle * status + bit_action + settle * status + read_back,
        # M1953 read as 0 a whole scan after the last request (a scan saw it), then the 1 held a scan and the 0
        # back, seen by a scan
        "rtc.adjust_30s()": settle * status + len(encode_request(1, ReadBits("M1953", 1))) + reply_len(1)
        + 2 * (bit_action + settle * status),
        "temperature.readings()": len(encode_request(1, ReadRegisters(plc_readings(profile), 32)))
        + reply_len(32 * 4),
    }
    round_trips = {"rtc.read()": 1, "rtc.read_all()": 1, "rtc.set()": 3 + 2 * settle,
                   "rtc.adjust_30s()": 3 + 3 * settle,
                   "temperature.readings()": 1}
    from hil.families.fbs.temperature import parse_temperature
    plc.temperature.config = parse_temperature(profile.areas["temperature"], str(BENCH))
    ops = {"rtc.read()": plc.rtc.read, "rtc.read_all()": plc.rtc.read_all,
           "rtc.set()": lambda: plc.rtc.set(dt.datetime(2024, 2, 29, 12, 0, 0)), "rtc.adjust_30s()": plc.rtc.adjust_30s,
           "temperature.readings()": plc.temperature.readings}
    rows = []
    try:
        for name, op in ops.items():
            before_b, before_r = counter.total, transport.requests
            op()
            used, trips = counter.total - before_b, transport.requests - before_r
            rows.append({"operation": name, "bytes": used, "round_trips": trips, "min_bytes": minimum[name],
                         "min_round_trips": round_trips[name], "ratio": used / minimum[name],
                         "line_9600_ms": used * 10 / 9600 * 1000})
    finally:
        transport.close()
    return rows


def plc_readings(profile) -> str:
    from hil.families.fbs.temperature import parse_temperature
    return str(parse_temperature(profile.areas["temperature"], str(BENCH)).readings)


class FrameRecorder:
    """A pytest plugin: every FATEK request frame and reply of the run, per test."""

    def __init__(self) -> None:
        self.frames: dict[str, list[tuple[str, bytes]]] = defaultdict(list)
        self._current: str | None = None
        self._attached = None

    def pytest_runtest_setup(self, item) -> None:
        from hil.plugin.perf import _bench
        bench = _bench(item.config)
        if bench is not None and self._attached is not bench.raw and hasattr(bench.raw, "observers"):
            bench.raw.observers.append(self._observe)
            self._attached = bench.raw
        self._current = item.nodeid

    def pytest_runtest_logfinish(self, nodeid, location) -> None:
        self._current = None

    def _observe(self, direction: str, frame: bytes) -> None:
        if self._current is not None:
            self.frames[self._current].append((direction, frame))


def suite_efficiency(target: str = "emulator+fatek-tcp") -> dict:
    """Run every suite once over FATEK: bytes and requests per suite file, against each request in its cheapest
    frame, and the time on a 9600 bit/s 7E1 line (bytes × 10 / 9600 + bench time, which holds a scan per request
    and the suites' waits)."""
    import pytest
    recorder = FrameRecorder()
    junit = Path(tempfile.mkdtemp()) / "junit.xml"
    code = pytest.main([str(ROOT / "suites"), "--bench", str(BENCH), "--target", target, "-q", "-p",
                        "no:cacheprovider", f"--junitxml={junit}", "-o", "junit_family=xunit1"],
                       plugins=[recorder])
    per_file: dict[str, dict] = defaultdict(lambda: defaultdict(float))
    for tc in ET.parse(junit).getroot().iter("testcase"):
        props = {p.get("name"): p.get("value") for p in tc.iter("property")}
        if "hil_requests" not in props:
            continue
        f = per_file[tc.get("classname").split(".")[-1]]
        f["tests"] += 1
        f["requests"] += int(props["hil_requests"])
        f["bytes"] += int(props.get("hil_wire_bytes", 0))
        f["bench_s"] += float(props.get("hil_virtual_s", 0))
        f["line_9600_s"] += float(props.get("hil_line_9600_s", 0))
    for nodeid, frames in recorder.frames.items():
        f = per_file[Path(nodeid.split("::")[0]).stem]
        f["min_bytes"] += sum(cheapest_request(fr) if d == "tx" else len(fr) for d, fr in frames)
        f["recorded_bytes"] += sum(len(fr) for _, fr in frames)
    out = {}
    for name, f in sorted(per_file.items()):
        if not f["tests"]:
            continue
        row = {k: (round(v, 3) if isinstance(v, float) and not v.is_integer() else int(v)) for k, v in f.items()}
        row.setdefault("recorded_bytes", 0)
        row.setdefault("min_bytes", 0)
        row["ratio_to_cheapest_frames"] = round(f["recorded_bytes"] / f["min_bytes"], 3) if f["min_bytes"] else None
        out[name] = row
    rtc = [v for k, v in out.items() if k.startswith("test_rtc")]
    total = {"bytes": sum(r["recorded_bytes"] for r in rtc), "min_bytes": sum(r["min_bytes"] for r in rtc),
             "requests": sum(r["requests"] for r in rtc), "line_9600_s": round(sum(r["line_9600_s"] for r in rtc), 1)}
    total["ratio"] = round(total["bytes"] / total["min_bytes"], 3) if total["min_bytes"] else None
    total["target_ratio"] = 1.5
    return {"pytest_exit": int(code), "per_suite": out, "rtc_suites": total}


# -- 3. virtual time ------------------------------------------------------------------------------------------------
def full_profile() -> tuple[object, str]:
    modules = [{"type": "6TC", "sensor": "K"}] * 4 + [{"type": "2TC", "sensor": "K"}] * 4  # 8 modules, 32 points
    base = load_profile(BENCH)
    temperature = dict(base.areas["temperature"], modules=modules)
    data = {"bench": {"name": "full"}, "rtc": {"chip": 3, "crystal_ppm": 12.5}, "temperature": temperature,
            "pid": {"en": "M0", "sn": 0, "zn": 32, "yn": "Y0", "sv": "R1000", "os": "R1040", "pr": "R1080",
                    "ir": "R1120", "dr": "R1160", "or": "R1200", "wr": "R1240"}, "plant": {}}
    try:
        return profile_from_dict(data), "8 modules, 32 points, 32 PID loops (one FUN86, Sn 0 Zn 32) + plant"
    except Exception as exc:  # noqa: BLE001 - the PID model may not have landed
        del data["pid"], data["plant"]
        return profile_from_dict(data), f"8 modules, 32 points, no PID ({type(exc).__name__}: {exc})"


def start_pid(emulator) -> None:
    mem = emulator.memory
    mem.set("M0", 1)  # EN
    mem.set("M1", 1)  # H/C = heating (0 would be cooling: PV 25 °C is far below SV, so the output would stay 0)
    mem.set("R4012", 0xFFFF)
    mem.set("R4013", 0xFFFF)
    for p in range(32):
        mem.set(f"R{1000 + p}", 1500)  # SV 150.0 °C


def virtual_time(quick: bool) -> list[dict]:
    from hil.families.fbs.sim.build import build_emulator
    from hil.families.fbs.sim.plc import Emulator
    full, full_note = full_profile()
    pid = "no PID" not in full_note

    def full_plc():
        emulator = build_emulator(full, EPOCH)
        if pid:
            start_pid(emulator)
        return emulator

    cases = [("idle (no models)", lambda: Emulator(), ""),
             ("default bench (RTC + temperature)", lambda: build_emulator(load_profile(BENCH), EPOCH), ""),
             ("full PLC", full_plc, f"{full_note}; the Python models with numpy")]
    rows = []
    hours = 2 if quick else 24
    for name, build, note in cases:
        emulator = build()
        wall = advance_timed(emulator, hours)
        # A test that polls once a virtual second (one request each) over an hour.
        emulator2 = build()
        start = time.perf_counter()
        for _ in range(3600 if not quick else 600):
            emulator2.service(lambda mem: mem.words["R"][4128])
            emulator2.advance(1.0)
        polled_wall = time.perf_counter() - start
        polled_virtual = emulator2.now
        rows.append({"configuration": name, "note": note, "virtual_hours": hours, "wall_s": wall,
                     "virtual_s_per_wall_s": hours * 3600 / wall if wall else float("inf"),
                     "scans": emulator.scans,
                     "polled_virtual_s_per_wall_s": polled_virtual / polled_wall})
    rounds = 3  # (paired rounds against the floor: a 24-hour run takes minutes, its noise is small beside it)
    full_walls, floors, ratios = full_plc_against_floor(full_plc, hours, rounds)
    full_row = next(r for r in rows if r["configuration"] == "full PLC")
    full_row["wall_s"] = min(full_walls + [full_row["wall_s"]])  # (the run above is one more)
    full_row["virtual_s_per_wall_s"] = hours * 3600 / full_row["wall_s"]
    floor = min(floors)
    rows.append({"configuration": "floor: plant + PID arithmetic alone", "virtual_hours": hours, "wall_s": floor,
                 "note": "32 points, a PID step per 4 s, no registers/schedule/alarms (plain CPython)",
                 "virtual_s_per_wall_s": hours * 3600 / floor, "scans": 0, "polled_virtual_s_per_wall_s": None,
                 "full_plc_over_floor": ratios[len(ratios) // 2], "ratio_range": [ratios[0], ratios[-1]],
                 "rounds": rounds})
    return rows


def virtual_time_table(quick: bool) -> list[dict]:
    """:func:`virtual_time`, printed: each configuration's virtual seconds per wall second, and the full PLC's
    ratio to the scalar floor (a figure, no goal)."""
    vt = virtual_time(quick)
    t = Table(title="Virtual time")
    for col in ("configuration", "virtual h", "wall s", "virtual s / wall s", "polled 1/s: virtual s / wall s"):
        t.add_column(col, justify="right" if col != "configuration" else "left")
    for r in vt:
        t.add_row(r["configuration"] + (f"\n[dim]{r['note']}[/]" if r["note"] else ""), str(r["virtual_hours"]),
                  f"{r['wall_s']:.4f}", f"{r['virtual_s_per_wall_s']:,.0f}",
                  "" if r["polled_virtual_s_per_wall_s"] is None else f"{r['polled_virtual_s_per_wall_s']:,.0f}")
    console.print(t)
    floor, full = vt[-1], vt[2]
    console.print(f"{full['virtual_hours']} h of the full PLC (the Python models + numpy): "
                  f"[bold]{full['wall_s']:.2f} s[/] at best; median of {floor['rounds']} paired rounds "
                  f"[bold]{floor['full_plc_over_floor']:.2f}×[/] "
                  f"(range {floor['ratio_range'][0]:.2f}–{floor['ratio_range'][1]:.2f}×) the bare CPython arithmetic "
                  f"of plant + PID alone ({floor['wall_s']:.2f} s at best)")
    return vt


def full_plc_against_floor(build, hours: float, rounds: int) -> tuple[list[float], list[float], list[float]]:
    """``hours`` of the full PLC and of the arithmetic floor, alternately, ``rounds`` times: (full PLC walls,
    floor walls, the per-round ratios sorted).  A shared machine's speed swings from one second to the next, and
    not alike for numpy's calls and plain CPython's loop, so each full-PLC run is set against the floor run next to
    it (their order swapped every round) and the headline is the median of those ratios."""
    fulls, floors = [], []
    for r in range(rounds):
        for part in (("full", "floor") if r % 2 == 0 else ("floor", "full")):
            if part == "floor":
                floors.append(arithmetic_floor(hours))
                continue
            fulls.append(advance_timed(build(), hours))
    return fulls, floors, sorted(f / g for f, g in zip(fulls, floors))


def advance_timed(emulator, hours: float) -> float:
    """Wall seconds for ``hours`` of virtual time and the scan at their end."""
    start = time.perf_counter()
    emulator.advance(hours * 3600)
    emulator.scan()
    return time.perf_counter() - start


def arithmetic_floor(hours: float, points: int = 32, interval: float = 4.0, pwm: float = 2.0) -> float:
    """Wall seconds CPython needs for the bare arithmetic of ``hours`` of the full PLC: per point and PID interval
    (the manual's default 4 s), the plant across the interval's PWM cycles and one PID step — no registers, no
    measurement schedule, noise, alarms or scans.  A floor for the full PLC row, measured in the same run."""
    exp = math.exp
    integral, previous, temps, outputs = [0.0] * points, [0] * points, [25.0] * points, [0] * points
    cycles = round(interval / pwm)
    start = time.perf_counter()
    for _ in range(round(hours * 3600 / interval)):
        for p in range(points):
            on = outputs[p] / 16383 * pwm
            temp = temps[p]
            for _ in range(cycles):
                temp = 325.0 + (temp - 325.0) * exp(-on / 300.0)
                temp = 25.0 + (temp - 25.0) * exp(-(pwm - on) / 300.0)
            temps[p] = temp
            pv = int(round(temp * 10))
            error = 1500 - pv
            integral[p] = min(max(integral[p] + 110 * (17 / 6000) * interval * error, -16383.0), 16383.0)
            derivative = -110 * 30 * (pv - previous[p]) / interval
            previous[p] = pv
            outputs[p] = int(min(max(round(110 * error + integral[p] + derivative), 0), 16383))
    return time.perf_counter() - start


# -- 4. hil run -------------------------------------------------------------------------------------------------------
# -- 5. bench time --------------------------------------------------------------------------------------------------
def bench_time_table(line: str) -> dict:
    """The non-slow FBs suites at time scale 1 against ``hil emulate`` in real time: over FATEK/TCP and over its
    FATEK pty paced at ``line`` (the real figure, not bytes × bit time), per suite side by side."""
    from benchmarks.bench_time import bench_times
    runs = {"FATEK/TCP": bench_times(1.0)}
    if line:
        runs[f"pty at {line}"] = bench_times(1.0, line=line)
        # hil run --lanes 2: the RTC suites' lane beside the main lane, in the main lane's idle line time
        runs[f"pty at {line}, --lanes 2"] = bench_times(1.0, line=line, lanes=2)
    t = Table(title="Bench time at time scale 1 (hil emulate in real time), per suite: tests' time s [bytes on the "
                    "wire, both ways; round trips; on a paced line what its characters alone take]")
    t.add_column("suite")
    for wire in runs:
        t.add_column(wire, justify="right")
    names = list(dict.fromkeys(n for r in runs.values() for n in r["per_suite"]))
    for name in names:
        cells = []
        for r in runs.values():
            row = r["per_suite"].get(name)
            cells.append("" if row is None else f"{row['test_time_s']:.1f}"
                         + f" [{row.get('wire_bytes', 0) / 1000:.1f} KB, {row.get('requests', 0)} round trips"
                         + (f", characters {row['characters_s']:.0f} s]" if "characters_s" in row else "]")
                         + (f" ({row['skipped']} skipped)" if row["skipped"] else "")
                         + (f" [red]{row['failures']} failed[/]" if row["failures"] else ""))
        t.add_row(name, *cells)
    t.add_row("[bold]session wall s[/]", *(f"[bold]{r['total_wall_s']:.0f}[/]" for r in runs.values()))
    console.print(t)
    console.print("target: ≤ 180 s for the non-slow set, on either wire (with lanes, a suite's tests' time overlaps "
                  "the other lane's: the session's wall time is the figure)")
    return runs


# -- 6. RFC 2217 -----------------------------------------------------------------------------------------------------
def _interleaved_ms(opens: dict, n: int) -> dict[str, float]:
    """Median ms per read of R4128 ×8 over each of ``opens``' transports (all open at once, each to its own PLC),
    ``n`` reads each, one of each in turn; connection set-up not counted."""
    import statistics
    transports = {name: opener() for name, opener in opens.items()}
    samples: dict[str, list[float]] = {name: [] for name in opens}
    try:
        for transport in transports.values():
            transport.read_words("R4128", 8)
        for _ in range(n):
            for name, transport in transports.items():
                started = time.perf_counter()
                transport.read_words("R4128", 8)
                samples[name].append(time.perf_counter() - started)
    finally:
        for transport in transports.values():
            transport.close()
    return {name: statistics.median(v) * 1000 for name, v in samples.items()}


def bench_rfc2217(n: int) -> dict:
    """Two emulators on their own ptys, one ser2net: FATEK (9600 7E1) over its RFC 2217 accepter against a raw TCP
    accepter, with ser2net's chardelay (its default, as labgrid exporters run it: a reply is held until the line has
    been quiet for a couple of characters) and without (what is left is the RFC 2217 client's own cost); Modbus RTU
    (115200 8E1) over RFC 2217 against pymodbus's client on a pty of its own (pymodbus's RTU client counts a reply
    by ``in_waiting``, which pyserial's ``socket://`` reports as 0 or 1: no raw-socket baseline)."""
    from tests.rfc2217_servers import NO_SER2NET, SER2NET, ser2net
    if SER2NET is None:
        return {"skipped": NO_SER2NET}
    from hil.families.fbs.sim.plc import Emulator
    from hil.families.fbs.transport.factory import open_transport, serve
    from hil.families.fbs.transport.modbus import ModbusTransport
    rows = []
    for wire, line, query in (("fatek-serial", "9600e71", "station=1"),
                              ("modbus-rtu", "115200e81", "unit=1&baudrate=115200&parity=E")):
        served = [serve(Emulator(), wire) for _ in range(2)]
        try:
            for chardelay in (True, False):
                fatek = wire.startswith("fatek")
                with ser2net(served[0].address, line, raw_device=served[1].address if fatek else None,
                             chardelay=chardelay) as where:
                    baseline = (lambda: open_transport(f"fatek+tcp://{where.raw}?station=1")) if fatek else \
                        (lambda served=served: ModbusTransport.rtu(served[1].address, unit=1, baudrate=115200))
                    scheme = "fatek" if fatek else "modbus"
                    url = f"{scheme}+rfc2217://{where.rfc2217}?{query}"
                    ms = _interleaved_ms({"rfc2217": lambda url=url: open_transport(url), "baseline": baseline}, n)
                rows.append({"wire": f"{'FATEK 9600 7E1' if fatek else 'Modbus RTU 115200 8E1'}",
                             "chardelay": chardelay, "rfc2217_ms": ms["rfc2217"],
                             "baseline": "socket:// to the same ser2net" if fatek else "the pty itself (no server)",
                             "baseline_ms": ms["baseline"], "ratio": ms["rfc2217"] / ms["baseline"]})
        finally:
            for handle in served:
                handle.stop()
    return {"reads": n, "rows": rows}


def hil_run_times() -> list[dict]:
    rows = []
    for target in TARGETS:
        junit = Path(tempfile.mkdtemp()) / "junit.xml"
        start = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "hil.cli.main", "run", "--target", target,
                               "--junitxml", str(junit), "--", "-q"], cwd=ROOT, capture_output=True, text=True)
        wall = time.perf_counter() - start
        root = ET.parse(junit).getroot() if junit.exists() else None
        tests = sum(int(s.get("tests", 0)) for s in root.iter("testsuite")) if root is not None else 0
        rows.append({"target": target, "wall_s": wall, "exit": proc.returncode, "tests": tests})
    return rows


def history_table(rounds: int) -> dict:
    h = history_overhead(rounds)
    console.print(f"hil run on the emulator, run history recording against off, {h['rounds']} interleaved pairs: "
                  f"median ratio [bold]{h['ratio']:.3f}×[/] (target ≤ 1.05×; pairs "
                  f"{', '.join(f'{r:.3f}' for r in h['ratios'])}; off {min(h['off_wall_s']):.1f} s, on "
                  f"{min(h['on_wall_s']):.1f} s at best; {h['runs_recorded']} runs, {h['tests_recorded']} tests "
                  f"recorded)")
    return h


def history_overhead(rounds: int) -> dict:
    """``hil run`` on the emulator with the run history recording (SQLite in a fresh state directory, as a new
    user's) against the same run with it off (``HIL_HISTORY_URL=off``), in interleaved pairs: the median of the
    paired wall-time ratios (target ≤ 1.05)."""
    import statistics
    state = Path(tempfile.mkdtemp(prefix="hil-history-bench-"))
    walls: dict[str, list[float]] = {"off": [], "on": []}
    ratios = []
    for r in range(rounds):
        pair = {}
        for mode in (("off", "on") if r % 2 == 0 else ("on", "off")):
            env = {k: v for k, v in os.environ.items() if k != "HIL_HISTORY_URL"}  # on: the default store
            env["HIL_STATE_DIR"] = str(state / mode)
            if mode == "off":
                env["HIL_HISTORY_URL"] = "off"
            out = Path(tempfile.mkdtemp())
            start = time.perf_counter()
            proc = subprocess.run([sys.executable, "-m", "hil.cli.main", "run", "--junitxml", str(out / "junit.xml"),
                                   "--html", str(out / "report.html"), "--", "-q"], cwd=ROOT, env=env,
                                  capture_output=True, text=True)
            pair[mode] = time.perf_counter() - start
            walls[mode].append(pair[mode])
            if proc.returncode not in (0, 1):
                raise RuntimeError(f"hil run ({mode}) exited {proc.returncode}: {proc.stdout[-800:]}")
        ratios.append(pair["on"] / pair["off"])
    from hil.history.store import Store
    store = Store(f"sqlite:///{state / 'on' / 'history.sqlite'}")
    recorded = store.runs()
    tests = sum(sum(r["counts"].values()) for r in recorded)
    store.close()
    return {"rounds": rounds, "off_wall_s": walls["off"], "on_wall_s": walls["on"], "ratio": statistics.median(ratios),
            "ratios": ratios, "runs_recorded": len(recorded), "tests_recorded": tests, "target_ratio": 1.05}


# -- report -----------------------------------------------------------------------------------------------------------
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short timings (a smoke run)")
    parser.add_argument("--json", default=str(ROOT / "reports" / "benchmarks.json"), help="where the JSON goes")
    parser.add_argument("--skip-run", action="store_true", help="leave out the `hil run` wall times")
    parser.add_argument("--history-only", action="store_true",
                        help="only what recording the run history adds to `hil run` (history on against off)")
    parser.add_argument("--virtual-time-only", action="store_true",
                        help="only the virtual-time figures: idle, the default bench, the full PLC against the floor")
    parser.add_argument("--bench-time-only", action="store_true",
                        help="only the bench time of the non-slow FBs suites at time scale 1, over FATEK/TCP and "
                             "over the paced serial line (--line; about 3 + 5 min)")
    parser.add_argument("--device-operations-only", action="store_true",
                        help="only the FATEK bytes per device operation (seconds, in process)")
    parser.add_argument("--record", action="store_true",
                        help="also write the FATEK bytes per device operation to docs/figures/device-operations.json, "
                             "which the documentation site's performance page shows (docs/_ext/hil_docs.py)")
    parser.add_argument("--line", default="9600 7E1",
                        help="the paced pty's line rate for the bench-time figure (default '9600 7E1', port 0's "
                             "factory setting; '' for TCP only)")
    args = parser.parse_args(argv)
    if args.device_operations_only:
        device_operations_figure(record=args.record)
        return 0
    if args.bench_time_only:
        bt = bench_time_table(args.line)
        out = Path(args.json).with_name("bench_time.json")
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(bt, indent=1))
        return 0
    if args.history_only:
        hist = history_table(1 if args.quick else 3)
        out = Path(args.json).with_name("history_overhead.json")
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(hist, indent=1))
        return 0
    seconds = 0.3 if args.quick else 1.5
    os.chdir(ROOT)
    results: dict = {"when": dt.datetime.now().isoformat(timespec="seconds"), "python": platform.python_version(),
                     "machine": platform.machine(), "cpus": os.cpu_count()}
    if args.virtual_time_only:
        results["virtual_time"] = virtual_time_table(args.quick)
        out = Path(args.json).with_name("virtual_time.json")
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(results, indent=2, default=str) + "\n")
        return 0

    results["wires"] = wires = bench_wires(seconds)
    base = wires[0]["round_trips_per_s"]
    t = Table(title="Round trips per emulator wire (FATEK/Modbus read of R4128 ×8, and of R0 ×64)")
    for col in ("target", "round trips/s", "registers/s (×8)", "registers/s (×64)", "vs in-process"):
        t.add_column(col, justify="right" if col != "target" else "left")
    for r in wires:
        t.add_row(r["target"], f"{r['round_trips_per_s']:,.0f}", f"{r['registers_per_s_8']:,.0f}",
                  f"{r['registers_per_s_64']:,.0f}", f"{r['round_trips_per_s'] / base:.3f}×")
    console.print(t)

    results["modbus_server"] = m = bench_modbus_servers(2.0 if args.quick else 10.0)
    console.print(f"Modbus TCP server: hil emulator against a bare pymodbus SimDevice, {m['rounds']} interleaved "
                  f"rounds each: median of the paired round ratios [bold]{m['ratio']:.2f}×[/] (target ≥ 0.8×), range "
                  f"{m['round_ratio_range'][0]:.2f}–{m['round_ratio_range'][1]:.2f}×; best rounds "
                  f"{m['hil_requests_per_s']:,.0f} vs {m['bare_requests_per_s']:,.0f} req/s "
                  f"({m['best_round_ratio']:.2f}×)")

    results["device_operations"] = device_operations_figure(record=args.record)

    results["suites"] = s = suite_efficiency()
    t = Table(title="Suites over FATEK (emulator+fatek-tcp): per suite file")
    for col in ("suite", "tests", "round trips", "bytes", "cheapest frames", "ratio", "bench s", "9600 7E1 line s"):
        t.add_column(col, justify="right" if col != "suite" else "left")
    for name, r in s["per_suite"].items():
        t.add_row(name, str(r["tests"]), str(r["requests"]), str(r["recorded_bytes"]), str(r["min_bytes"]),
                  f"{r['ratio_to_cheapest_frames']}", f"{r['bench_s']}", f"{r['line_9600_s']}")
    console.print(t)
    rt = s["rtc_suites"]
    console.print(f"RTC suites: {rt['requests']} round trips, {rt['bytes']} bytes vs {rt['min_bytes']} in the cheapest "
                  f"frames → [bold]{rt['ratio']}×[/] (target ≤ 1.5×); {rt['line_9600_s']} s on a 9600 7E1 line")

    results["virtual_time"] = virtual_time_table(args.quick)

    results["rfc2217"] = rf = bench_rfc2217(40 if args.quick else 200)
    if "skipped" in rf:
        console.print(f"RFC 2217 round trips: skipped — {rf['skipped']}")
    else:
        t = Table(title=f"RFC 2217 round trips: median of {rf['reads']} reads of R4128 ×8, ser2net exporting the "
                        f"emulator's pty (target ≤ 1.5× the raw socket)")
        for col in ("wire", "ser2net chardelay", "rfc2217:// ms", "baseline", "baseline ms", "ratio"):
            t.add_column(col, justify="left" if col in ("wire", "baseline") else "right")
        for r in rf["rows"]:
            t.add_row(r["wire"], "on (default)" if r["chardelay"] else "off", f"{r['rfc2217_ms']:.2f}", r["baseline"],
                      f"{r['baseline_ms']:.2f}", f"{r['ratio']:.2f}×")
        console.print(t)

    if not args.skip_run:
        results["hil_run"] = runs = hil_run_times()
        t = Table(title="hil run (all suites) per target")
        for col in ("target", "tests", "exit", "wall s", "vs in-process"):
            t.add_column(col, justify="right" if col != "target" else "left")
        for r in runs:
            t.add_row(r["target"], str(r["tests"]), str(r["exit"]), f"{r['wall_s']:.2f}",
                      f"{r['wall_s'] / runs[0]['wall_s']:.2f}×")
        console.print(t)
        results["history_overhead"] = history_table(1 if args.quick else 3)

    out = Path(args.json)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2, default=str) + "\n")
    console.print(f"JSON: {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
