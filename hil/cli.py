"""The ``hil`` command: run the suites, serve the emulator, probe a PLC, work its clock."""

from __future__ import annotations

import argparse
import sys

from rich.console import Console

from hil import __version__
from hil.errors import HilError

EXAMPLES = """examples:
  hil run                                   suites on the in-process emulator, JUnit in reports/junit.xml
  hil run --target emulator+fatek-serial    the same over the FATEK protocol on a pseudo-terminal
  hil run --bench my-bench.toml -- -k rtc   a real bench, RTC suites only (pytest args after --)
  hil emulate --fatek-tcp 127.0.0.1:5000    serve the emulator for external clients
  hil probe fatek+serial:///dev/ttyUSB0     status and key registers of a PLC
"""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="hil", description="Hardware-in-the-loop tests for FATEK FBs PLCs.",
                                     epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"hil {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    run = sub.add_parser("run", help="run the suites against a bench (default: the emulator)",
                         formatter_class=argparse.RawDescriptionHelpFormatter,
                         epilog="examples:\n  hil run\n  hil run --target emulator+modbus-tcp\n"
                                "  hil run --bench fixtures/benches/example-bench.toml -- -k smoke -x\n")
    run.add_argument("--bench", metavar="FILE", help="bench profile (default fixtures/benches/emulator.toml)")
    run.add_argument("--target", metavar="URL", help="target URL overriding the profile's")
    run.add_argument("--junitxml", metavar="PATH", default="reports/junit.xml",
                     help="where the JUnit XML goes (default reports/junit.xml)")
    run.add_argument("pytest_args", nargs=argparse.REMAINDER, help="after --: extra pytest arguments")

    emulate = sub.add_parser("emulate", help="serve the emulator on TCP ports and/or pseudo-terminals",
                             formatter_class=argparse.RawDescriptionHelpFormatter,
                             epilog="examples:\n  hil emulate --fatek-tcp 127.0.0.1:5000 --modbus-tcp 127.0.0.1:5020\n"
                                    "  hil emulate --fatek-pty --time-scale 60\n"
                                    "Prints one line per endpoint, '<kind> <address-or-pty-path>', once it listens.")
    emulate.add_argument("--bench", metavar="FILE", help="bench profile that configures the emulator")
    emulate.add_argument("--fatek-tcp", metavar="HOST:PORT", help="FATEK protocol on TCP (port 0: OS chooses)")
    emulate.add_argument("--modbus-tcp", metavar="HOST:PORT", help="Modbus/TCP")
    emulate.add_argument("--fatek-pty", action="store_true", help="FATEK protocol on a pseudo-terminal")
    emulate.add_argument("--modbus-pty", action="store_true", help="Modbus RTU on a pseudo-terminal")
    emulate.add_argument("--rig-modbus-tcp", metavar="HOST:PORT",
                         help="also serve a sensor-break fault rig: Modbus/TCP coil FIRST+point = 1 opens the "
                              "point's sensor (profile: [faults.sensor_break] kind = \"modbus-coil\")")
    emulate.add_argument("--rig-first-coil", type=int, default=0, metavar="N",
                         help="coil of temperature point 0 on the rig (default 0)")
    emulate.add_argument("--time-scale", type=float, default=1.0, metavar="X",
                         help="virtual seconds per wall second (default 1)")

    probe = sub.add_parser("probe", help="show a PLC's status and key registers",
                           epilog="example: hil probe fatek+tcp://192.168.1.5:500")
    probe.add_argument("url", nargs="?", help="target URL, e.g. fatek+serial:///dev/ttyUSB0 or emulator+modbus-tcp "
                                              "(default: the --bench profile's target)")
    probe.add_argument("--bench", metavar="FILE",
                       help="bench profile: its [temperature] section adds the temperature points to the report "
                            "(and configures an emulator… target)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    console = Console(stderr=False)
    try:
        return dispatch(args, console)
    except KeyboardInterrupt:
        return 130
    except (HilError, OSError, ValueError) as exc:
        if args.debug:
            raise
        Console(stderr=True).print(f"[bold red]hil {args.command}:[/] {exc}", highlight=False)
        return 2


def dispatch(args: argparse.Namespace, console: Console) -> int:
    if args.command == "run":
        from hil.commands.run import run
        extra = args.pytest_args[1:] if args.pytest_args[:1] == ["--"] else args.pytest_args
        return run(args.bench, args.target, args.junitxml, extra)
    if args.command == "emulate":
        from hil.commands.emulate import emulate
        from hil.paths import default_bench
        endpoints = [(w, a) for w, a in (("fatek-tcp", args.fatek_tcp), ("modbus-tcp", args.modbus_tcp)) if a]
        endpoints += [(w, None) for w, on in (("fatek-serial", args.fatek_pty), ("modbus-rtu", args.modbus_pty))
                      if on]
        if not endpoints:
            raise ValueError("nothing to serve: give --fatek-tcp HOST:PORT, --modbus-tcp HOST:PORT, --fatek-pty "
                             "or --modbus-pty")
        return emulate(args.bench or str(default_bench()), endpoints, args.time_scale, args.rig_modbus_tcp,
                       args.rig_first_coil)
    if args.command == "probe":
        from hil.commands.probe import probe
        if not args.url and not args.bench:
            raise ValueError("probe what? give a target URL, or --bench FILE to use the profile's target")
        return probe(args.url, console, bench=args.bench)
    raise AssertionError(args.command)


if __name__ == "__main__":
    sys.exit(main())
