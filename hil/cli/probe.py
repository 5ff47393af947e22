"""``hil probe URL``: is the PLC there, what is it, and a few registers that tell its state."""

from __future__ import annotations

import argparse
from collections.abc import Callable

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from hil.bench.profile import Profile, load_profile
from hil.cli.parser import Subparsers
from hil.cli.probe_s7 import probe_s7
from hil.cli.rtc import format_time
from hil.cli.status import status_panel
from hil.cli.target import open_target
from hil.core.errors import HilError
from hil.core.timebase import HostTimebase
from hil.families.fbs.device.plc import FbsPlc
from hil.families.fbs.device.temperature import Temperature
from hil.families.fbs.registers import pair_bit
from hil.families.fbs.rtc_time import RtcTime
from hil.families.fbs.temperature import BREAK_VALUE
from hil.families.fbs.transport.base import Transport

# (label, element) — read only where the wire can reach them.
PROBE_REGISTERS = [
    ("RTC chip (D4053)", "D4053"), ("RTC rate code (D4054)", "D4054"),
    ("PID timing R4005", "R4005"), ("heater-loop % R4006", "R4006"), ("heater-loop s R4007", "R4007"),
    ("pre-alarm R4008", "R4008"), ("installed R4010/R4011", "R4010"), ("PID enable R4012/R4013", "R4012"),
]
_COUNTS = {"R4010": 2, "R4012": 2}


#: families whose probe is not the FBs one below (by the name their plug-in is registered under)
_OTHER_FAMILIES: dict[str, Callable[[Profile, str | None, Console], int]] = {"s7-200smart": probe_s7}


def probe(url: str | None, console: Console, bench: str | None = None) -> int:
    """Print the PLC's status and key registers; with a ``bench`` profile that has [temperature], its points."""
    if bench is not None:
        given = load_profile(bench)
        if given.family in _OTHER_FAMILIES:
            return _OTHER_FAMILIES[given.family](given, url, console)
    with open_target(url, bench) as opened:
        transport, profile = opened.transport, opened.profile if bench else None
        console.print(status_panel(transport.status(), transport.description))
        table = Table(title="key registers", show_header=True)
        table.add_column("item")
        table.add_column("value")
        table.add_row("RTC R4128–R4134", _rtc_row(transport))
        for label, element in PROBE_REGISTERS:
            reason = transport.unreachable_reason(element)
            if reason:
                table.add_row(label, f"[dim]not reachable: {escape(reason)}[/dim]")
                continue
            values = transport.read_words(element, _COUNTS.get(element, 1))
            table.add_row(label, " ".join(f"{v} ({v:04X}H)" for v in values))
        console.print(table)
        if profile is not None and "temperature" in profile.sections:
            console.print(temperature_table(transport, profile))
    return 0


def _rtc_row(transport: Transport) -> str:
    """The clock as ``hil rtc read`` shows it: a date and weekday (invalid fields pointed out)."""
    reason = transport.unreachable_reason("R4128")
    if reason:
        return f"[dim]not reachable: {escape(reason)}[/dim]"
    return format_time(RtcTime.from_registers(transport.read_words("R4128", 7)))


def temperature_table(transport: Transport, profile: Profile) -> Table:
    """One row per configured point: module, sensor, installed bit, reading, break bit; the caption has the
    table marker, execution code and counts as the PLC reports them."""
    config = profile.sections["temperature"]
    if transport.emulator is not None:  # a freshly built emulator: let every point be measured once
        transport.emulator.advance(config.update_period() * 1.5)
    temp = Temperature(FbsPlc(transport, HostTimebase()), config)
    unit = f"°{config.unit}"
    table = Table(title=f"temperature points ({len(config.modules)} modules, {config.points} points)")
    for column in ("point", "module", "sensor", "installed", f"reading {unit}", "break"):
        table.add_column(column, justify="right" if column == "point" else "left")
    try:
        head, work = temp.read_table(), temp.read_work()
        readings = temp.readings()
        mask = transport.read_words("R4010", 2)
    except HilError as exc:
        table.caption = f"[red]cannot read the temperature area: {exc}[/red]"
        return table
    breaks = set(work.break_points)
    for point, value in enumerate(readings):
        k, module = config.point_module(point)
        installed = pair_bit(mask, point)
        shown = "[red]28767 (open)[/red]" if value == BREAK_VALUE else f"{value / 10:.1f}"
        table.add_row(str(point), f"{k + 1}: FBs-{module.type.name}", module.sensor.name,
                      "yes" if installed else "[dim]no[/dim]", shown, "[red]BREAK[/red]" if point in breaks else "")
    table.caption = (f"table {config.table}: SR+0 = {head.marker:04X}H; work {config.work}: execution code "
                     f"{work.execution_code:02X}H, mismatch bits {work.mismatch_bits:08b}, "
                     f"{work.total_points} points / {work.module_count} modules")
    return table


# -- the command line -----------------------------------------------------------------------------------------------
def add_parser(sub: Subparsers, summary: str) -> None:
    probe = sub.add_parser("probe", help=summary,
                           description="Connect, ask the PLC what it is (FATEK command 53 where the wire has it) "
                                       "and show its state and key registers. Reads only.",
                           epilog="examples:\n  hil probe fatek+tcp://192.168.1.5:500\n"
                                  "  hil probe fatek+serial:///dev/ttyUSB0?baudrate=19200\n"
                                  "  hil probe modbus+tcp://192.168.1.5:502?unit=1\n"
                                  "  hil probe fatek+rfc2217://exporter:3001   (port 0 behind ser2net / labgrid)\n"
                                  "  hil probe --bench fixtures/benches/emulator.toml   (the profile's target, "
                                  "with its temperature points)\n")
    probe.add_argument("url", nargs="?", help="target URL, e.g. fatek+serial:///dev/ttyUSB0 or emulator+modbus-tcp "
                                              "(default: the --bench profile's target, else the emulator, as hil run)")
    probe.add_argument("--bench", metavar="FILE",
                       help="bench profile: its [temperature] section adds the temperature points to the report "
                            "(and configures an emulator… target)")
    probe.set_defaults(func=command)


def command(args: argparse.Namespace, console: Console) -> int:
    return probe(args.url, console, bench=args.bench)
