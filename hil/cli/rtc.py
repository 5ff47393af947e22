"""``hil rtc read|set|sync URL`` and ``hil drift code|decode|measure``: the PLC's clock from the command line.

The commands drive :class:`hil.families.fbs.device.rtc.Rtc` over a *direct* transport, not the bench's guarded one: the
operator named the PLC and asked for the write on the command line, so there is no profile whitelist to consult
and nothing to journal or restore.  An ``emulator…`` target is built from a bench profile (default
fixtures/benches/emulator.toml, so it has an S-35390A RTC) and runs in virtual time.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import math
import re
from collections.abc import Callable, Iterator
from typing import TypeVar

from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

from hil.cli.target import open_target
from hil.core.errors import HilError, InvalidValue, UnreachableAddress
from hil.core.humantime import span
from hil.core.timebase import Timebase
from hil.families.fbs import registers as reg
from hil.families.fbs.d4054 import RATE_MAX, RATE_MIN, TABLE, RateCode, code_for_rate, rate_for_code
from hil.families.fbs.device.plc import FbsPlc
from hil.families.fbs.rtc_time import YEAR_BASE, RtcTime, weekday_of

T = TypeVar("T")

WEEKDAYS = ("Sunday", "Monday", "Tuesday", "Wednesday", "Thursday", "Friday", "Saturday")  # 0 = Sunday

TIME_FORMATS = "YYYY-MM-DD HH:MM:SS (or YYYY-MM-DDTHH:MM:SS, seconds optional, date alone = midnight)"
_TIME_RE = re.compile(r"^(\d{4})-(\d{1,2})-(\d{1,2})(?:[T ](\d{1,2}):(\d{1,2})(?::(\d{1,2})(?:\.\d+)?)?)?$")

CODE_FORMATS = "a D4054 code in hex: 56E5, 56E5H or 0x56E5 (0000H = no correction, else 5600H–56FFH)"
_CODE_RE = re.compile(r"^(?:0x)?([0-9a-f]{1,4})h?$", re.IGNORECASE)


# -- opening a PLC --------------------------------------------------------------------------------------------------
@contextlib.contextmanager
def open_plc(url: str, bench: str | None = None, *, writing: bool = False) -> Iterator[FbsPlc]:
    """An :class:`FbsPlc` on a direct transport to ``url`` (see :mod:`hil.cli.target`; ``writing``: holds the
    bench lock and replays a dead run's journal first)."""
    with open_target(url, bench, writing=writing) as opened:
        yield opened.plc()


def _reachable(read: Callable[[], T]) -> T | UnreachableAddress:
    """``read()``, or the UnreachableAddress the transport raised before sending anything."""
    try:
        return read()
    except UnreachableAddress as exc:
        return exc


def _require(plc: FbsPlc, addresses: list[str], action: str) -> None:
    """Refuse, before writing anything, an action whose addresses this wire cannot reach."""
    plc.io.require(addresses, action)


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


def _not_reachable(exc: UnreachableAddress) -> str:
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
        chip_and_code = _reachable(rtc.read_chip_and_rate_code)  # D4053–D4054: one round trip
        chip, code = ((chip_and_code, chip_and_code) if isinstance(chip_and_code, UnreachableAddress)
                      else chip_and_code)

        table = Table(title=f"RTC of {escape(plc.io.description)}", show_header=False)
        table.add_column("item")
        table.add_column("value")
        table.add_row("time R4128–R4134", format_time(now))
        table.add_row("chip D4053", _not_reachable(chip) if isinstance(chip, UnreachableAddress)
                      else f"{chip.name} ({chip.code})")
        if isinstance(flags, UnreachableAddress):
            table.add_row("M1954 / M1955", _not_reachable(flags))
        else:
            table.add_row("M1954 installed", f"{int(flags.installed)} ({'yes' if flags.installed else 'no'})")
            table.add_row("M1955 set error", f"{int(flags.set_error)} "
                          f"({'the last set was refused' if flags.set_error else 'no error'})")
            if flags.hold:
                table.add_row("M1952 hold", "[yellow]1: read-out frozen (a set is pending)[/yellow]")
        table.add_row("R4135 hour/minute", _not_reachable(hour_minute) if isinstance(hour_minute, UnreachableAddress)
                      else f"{hour_minute:04X}H")
        if isinstance(code, UnreachableAddress):
            table.add_row("rate code D4054", _not_reachable(code))
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
        raise InvalidValue(f"cannot read {text!r} as a time: give {TIME_FORMATS}")
    year, month, day, hour, minute, second = (int(g) if g else 0 for g in match.groups())
    if not YEAR_BASE <= year <= YEAR_BASE + 99:
        raise InvalidValue(f"the FBs RTC holds years {YEAR_BASE}–{YEAR_BASE + 99} only, not {year}")
    value = RtcTime(second, minute, hour, day, month, year - YEAR_BASE, 0)
    try:
        return value.with_weekday_from_date()
    except ValueError:  # no such date: send it anyway, the PLC's verdict is the point
        return value


def _report_set(console: Console, plc: FbsPlc, result) -> int:
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
        _require(plc, _SET_ADDRESSES, "set the RTC")  # a failure after M1952 := 1 would leave the clock frozen
        return _report_set(console, plc, plc.rtc.set(value))


def rtc_sync(url: str, console: Console, bench: str | None = None) -> int:
    with open_plc(url, bench, writing=True) as plc:
        _require(plc, _SET_ADDRESSES, "set the RTC")
        result = plc.rtc.sync_to_host()
        host = plc.time.calendar()
        code = _report_set(console, plc, result)
        if code == 0:
            console.print(f"host time {host.strftime('%Y-%m-%d %H:%M:%S')}", highlight=False)
        return code


# -- hil drift ----------------------------------------------------------------------------------------------------
def parse_rate(text: str) -> float:
    cleaned = text.strip().replace("\u2212", "-").removesuffix("s/day").strip()
    try:
        rate = float(cleaned)
    except ValueError:
        rate = math.nan
    if not math.isfinite(rate):
        raise InvalidValue(f"cannot read {text!r} as a clock error: give s/day as a number, positive = the PLC clock "
                         f"runs fast (e.g. 3.38 or -5.62; range {RATE_MIN}…+{RATE_MAX})")
    if not RATE_MIN <= round(rate, 9) <= RATE_MAX:  # {:g}: 1e308 stays short, not 309 digits
        raise InvalidValue(f"clock error {rate:+g} s/day is outside the S-35390A setting range {RATE_MIN}…+{RATE_MAX} "
                         f"s/day (manual ch. 15); D4054 cannot correct it")
    return rate


def parse_code(text: str) -> int:
    match = _CODE_RE.match(text.strip())
    if not match:
        raise InvalidValue(f"cannot read {text!r} as a D4054 code: give {CODE_FORMATS}")
    code = int(match.group(1), 16)
    try:
        rate_for_code(code)
    except ValueError as exc:
        raise InvalidValue(str(exc)) from None
    return code


def _listed_rate(code: int) -> float | None:
    return next((rate for rate, c in TABLE if c == code), None)


def drift_code(rate_text: str, console: Console) -> int:
    rate = parse_rate(rate_text)
    code = code_for_rate(rate)
    listed = _listed_rate(code)
    console.print(f"[bold]{code:04X}H[/bold]", highlight=False)
    console.print(f"  {format_rate(rate_for_code(code))}", highlight=False)
    console.print(f"  manual Table 1 row {listed:+.2f} s/day, nearest to a clock {abs(rate):g} s/day "
                  f"{'fast' if rate >= 0 else 'slow'}", highlight=False)
    return 0


def drift_decode(code_text: str, console: Console) -> int:
    code = parse_code(code_text)
    rate = rate_for_code(code)
    table = Table(title=f"D4054 = {code:04X}H", show_header=False)
    table.add_column("item")
    table.add_column("value")
    table.add_row("mode", rate.mode if rate.mode != "none" else "none (no correction)")
    table.add_row("steps", f"{rate.steps:+d}")
    table.add_row("rate", f"{rate.s_per_day:+.4f} s/day (for a PLC clock that runs fast; negative = slow)")
    table.add_row("ppm", f"{rate.ppm:+.3f}")
    listed = _listed_rate(code)
    if listed is not None:
        table.add_row("manual Table 1", f"{listed:+.2f} s/day")
    console.print(table)
    return 0


class _ProgressTimebase:
    """A host timebase whose waits tick a rich progress bar (bench seconds since ``start``)."""

    virtual = False

    def __init__(self, inner: Timebase, progress: Progress, task, total: float) -> None:
        self.inner, self.progress, self.task, self.total = inner, progress, task, total
        self.start = inner.now()

    def now(self) -> float:
        return self.inner.now()

    def calendar(self) -> dt.datetime:
        return self.inner.calendar()

    def wait(self, seconds: float) -> None:
        end = self.inner.now() + seconds
        while (left := end - self.inner.now()) > 0:
            self.inner.wait(min(left, 0.25))
            self.progress.update(self.task, completed=min(self.inner.now() - self.start, self.total))


#: The longest measurement: the FBs calendar holds 2000–2099, and a year is already far finer than any use.
MAX_DURATION = 366 * 86400.0


def drift_measure(url: str, duration: float, console: Console, bench: str | None = None,
                  apply: bool = False) -> int:
    if not math.isfinite(duration) or not 5 < duration <= MAX_DURATION:
        raise InvalidValue(f"--duration {duration:g} s: give more than 5 s and at most {MAX_DURATION:.0f} s (366 days; "
                           f"the PLC's calendar holds 2000–2099 only)")
    with open_plc(url, bench, writing=apply) as plc:
        if apply:  # fail before a long measurement, not after it
            _require(plc, [reg.RTC_RATE_CODE, reg.RTC_CHIP], "write the compensating code")
            chip = plc.rtc.chip
            if not chip.has_rate_adjust:
                raise HilError(f"cannot write the compensating code: D4053 = {chip.code} ({chip.name}); only an "
                               f"S-35390A (3) takes a D4054 rate code (nothing was written)")
        current = _reachable(lambda: plc.rtc.rate_code)
        if plc.time.virtual or not console.is_terminal:
            measurement = plc.rtc.drift.measure(duration)
        else:
            columns = (TextColumn("measuring drift"), BarColumn(),
                       TextColumn("{task.completed:.0f}/{task.total:.0f} s"), TimeRemainingColumn())
            with Progress(*columns, console=console, transient=True) as progress:
                task = progress.add_task("drift", total=duration)
                host = plc.time
                plc.time = _ProgressTimebase(host, progress, task, duration)
                try:
                    measurement = plc.rtc.drift.measure(duration)
                finally:
                    plc.time = host

        table = Table(title=f"RTC drift of {escape(plc.io.description)}", show_header=False)
        table.add_column("item")
        table.add_column("value")
        side = "fast" if measurement.s_per_day >= 0 else "slow"
        table.add_row("drift", f"{measurement.s_per_day:+.3f} s/day (PLC clock runs {side})")
        table.add_row("ppm", f"{measurement.ppm:+.3f}")
        table.add_row("resolution", f"±{measurement.resolution:.3f} s/day")
        table.add_row("measured over", f"{measurement.reference_elapsed:.1f} s bench time, "
                      f"{len(measurement.samples)} timed second transitions")
        # The compensating code is for the clock's own error: add back whatever correction D4054 applied.
        correction = 0.0
        if isinstance(current, UnreachableAddress):
            table.add_row("D4054 now", _not_reachable(current) + " (assumed 0000H)")
        else:
            try:
                correction = rate_for_code(current).s_per_day
                table.add_row("D4054 now", f"{current:04X}H: {format_rate(rate_for_code(current))}")
            except ValueError:
                table.add_row("D4054 now", f"{current:04X}H [red]not a valid code (assumed 0000H)[/red]")
        raw = measurement.s_per_day + correction
        code = None
        try:
            code = code_for_rate(raw)
            table.add_row("compensating code", f"[bold]{code:04X}H[/bold]: {format_rate(rate_for_code(code))}"
                          + (f" (for {raw:+.3f} s/day without correction)" if correction else ""))
        except ValueError:
            table.add_row("compensating code", f"[red]none: {raw:+.3f} s/day is outside the S-35390A range "
                                               f"{RATE_MIN}…+{RATE_MAX} s/day[/red]")
        vague = abs(measurement.s_per_day) < measurement.resolution
        if vague:
            table.add_row("note", "[yellow]the drift is within the resolution: measure longer before writing a "
                                  "code[/yellow]")
        console.print(table)
        if not apply:
            return 0
        if code is None or vague:
            console.print("[bold red]not applied[/bold red]: D4054 left as it was", highlight=False)
            return 1
        plc.rtc.rate_code = code  # direct write: the operator asked for it with --apply
        console.print(f"[green]written[/green]: D4054 = {code:04X}H (was {current:04X}H)", highlight=False)
    return 0


__all__ = ["rtc_read", "rtc_set", "rtc_sync", "drift_code", "drift_decode", "drift_measure", "open_plc",
           "parse_time", "parse_code", "parse_rate", "format_time", "WEEKDAYS"]
