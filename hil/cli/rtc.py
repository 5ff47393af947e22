"""``hil rtc read|set|sync URL``: the PLC's clock from the command line (``hil drift``: :mod:`hil.cli.drift`).

The commands drive :class:`hil.families.fbs.device.rtc.Rtc` over a *direct* transport, not the bench's guarded one: the
operator named the PLC and asked for the write on the command line, so there is no profile whitelist to consult
and nothing to journal or restore.  An ``emulator…`` target is built from a bench profile (default
fixtures/benches/emulator.toml, so it has an S-35390A RTC) and runs in virtual time.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import re
from collections.abc import Callable, Iterator
from typing import TypeVar

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from hil.cli.parser import Subparsers
from hil.cli.target import open_target
from hil.core.errors import InvalidValue, UnreachableAddress
from hil.core.humantime import span
from hil.families.fbs import registers as reg
from hil.families.fbs.d4054 import RateCode, rate_for_code
from hil.families.fbs.device.plc import FbsPlc
from hil.families.fbs.device.rtc import SetResult
from hil.families.fbs.rtc_time import YEAR_BASE, RtcTime, weekday_of

T = TypeVar("T")

WEEKDAYS = ("Sunday", "Monday", "Tuesday", "Wednesday", "Thursday", "Friday", "Saturday")  # 0 = Sunday

TIME_FORMATS = "YYYY-MM-DD HH:MM:SS (or YYYY-MM-DDTHH:MM:SS, seconds optional, date alone = midnight)"
_TIME_RE = re.compile(r"^(\d{4})-(\d{1,2})-(\d{1,2})(?:[T ](\d{1,2}):(\d{1,2})(?::(\d{1,2})(?:\.\d+)?)?)?$")

URL_HELP = ("target URL, e.g. fatek+tcp://192.168.1.5:500, fatek+serial:///dev/ttyUSB0 or emulator+fatek-tcp "
            "(default: the --bench profile's target, else the emulator)")
BENCH_HELP = "bench profile for an emulator… target (default fixtures/benches/emulator.toml: an S-35390A RTC)"


# -- opening a PLC --------------------------------------------------------------------------------------------------
@contextlib.contextmanager
def open_plc(url: str, bench: str | None = None, *, writing: bool = False) -> Iterator[FbsPlc]:
    """An :class:`FbsPlc` on a direct transport to ``url`` (see :mod:`hil.cli.target`; ``writing``: holds the
    bench lock and replays a dead run's journal first)."""
    with open_target(url, bench, writing=writing) as opened:
        yield opened.plc()


def reachable(read: Callable[[], T]) -> T | UnreachableAddress:
    """``read()``, or the UnreachableAddress the transport raised before sending anything."""
    try:
        return read()
    except UnreachableAddress as exc:
        return exc


# -- formatting ---------------------------------------------------------------------------------------------------
def format_time(t: RtcTime, *, flag: bool = True) -> str:
    """``2024-02-29 12:00:00 Thursday``; with ``flag``, invalid fields and a weekday that does not match the date
    are pointed out."""
    bad = t.validate()
    dated = not {"day", "month", "year"} & set(bad)  # else the weekday's name would mean nothing
    day = WEEKDAYS[t.weekday] if dated and 0 <= t.weekday <= 6 else f"weekday {t.weekday}"
    text = (f"{YEAR_BASE + t.year:04d}-{t.month:02d}-{t.day:02d} {t.hour:02d}:{t.minute:02d}:{t.second:02d} "
            f"{day}")
    if not flag:
        return text
    if bad:
        return text + " [red](invalid: " + ", ".join(f"{n}={getattr(t, n)}" for n in bad) + ")[/red]"
    implied = weekday_of(t.year, t.month, t.day)
    if implied != t.weekday:
        text += f" [yellow](the date is a {WEEKDAYS[implied]})[/yellow]"
    return text


def format_rate(rate: RateCode) -> str:
    if rate.mode == "none":
        return "no correction"
    return f"{rate.mode}, {rate.steps:+d} steps, {rate.s_per_day:+.3f} s/day ({rate.ppm:+.2f} ppm)"


def not_reachable(exc: UnreachableAddress) -> str:
    return f"[dim]not reachable over {escape(exc.via)}[/dim]"


def _vs_host(plc: dt.datetime, host: dt.datetime) -> str:
    """PLC − host.  The RTC shows whole seconds, so a clock in step shows the host's second: −1 s < diff ≤ 0."""
    diff = (plc - host).total_seconds()
    if -1.0 < diff <= 1e-6:
        return "in step (to the whole second the RTC shows)"
    side = "ahead of" if diff > 0 else "behind"
    readable = f"PLC {span(diff)} {side} host time" + (f" ({diff:+.1f} s)" if abs(diff) >= 60 else "")
    return f"{readable}; ±1 s: the RTC shows whole seconds"


# -- hil rtc ------------------------------------------------------------------------------------------------------
def rtc_read(url: str, console: Console, bench: str | None = None) -> int:
    with open_plc(url, bench) as plc:
        rtc = plc.rtc
        snapshot = rtc.read_all()  # time, R4135 and M1952–M1955: one round trip
        now, flags, hour_minute = snapshot.time, snapshot.flags, snapshot.hour_minute
        host = plc.time.calendar()
        chip_and_code = reachable(rtc.read_chip_and_rate_code)  # D4053–D4054: one round trip
        chip, code = ((chip_and_code, chip_and_code) if isinstance(chip_and_code, UnreachableAddress)
                      else chip_and_code)

        table = Table(title=f"RTC of {escape(plc.io.description)}", show_header=False)
        table.add_column("item")
        table.add_column("value")
        table.add_row("time R4128–R4134", format_time(now))
        table.add_row("chip D4053", not_reachable(chip) if isinstance(chip, UnreachableAddress)
                      else f"{chip.name} ({chip.code})")
        if isinstance(flags, UnreachableAddress):
            table.add_row("M1954 / M1955", not_reachable(flags))
        else:
            table.add_row("M1954 installed", f"{int(flags.installed)} ({'yes' if flags.installed else 'no'})")
            table.add_row("M1955 set error", f"{int(flags.set_error)} "
                          f"({'the last set was refused' if flags.set_error else 'no error'})")
            if flags.hold:
                table.add_row("M1952 hold", "[yellow]1: read-out frozen (a set is pending)[/yellow]")
        table.add_row("R4135 hour/minute", not_reachable(hour_minute) if isinstance(hour_minute, UnreachableAddress)
                      else f"{hour_minute:04X}H")
        if isinstance(code, UnreachableAddress):
            table.add_row("rate code D4054", not_reachable(code))
        else:
            try:
                decoded = format_rate(rate_for_code(code))
            except ValueError:
                decoded = "[red]not a valid code[/red]"
            table.add_row("rate code D4054", f"{code:04X}H: {decoded}")
        if now.is_valid:
            table.add_row("vs host time", _vs_host(now.to_datetime(), host))
        else:
            table.add_row("vs host time", "[red]cannot compare: the PLC's time is invalid[/red]")
        table.add_row("host time", f"{host:%Y-%m-%d %H:%M:%S}.{host.microsecond // 100000}")
        console.print(table)
    return 0


def parse_time(text: str) -> RtcTime:
    """RTC register values for an ISO-like string, *not* validated beyond the year (so "2023-02-29" reaches
    the PLC and can be refused).  The weekday comes from the date when the date exists, else 0."""
    match = _TIME_RE.match(text.strip())
    if not match:
        raise InvalidValue(f"cannot read {text!r} as a time — give {TIME_FORMATS}")
    year, month, day, hour, minute, second = (int(g) if g else 0 for g in match.groups())
    if not YEAR_BASE <= year <= YEAR_BASE + 99:
        raise InvalidValue(f"the FBs RTC holds years {YEAR_BASE}–{YEAR_BASE + 99} only, not {year} — give a date in "
                           f"those years")
    value = RtcTime(second, minute, hour, day, month, year - YEAR_BASE, 0)
    try:
        return value.with_weekday_from_date()
    except ValueError:  # no such date: send it anyway, the PLC's verdict is the point
        return value


def _report_set(console: Console, plc: FbsPlc, result: SetResult) -> int:
    sent = format_time(result.sent)
    if result.accepted:
        console.print(f"[green]accepted[/green] (M1955 = 0): set to {escape(sent)}", highlight=False)
        if result.problems:
            console.print(f"[yellow]warning:[/yellow] the PLC took a time our validation finds invalid "
                          f"({escape(', '.join(result.problems))})", highlight=False)
        console.print(f"PLC now shows {escape(format_time(plc.rtc.read()))}", highlight=False)
        return 0
    ours = (f"our validation finds invalid: "
            f"{', '.join(f'{n}={getattr(result.sent, n)}' for n in result.problems)}" if result.problems
            else "our validation finds nothing wrong with it")
    console.print(f"[bold red]refused[/bold red] by the PLC (M1955 = 1): sent "
                  f"{escape(format_time(result.sent, flag=False))}",
                  highlight=False)
    console.print(f"  {escape(ours)}", highlight=False)
    return 1


_SET_ADDRESSES = [reg.RTC_HOLD, *reg.RTC_FIELDS, reg.RTC_SET_ERROR]


def rtc_set(url: str, when: str, console: Console, bench: str | None = None) -> int:
    value = parse_time(when)
    with open_plc(url, bench, writing=True) as plc:
        plc.io.require(_SET_ADDRESSES, "set the RTC")  # a failure after M1952 := 1 would leave the clock frozen
        return _report_set(console, plc, plc.rtc.set(value))


def rtc_sync(url: str, console: Console, bench: str | None = None) -> int:
    with open_plc(url, bench, writing=True) as plc:
        plc.io.require(_SET_ADDRESSES, "set the RTC")
        result = plc.rtc.sync_to_host()
        host = plc.time.calendar()
        code = _report_set(console, plc, result)
        if code == 0:
            console.print(f"host time {host.strftime('%Y-%m-%d %H:%M:%S')}", highlight=False)
        return code


__all__ = ["rtc_read", "rtc_set", "rtc_sync", "open_plc", "parse_time", "format_time", "format_rate", "reachable",
           "not_reachable", "WEEKDAYS"]


# -- the command line -----------------------------------------------------------------------------------------------
def add_parser(sub: Subparsers, summary: str) -> None:
    rtc = sub.add_parser("rtc", help=summary,
                         description="The PLC's real-time clock (R4128–R4135, M1952–M1955, D4053/D4054). Writes go "
                                     "straight to the PLC: no bench profile guards them.",
                         epilog="examples:\n  hil rtc read fatek+tcp://192.168.1.5:500\n"
                                "  hil rtc set fatek+serial:///dev/ttyUSB0 \"2024-02-29 12:00:00\"\n"
                                "  hil rtc sync emulator+modbus-tcp\n")
    rtc_sub = rtc.add_subparsers(dest="rtc_command", metavar="ACTION", required=True)
    read = rtc_sub.add_parser("read", help="the time, chip, flags and rate code, and the difference from host time",
                              epilog="examples:\n  hil rtc read fatek+tcp://192.168.1.5:500\n"
                                     "  hil rtc read emulator+modbus-tcp    (D4053/D4054 are not on the Modbus map)\n")
    set_ = rtc_sub.add_parser("set", help="set the clock (M1952 procedure); exit 1 if the PLC refuses (M1955 = 1)",
                              epilog="examples:\n  hil rtc set fatek+tcp://192.168.1.5:500 \"2024-02-29 12:00:00\"\n"
                                     "  hil rtc set emulator 2024-02-29T12:00\n"
                                     "An invalid date (2023-02-29) is sent as is, so you see whether the PLC takes "
                                     "it.\n")
    sync = rtc_sub.add_parser("sync", help="set the clock to host time, on a whole second",
                              epilog="example:\n  hil rtc sync fatek+serial:///dev/ttyUSB0\n")
    for p in (read, set_, sync):
        p.add_argument("url", metavar="URL", nargs="?", help=URL_HELP)
    set_.add_argument("time", metavar="TIME", help="YYYY-MM-DD HH:MM:SS (ISO; 'T' or space; seconds optional)")
    for p in (read, set_, sync):
        p.add_argument("--bench", metavar="FILE", help=BENCH_HELP)
    read.set_defaults(func=lambda args, console: rtc_read(args.url, console, bench=args.bench))
    set_.set_defaults(func=lambda args, console: rtc_set(args.url, args.time, console, bench=args.bench))
    sync.set_defaults(func=lambda args, console: rtc_sync(args.url, console, bench=args.bench))
