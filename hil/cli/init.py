"""``hil init TARGET``: a bench profile and a first test for a PLC, filled in from what the PLC says.

Read-only: it asks the PLC its status and identity (FATEK command 53 where the wire has it), the RTC chip (D4053)
and, at the address given (``--temperature-table R3000``), the temperature table (SR+0 = A556H, the module count,
where the readings and the work block are, each module's type and sensor: spec/fbs-temperature.md).  What it cannot
read — scratch registers, FUN86 boxes, fault injectors, the unit WinProladder set — is left as commented
placeholders saying what to fill in.  Nothing is overwritten unless ``--force``.
"""

from __future__ import annotations

import argparse
import os
from dataclasses import dataclass, field
from pathlib import Path

from rich.console import Console

from hil.bench.lab.spec import LABGRID
from hil.bench.profile_keys import BENCH, EMULATOR, HISTORY, SAFETY, WIRE_FAULTS
from hil.bench.schema_export import render_section, schema_line
from hil.cli.parser import Subparsers
from hil.cli.target import open_target
from hil.core.errors import HilError, InvalidValue
from hil.families.fbs import registers as reg
from hil.families.fbs.address import parse
from hil.families.fbs.device.temperature import TableView
from hil.families.fbs.identity import read_identity
from hil.families.fbs.injectors.config import FAULTS
from hil.families.fbs.pid import PID
from hil.families.fbs.plugin import FAMILY
from hil.families.fbs.rtc_profile import RTC
from hil.families.fbs.rtc_time import CHIP_NAMES
from hil.families.fbs.sim.models.plant_config import PLANT
from hil.families.fbs.temperature import (
    MAX_MODULES,
    MODULE_BY_CODE,
    SENSOR_BY_CODE,
    TABLE_MARKER,
    TEMPERATURE,
    decode_start,
)
from hil.families.fbs.transport.base import Transport


@dataclass
class Found:
    """What the PLC told: each value, or why it is not known (``notes``, written into the profile)."""

    status: str = ""
    identity: dict[str, str] = field(default_factory=dict)
    chip: int | None = None
    rate_code_reachable: bool = False
    temperature: dict[str, object] | None = None
    notes: list[str] = field(default_factory=list)


def read_plc(transport: Transport, table: str | None) -> Found:
    found = Found(status=transport.status().summary(), identity=read_identity(transport) or {})
    reason = transport.unreachable_reason(reg.RTC_CHIP)
    if reason:
        found.notes.append(f"RTC chip not read: {reason}")
    else:
        found.chip = transport.read(reg.RTC_CHIP)
        found.rate_code_reachable = transport.unreachable_reason(reg.RTC_RATE_CODE) is None
    if table is not None:
        found.temperature = _read_table(transport, table, found.notes)
    return found


def _read_table(transport: Transport, at: str, notes: list[str]) -> dict[str, object] | None:
    start = parse(at)
    head = TableView(transport.read_words(start, 4))
    if head.marker != TABLE_MARKER:
        notes.append(f"no temperature table at {at}: {start} = {head.marker:04X}H, not the marker {TABLE_MARKER:04X}H")
        return None
    if not 1 <= head.module_count <= MAX_MODULES:
        notes.append(f"the temperature table at {at} counts {head.module_count} modules (1–{MAX_MODULES} expected)")
        return None
    view = TableView(transport.read_words(start, 4 + head.module_count))
    readings, work = decode_start(view.words[2]), decode_start(view.words[3])
    modules = []
    for k, (sensor, module) in enumerate(view.modules):
        if module not in MODULE_BY_CODE or sensor not in SENSOR_BY_CODE:
            notes.append(f"temperature table entry {k} at {start.offset(4 + k)} = {view.words[4 + k]:04X}H names no "
                         f"known module/sensor")
            return None
        modules.append((MODULE_BY_CODE[module].name, SENSOR_BY_CODE[sensor].name))
    if readings is None or work is None:
        notes.append(f"the temperature table at {at} names no readings/work registers ({view.words[2]}, "
                     f"{view.words[3]})")
        return None
    return {"table": str(start), "readings": str(readings), "work": str(work), "modules": modules}


def render_profile(name: str, target: str, found: Found, time_scale: float = 1.0,
                   scratch: tuple[str, ...] = ()) -> str:
    """The profile for what the PLC said: every declared key of the core's and the FBs family's sections (set,
    or commented out with its default), each with its description (:func:`hil.bench.schema_export.render_section`)."""
    lines = [schema_line(),
             f"# Bench profile written by `hil init {target}` from what the PLC said; check every line and fill in",
             "# the commented placeholders (docs/writing-tests.md, docs/profiles.md,",
             "# fixtures/benches/example-bench.toml).",
             f"# PLC status: {found.status}"]
    if found.identity:
        lines.append("# PLC identity (FATEK command 53): " + ", ".join(f"{k} {v}" for k, v in found.identity.items()))
    lines += [f"# {note}" for note in found.notes] + [""]
    bench = {"name": name, "target": target, "time_scale": time_scale,
             **({"scratch": list(scratch)} if scratch else {})}
    said = {"time_scale": "an accelerated hil emulate's"} if time_scale != 1 else {}
    lines += render_section(BENCH, bench, {**said, **({"scratch": "hil init --scratch"} if scratch else {})},
                            shown={"family": FAMILY.name, "scan_counter": "R3999",
                                   "scratch": ["R1000-R1099", "M1000-M1015"]})
    # the scratch ranges the user named are the suites' to write: in the allow-list with the clock's elements
    lines += render_section(SAFETY, {"writable": [*_writable(found), *scratch]},
                            {"writable": "with hil init --scratch" if scratch else "add your scratch ranges"},
                            shown={"volatile": list(FAMILY.default_volatile)})
    if found.chip is not None:
        lines += render_section(RTC, {"chip": CHIP_NAMES.get(found.chip, str(found.chip))},
                                {"chip": f"D4053 = {found.chip}"})
    else:
        lines += render_section(RTC, active=False)
    lines += _temperature(found.temperature)
    lines += ["# Your FUN86 (TPCTL) boxes (fixtures/benches/example-bench.toml); add their operands to [safety] "
              "writable.",
              "# [[pid.instances]]   # several boxes: one such table each, with the keys of [pid] below"]
    lines += render_section(PID, active=False)
    lines += render_section(FAULTS, active=False)
    for section in (EMULATOR, PLANT, WIRE_FAULTS, HISTORY, LABGRID):  # what a profile for a PLC rarely sets
        lines += render_section(section, active=False)
    return "\n".join(lines).rstrip("\n") + "\n"


def _writable(found: Found) -> list[str]:
    """The RTC's set values and triggers (and the S-35390A's rate code where the wire reaches it)."""
    if found.chip in (None, 0):
        return []
    return ["R4128-R4134", "M1952-M1953"] + (["D4054"] if found.rate_code_reachable and found.chip == 3 else [])


def _temperature(table: dict[str, object] | None) -> list[str]:
    if table is None:
        return ["# hil init --temperature-table R3000 reads [temperature] from the PLC"] + render_section(
            TEMPERATURE, active=False)
    values = {key: table[key] for key in ("table", "readings", "work")}
    values["modules"] = [{"type": m, "sensor": s} for m, s in table["modules"]]  # type: ignore[attr-defined]
    values.update(unit="C", averaging=1, rate="normal")
    check = "check: not readable from the PLC"
    return [f"# read from the table at {table['table']}"] + render_section(
        TEMPERATURE, values, {"unit": check, "averaging": check, "rate": check})


FIRST_TEST = '''"""A first test for {name}, written by `hil init`: run it with
    hil run --bench {profile} -- {test}
or  pytest --bench {profile} {test}
"""

from __future__ import annotations

import pytest

from hil.api import Bench, Rtc, Temperature


def test_the_plc_answers_and_runs(bench: Bench) -> None:
    status = bench.plc.status()
    assert status.running, f"the PLC is not in RUN: {{status.summary()}}"


def test_the_clock_keeps_bench_time(bench: Bench, rtc: Rtc) -> None:
    """Set the clock (put back after the test), let 5 bench seconds pass: it has moved on by as much, to its
    resolution of a second (bench time: virtual on the emulator, scaled for an accelerated one)."""
    start = bench.time.calendar().replace(microsecond=0)
    assert rtc.set(start), f"the PLC refused {{start}} (M1955)"
    began = bench.time.now()
    bench.wait(5.0)
    moved = (rtc.read().to_datetime() - start).total_seconds()
    elapsed = bench.time.now() - began
    assert abs(moved - elapsed) <= 1.5, f"the clock moved {{moved}} s in {{elapsed:.1f}} bench seconds"


def test_every_point_reads_a_temperature(temperature: Temperature) -> None:
    readings = temperature.readings()
    if not readings:
        pytest.skip("no temperature points configured")
    assert all(-2000 <= r <= 18000 for r in readings), readings  # 0.1 °: within any sensor's range
'''


def init(target: str, directory: Path, console: Console, *, name: str | None = None, table: str | None = None,
         time_scale: float = 1.0, force: bool = False, scratch: tuple[str, ...] = ()) -> int:
    profile, test = directory / "bench.toml", directory / "tests" / "test_first.py"
    _refuse_links(profile, test)
    existing = [p for p in (profile, test) if os.path.lexists(p)]
    if existing and not force:
        raise InvalidValue(f"{', '.join(map(str, existing))} already exist{'s' if len(existing) == 1 else ''}: "
                           f"pass --force to overwrite")
    if not time_scale > 0:
        raise InvalidValue(f"--time-scale {time_scale:g} — give a number above 0")
    if table is not None:
        try:
            parse(table)
        except HilError as exc:
            raise InvalidValue(f"--temperature-table {table!r}: {exc}") from None
    for span in scratch:
        try:
            FAMILY.check_ranges([span])
        except (HilError, ValueError) as exc:
            raise InvalidValue(f"--scratch {span!r}: {exc} (give a range such as R1000-R1099)") from None
    with open_target(target) as opened:
        found = read_plc(opened.transport, table)
    # the bench's name keys its run history: the directory the user chose names it, not the URL (two profiles
    # for one address would share one trend)
    name = name or directory.resolve().name
    test.parent.mkdir(parents=True, exist_ok=True)
    _write(profile, render_profile(name, target, found, time_scale, scratch), force)
    _write(test, FIRST_TEST.format(name=name, profile=profile.name, test=test.relative_to(directory)), force)
    console.print(f"wrote {profile} and {test}")
    for note in found.notes:
        console.print(f"  note: {note}")
    here = "" if directory.resolve() == Path.cwd().resolve() else f"cd {directory} && "
    def say(text: str) -> None:  # one command a line, never wrapped (a pipe is 80 columns): pasted as it stands
        console.print(text, soft_wrap=True, highlight=False)

    say("next, your first test, then the bundled suites:")
    say(f"  {here}hil run --bench {profile.name} -- tests")
    say(f"  {here}hil run --bench {profile.name}")
    if not scratch:
        say("  (the smoke suite's round trips need registers nobody else uses: name them in [bench] scratch and "
            "[safety] writable, or hil init --scratch R1000-R1099 --force)")
    return 0


def _refuse_links(*paths: Path) -> None:
    """A symbolic link where init writes, dangling or not, would have it write wherever the link points (another
    user's file, a system file): refused, with or without --force."""
    for path in paths:
        if path.is_symlink():
            raise InvalidValue(f"{path} is a symbolic link (to {os.readlink(path)}): hil init writes no file through "
                               f"one — remove the link, or pass --dir with a directory of your own")


def _write(path: Path, text: str, force: bool) -> None:
    """Write ``path`` itself, never through a link planted there since the check (O_NOFOLLOW; without ``force``
    only a file that does not exist yet, O_EXCL)."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_NOFOLLOW | (os.O_TRUNC if force else os.O_EXCL)
    try:
        fd = os.open(path, flags, 0o666)  # the umask cuts it, as for any file the user writes
    except OSError as exc:
        raise InvalidValue(f"cannot write {path}: {exc.strerror} — hil init writes only a plain file of its own "
                           f"there (no symbolic link; an existing file only with --force)") from None
    with os.fdopen(fd, "w", encoding="utf-8") as out:
        out.write(text)


__all__ = ["Found", "init", "read_plc", "render_profile"]


# -- the command line -----------------------------------------------------------------------------------------------
def add_parser(sub: Subparsers, summary: str) -> None:
    parser = sub.add_parser("init", help=summary,
                            description="Read-only: the PLC's status, identity, RTC chip (D4053) and, with "
                                        "--temperature-table, its temperature table; writes DIR/bench.toml and "
                                        "DIR/tests/test_first.py, with commented placeholders for the rest.",
                            epilog="examples:\n  hil init fatek+tcp://192.168.1.5:500 --temperature-table R3000\n"
                                   "  hil init fatek+serial:///dev/ttyUSB0 --dir my-bench --name \"line 3\"\n")
    parser.add_argument("url", help="target URL of the PLC (fatek+tcp://HOST:500, fatek+serial:///dev/ttyUSB0, "
                                    "modbus+tcp://HOST:502?unit=1 …)")
    parser.add_argument("--dir", metavar="DIR", default=".", help="where to write (default: here)")
    parser.add_argument("--name", help="the bench's name, which keys its run history (default: the directory's name)")
    parser.add_argument("--scratch", metavar="RANGE", action="append", default=[],
                        help="registers or bits nobody else uses on this PLC (e.g. R1000-R1099; again for more): "
                             "[bench] scratch and [safety] writable, for the smoke suite's round trips")
    parser.add_argument("--temperature-table", metavar="ADDRESS",
                        help="where the ladder keeps the temperature table (SR, e.g. R3000): read and filled in")
    parser.add_argument("--time-scale", metavar="N", type=float, default=1.0,
                        help="[bench] time_scale: 1 for a PLC; N for a hil emulate --time-scale N (default 1)")
    parser.add_argument("--force", action="store_true", help="overwrite bench.toml and tests/test_first.py")
    parser.set_defaults(func=command)


def command(args: argparse.Namespace, console: Console) -> int:
    return init(args.url, Path(args.dir), console, name=args.name, table=args.temperature_table,
                scratch=tuple(args.scratch), time_scale=args.time_scale, force=args.force)
