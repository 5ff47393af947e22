"""``hil drift code|decode|measure``: the S-35390A clock-rate compensation (D4054) — the manual's code for a
clock error, what a code does, and measuring a PLC clock's drift against host time (see :mod:`hil.cli.rtc` for how
the PLC is reached)."""

from __future__ import annotations

import datetime as dt
import math
import re

from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TaskID, TextColumn, TimeRemainingColumn
from rich.table import Table

from hil.cli.parser import Subparsers
from hil.cli.rtc import BENCH_HELP, URL_HELP, format_rate, not_reachable, open_plc, reachable
from hil.core.errors import HilError, InvalidValue, UnreachableAddress
from hil.core.timebase import Timebase
from hil.families.fbs import registers as reg
from hil.families.fbs.d4054 import RATE_MAX, RATE_MIN, TABLE, code_for_rate, rate_for_code

CODE_FORMATS = "a D4054 code in hex: 56E5, 56E5H or 0x56E5 (0000H = no correction, else 5600H–56FFH)"
_CODE_RE = re.compile(r"^(?:0x)?([0-9a-f]{1,4})h?$", re.IGNORECASE)


# -- the rates ----------------------------------------------------------------------------------------------------
def parse_rate(text: str) -> float:
    cleaned = text.strip().replace("\u2212", "-").removesuffix("s/day").strip()
    try:
        rate = float(cleaned)
    except ValueError:
        rate = math.nan
    if not math.isfinite(rate):
        raise InvalidValue(f"cannot read {text!r} as a clock error — give s/day as a number, positive = the PLC clock "
                         f"runs fast (e.g. 3.38 or -5.62; range {RATE_MIN}…+{RATE_MAX})")
    if not RATE_MIN <= round(rate, 9) <= RATE_MAX:  # {:g}: 1e308 stays short, not 309 digits
        raise InvalidValue(f"clock error {rate:+g} s/day is outside the S-35390A setting range {RATE_MIN}…+{RATE_MAX} "
                         f"s/day (manual ch. 15); D4054 cannot correct it")
    return rate


def parse_code(text: str) -> int:
    match = _CODE_RE.match(text.strip())
    if not match:
        raise InvalidValue(f"cannot read {text!r} as a D4054 code — give {CODE_FORMATS}")
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

    def __init__(self, inner: Timebase, progress: Progress, task: TaskID, total: float) -> None:
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
        raise InvalidValue(f"--duration {duration:g} s — give more than 5 s and at most {MAX_DURATION:.0f} s "
                           f"(366 days; the PLC's calendar holds 2000–2099 only)")
    with open_plc(url, bench, writing=apply) as plc:
        if apply:  # fail before a long measurement, not after it
            plc.io.require([reg.RTC_RATE_CODE, reg.RTC_CHIP], "write the compensating code")
            chip = plc.rtc.chip
            if not chip.has_rate_adjust:
                raise HilError(f"cannot write the compensating code: D4053 = {chip.code} ({chip.name}); only an "
                               f"S-35390A (3) takes a D4054 rate code (nothing was written)")
        current = reachable(lambda: plc.rtc.rate_code)
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
            table.add_row("D4054 now", not_reachable(current) + " (assumed 0000H)")
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


# -- the command line -----------------------------------------------------------------------------------------------
def add_parser(sub: Subparsers, summary: str) -> None:
    drift = sub.add_parser("drift", help=summary,
                           description="S-35390A clock-rate compensation (D4054). Positive rates mean the PLC clock "
                                       "runs fast.",
                           epilog="examples:\n  hil drift code 3.38\n  hil drift decode 56E5H\n"
                                  "  hil drift measure fatek+tcp://192.168.1.5:500 --duration 3600\n")
    drift_sub = drift.add_subparsers(dest="drift_command", metavar="ACTION", required=True)
    code = drift_sub.add_parser("code", help="the manual's D4054 code for a clock error in s/day",
                                epilog="examples:\n  hil drift code 3.38     -> 56E5H\n"
                                       "  hil drift code -5.62    -> 5603H (a clock 5.62 s/day slow)\n")
    code.add_argument("rate", metavar="RATE", help="s/day the PLC clock runs fast (negative: slow), "
                                                  "-16.88 … +16.61")
    decode = drift_sub.add_parser("decode", help="what a D4054 code does: mode, steps, s/day, ppm",
                                  epilog="examples:\n  hil drift decode 56E5\n  hil drift decode 0x5603\n"
                                         "  hil drift decode 56E5H\n")
    decode.add_argument("code", metavar="CODE", help="hex: 56E5, 56E5H or 0x56E5")
    measure = drift_sub.add_parser("measure", help="measure the clock's error in s/day against host time",
                                   epilog="examples:\n  hil drift measure fatek+tcp://192.168.1.5:500 --duration 3600\n"
                                          "  hil drift measure emulator --duration 86400   (virtual time: instant)\n"
                                          "  hil drift measure fatek+serial:///dev/ttyUSB0 --duration 86400 --apply\n"
                                          "Longer is finer: the resolution is one polling bracket (tens of ms) over "
                                          "the duration, about ±0.03 s/day over a day. Without --apply D4054 is left "
                                          "as it is.\n")
    measure.add_argument("url", metavar="URL", nargs="?", help=URL_HELP)
    measure.add_argument("--duration", type=float, required=True, metavar="SECONDS",
                         help="bench seconds to measure over (more than 5)")
    measure.add_argument("--apply", action="store_true",
                         help="then write the compensating code to D4054 (S-35390A; not over the default Modbus map)")
    measure.add_argument("--bench", metavar="FILE", help=BENCH_HELP)
    code.set_defaults(func=lambda args, console: drift_code(args.rate, console))
    decode.set_defaults(func=lambda args, console: drift_decode(args.code, console))
    measure.set_defaults(func=lambda args, console: drift_measure(args.url, args.duration, console,
                                                                  bench=args.bench, apply=args.apply))
