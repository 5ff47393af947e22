"""``hil emulate``: serve the emulator on real wires until SIGINT/SIGTERM, for external clients and benches."""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import math
import signal
import sys
import threading
import time
from collections.abc import Callable
from functools import partial
from typing import Any

from rich.console import Console

from hil.bench.family import build_emulator, family
from hil.bench.profile import Profile, load_profile
from hil.cli.emulate_live import LivePanel
from hil.cli.parser import Subparsers
from hil.core.errors import InvalidValue
from hil.core.paths import default_bench
from hil.core.registry import PROTOCOLS, WIRES
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs.sim.rig import start_rig_modbus_tcp
from hil.io.hosts import unresolved
from hil.io.url import serial_target
from hil.sim.engine import Engine
from hil.sim.pacing import LineRate
from hil.sim.runtime import ServerHandle
from hil.sim.timing import MODES as TIMING_MODES


def split_host_port(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not port.isascii() or not port.isdigit():
        raise InvalidValue(f"{text!r} is not HOST:PORT — give e.g. 127.0.0.1:5000 (port 0 lets the OS choose)")
    if int(port) > 65535:
        raise InvalidValue(f"{text!r}: port {port} is not a TCP port — give 0–65535 (0 lets the OS choose)")
    if host.startswith("[") and host.endswith("]"):  # [::1]:5000
        host = host[1:-1]
    return host or "127.0.0.1", int(port)


def _listening(where: str | None, start: Callable[[], ServerHandle]) -> ServerHandle:
    """Start a server; an address this host cannot listen on is the user's to fix: one line saying which."""
    try:
        return start()
    except OSError as exc:
        host = split_host_port(where)[0] if where else ""
        why = f"the host name {host!r} does not resolve" if unresolved(host) else (exc.strerror or str(exc))
        raise InvalidValue(f"cannot listen on {where or 'a pseudo-terminal'}: {why} — give an address of this host "
                           f"(127.0.0.1, 0.0.0.0 for all) and a free port (0 lets the OS choose)") from None


def _emulator_profile(bench: str, line: str | None, timing: str | None, seed: int | None) -> Profile:
    """The bench profile with the command line's ``--line``, ``--timing`` and ``--seed`` over its own."""
    profile = load_profile(bench)
    if line is not None:
        rate = LineRate.parse(line)
        profile = dataclasses.replace(profile, emulator=dataclasses.replace(profile.emulator, line=rate))
    return with_timing(profile, timing, seed)


def _serve_rig(emulator: Engine, where: str, first_coil: int) -> ServerHandle:
    """The FBs fault rig (sensor break, heater open, SSR short as Modbus/TCP coils) beside the emulator."""
    if not isinstance(emulator, Emulator):
        raise InvalidValue(f"--rig-modbus-tcp serves the FBs fault rig: this profile's emulator is "
                           f"{type(emulator).__name__}, not an FBs PLC — leave --rig-modbus-tcp out")
    host, port = split_host_port(where)
    return _listening(where, partial(start_rig_modbus_tcp, emulator, host, port, first_coil=first_coil))


def with_timing(profile: Profile, timing: str | None, seed: int | None) -> Profile:
    """``profile`` with the command line's ``--timing`` and ``--seed`` over its ``[emulator]`` keys."""
    if timing is not None and timing not in TIMING_MODES:
        raise InvalidValue(f"--timing {timing} is not a timing — give one of {', '.join(TIMING_MODES)}")
    changes: dict[str, Any] = {k: v for k, v in (("timing", timing), ("seed", seed)) if v is not None}
    if changes.get("timing") == "instant" and profile.emulator.scan_time_range_ms is not None:
        changes["scan_time_range_ms"] = None  # (the profile's scan range varies bench scans only)
    return dataclasses.replace(profile, emulator=dataclasses.replace(profile.emulator, **changes))


def client_target(kind: str, address: str, profile: Profile) -> str | None:
    """The target URL a client gives (``--target``, ``[bench] target``) to reach the endpoint ``kind`` serves at
    ``address``: the wire's scheme, a paced pty's line settings, the station the emulator answers as; None for an
    endpoint that is no PLC wire (the fault rig)."""
    wire = WIRES.get(kind)
    if wire is None:
        return None
    query: dict[str, object] = {}
    rate = profile.emulator.line
    if wire.kind == "pty":
        url = serial_target(wire.protocol, address)
        if rate is not None:
            query.update(baudrate=rate.baudrate, bytesize=rate.bytesize, parity=rate.parity, stopbits=rate.stopbits)
    else:
        url = f"{wire.protocol}+{wire.kind}://{address}"
    param = PROTOCOLS[wire.protocol].address_param
    if param is not None:
        query[param] = profile.station
    return url + ("?" + "&".join(f"{k}={v}" for k, v in query.items()) if query else "")


def paste_line(handle: ServerHandle, profile: Profile) -> str:
    """One endpoint for people: where it serves, the URL to paste, and a pty's pace."""
    target = client_target(handle.kind, handle.address, profile)
    if target is None:
        return f"{handle.kind} at {handle.address} (a fault rig: [faults.*] target = \"modbus+tcp://{handle.address}\")"
    said = f"{handle.kind} at {handle.address} — --target '{target}'"
    if WIRES[handle.kind].kind != "pty":
        return said
    rate = profile.emulator.line
    if rate is None:
        return said + " (unpaced: any line settings, no character time)"
    return said + f" (paced at {rate}: {1000 * rate.char_time:.2f} ms a character)"


def emulate(bench: str, endpoints: list[tuple[str, str | None]], time_scale: float,
            rig_modbus_tcp: str | None = None, rig_first_coil: int = 0, live: bool = False,
            line: str | None = None, timing: str | None = None, seed: int | None = None) -> int:
    """``endpoints``: (wire, "HOST:PORT" or None for ptys).  Prints ``<kind> <address>`` per endpoint.

    ``line``: "9600 7E1" paces the pty wires at that rate (over the profile's ``[emulator] line``).

    ``timing`` ("instant" or "bench") and ``seed`` override the profile's ``[emulator] timing`` and ``seed``; the
    seed in effect is printed on stderr once every endpoint listens (stdout's lines are the endpoints scripts
    parse), to replay a run.

    ``rig_modbus_tcp``: also serve a fault rig (Modbus/TCP coils: sensor break, heater open, SSR short; see
    hil.families.fbs.sim.rig).
    """
    if not (math.isfinite(time_scale) and time_scale > 0):  # before any endpoint line: scripts wait for those
        raise InvalidValue(f"--time-scale {time_scale:g} — give a positive number of virtual seconds per wall second")
    profile = _emulator_profile(bench, line, timing, seed)
    epoch = dt.datetime.now().replace(microsecond=0)
    emulator = build_emulator(profile, epoch)
    servers: list[ServerHandle] = []
    stop = threading.Event()
    # Before the first endpoint line: a client may stop us as soon as it has read it (a Ctrl-C or SIGTERM then ends
    # the run cleanly, after the start-up, rather than as an interruption).  Not stop.set() in the handler: it runs
    # in the main thread, which may hold the Event's own lock inside stop.wait() (the real-time loop waits on it
    # every scan) — set it from another thread.
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: threading.Thread(target=stop.set, daemon=True).start())
    try:
        for wire, where in endpoints:
            host, port = split_host_port(where) if where else ("127.0.0.1", 0)
            serve = partial(family(profile.family).serve, profile, emulator, wire, host, port)
            servers.append(_listening(where, serve))
            print(f"{servers[-1].kind} {servers[-1].address}", flush=True)
        if rig_modbus_tcp:
            servers.append(_serve_rig(emulator, rig_modbus_tcp, rig_first_coil))
            print(f"{servers[-1].kind} {servers[-1].address}", flush=True)
        for handle in servers:  # for people: what to paste (stdout's lines are for scripts)
            print(f"hil emulate: {paste_line(handle, profile)}", file=sys.stderr, flush=True)
        # once it serves (a usage error stays one line): the seed in effect, to replay the run
        print(f"hil emulate: seed {profile.emulator.seed}, timing {profile.emulator.timing_plan().describe()} "
              f"(replay: --timing {profile.emulator.timing} --seed {profile.emulator.seed})", file=sys.stderr,
              flush=True)
        # The clock starts at host time: catch up the whole second dropped from the epoch and the start-up
        emulator.advance_to(emulator.now + max(0.0, time.time() - epoch.timestamp()))
        if live:  # after the endpoint lines: clients parse those, the panel is for people
            with LivePanel(emulator, profile, servers, time_scale, stop):
                emulator.run_realtime(stop, time_scale)
        else:
            emulator.run_realtime(stop, time_scale)
    finally:
        for handle in servers:
            handle.stop()
    print(f"emulator stopped after {emulator.stats['requests']} requests", file=sys.stderr)
    return 0


# -- the command line -----------------------------------------------------------------------------------------------
def add_parser(sub: Subparsers, summary: str) -> None:
    emulate = sub.add_parser("emulate", help=summary,
                             epilog="examples:\n  hil emulate --fatek-tcp 127.0.0.1:5000 --modbus-tcp 127.0.0.1:5020\n"
                                    "  hil emulate --fatek-serial --time-scale 60\n"
                                    "  hil emulate --bench fixtures/benches/emulator.toml --fatek-tcp 0.0.0.0:500\n"
                                    "Prints one line per endpoint, '<kind> <address-or-pty-path>', once it listens; "
                                    "on a terminal a live panel (clock, temperatures, requests) follows. Ctrl-C "
                                    "stops.")
    emulate.add_argument("--no-live", action="store_true", help="no live panel, even on a terminal")
    emulate.add_argument("--bench", metavar="FILE", help="bench profile that configures the emulator")
    for wire in WIRES.values():  # every registered emulator wire: --NAME HOST:PORT, or --NAME for a pty
        if wire.kind == "pty":
            emulate.add_argument(wire.option, action="store_true", dest=f"wire:{wire.name}", help=wire.help)
            for alias in wire.aliases:
                emulate.add_argument(f"--{alias}", action="store_true", dest=f"wire:{wire.name}",
                                     help=argparse.SUPPRESS)
        else:
            emulate.add_argument(wire.option, metavar="HOST:PORT", dest=f"wire:{wire.name}", help=wire.help)
    emulate.add_argument("--line", metavar="'BAUD FRAME'",
                         help="pace the pseudo-terminals' characters at this line rate, e.g. '9600 7E1' (port 0's "
                              "factory setting; default: the profile's [emulator] line, else unpaced)")
    emulate.add_argument("--rig-modbus-tcp", metavar="HOST:PORT",
                         help="also serve a fault rig, a Modbus/TCP relay module: coil FIRST+point = 1 opens the "
                              "point's sensor, FIRST+32+point its heater circuit, FIRST+64+point shorts its SSR "
                              "(profile: [faults.sensor_break|heater_open|ssr_short] kind = \"modbus-coil\", "
                              "first_coil = FIRST, FIRST+32, FIRST+64)")
    emulate.add_argument("--rig-first-coil", type=int, default=0, metavar="FIRST",
                         help="the rig's first coil: temperature point 0's sensor (default 0)")
    emulate.add_argument("--time-scale", type=float, default=1.0, metavar="X",
                         help="virtual seconds per wall second (default 1)")
    emulate.add_argument("--timing", choices=("instant", "bench"),
                         help="'bench': readings, table rewrites and PID steps as late as the manual allows, scans "
                              "of varying length, at seeded phases (default: the profile's [emulator] timing)")
    emulate.add_argument("--seed", type=int, metavar="N",
                         help="the emulator's seed (timing phases, plant noise; default: the profile's [emulator] "
                              "seed); hil emulate prints the one in effect at start")

    emulate.set_defaults(func=command)


def command(args: argparse.Namespace, console: Console) -> int:
    return emulate(args.bench or str(default_bench()), asked_endpoints(args), args.time_scale, args.rig_modbus_tcp,
                   args.rig_first_coil, live=not args.no_live and console.is_terminal, line=args.line,
                   timing=args.timing, seed=args.seed)


def asked_endpoints(args: argparse.Namespace) -> list[tuple[str, str | None]]:
    """The wires the command line asks to serve: (wire, HOST:PORT) for TCP first, then (wire, None) per pty."""
    given = {name: getattr(args, f"wire:{name}") for name in WIRES}
    tcp = [w for w in WIRES.values() if w.kind != "pty"]  # TCP endpoints first, then the ptys (their order)
    found: list[tuple[str, str | None]] = [(w.name, given[w.name]) for w in tcp if given[w.name]]
    found += [(w.name, None) for w in WIRES.values() if w.kind == "pty" and given[w.name]]
    if not found:
        flags = [w.option + ("" if w.kind == "pty" else " HOST:PORT") for w in WIRES.values()]
        raise InvalidValue(f"nothing to serve — give {', '.join(flags[:-1])} or {flags[-1]} (the profile's "
                           f"family serves some of them)")
    return found
