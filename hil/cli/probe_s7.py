"""``hil probe --bench s7.toml``: an S7-200 SMART bench's CPU — status and the clock buffers, read only.

The S7 clock is read by the bench's test program (READ_RTC on a rising edge of a trigger), so a read-only probe
shows the buffers as the program last left them, the ENO/error of the last clock instruction and the triggers'
state; ``hil run --bench …`` runs the S7 suites, which pulse the triggers.
"""

from __future__ import annotations

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from hil.bench.profile import Profile
from hil.cli.status import status_panel
from hil.families.s7smart.bench import S7Bench
from hil.families.s7smart.protocol import timebuf


def probe_s7(profile: Profile, url: str | None, console: Console) -> int:
    bench = S7Bench(profile, target=url)
    try:
        console.print(status_panel(bench.io.status(), bench.raw.description, family="S7-200 SMART"))
        layout = bench.layout
        if layout is None:
            console.print("[dim]the profile has no [s7rtc] section: no clock buffers to show[/dim]")
            return 0
        table = Table(title="clock (as the test program last left it; hil run pulses the triggers)")
        table.add_column("item")
        table.add_column("value")
        for label, buffer in (("READ_RTC buffer", layout.read_buffer), ("SET_RTC buffer", layout.set_buffer),
                              ("SET_RTC_I buffer", layout.set_i_buffer)):
            if buffer is not None:
                table.add_row(f"{label} {buffer}", _buffer(bench.raw.read_v(buffer.byte, 8)))
        table.add_row(f"ENO {layout.eno}, error {layout.error}",
                      f"{bench.raw.read(layout.eno)}, {bench.raw.read(layout.error):04X}H")
        for trigger in layout.triggers():
            table.add_row(f"trigger {trigger}", str(bench.raw.read(trigger)))
        console.print(table)
    finally:
        bench.close()
    return 0


def _buffer(data: bytes) -> str:
    try:
        when = f" = {timebuf.decode(data):%Y-%m-%d %H:%M:%S}"
    except timebuf.TimeBufferError as exc:
        when = f" [dim](not a valid time: {escape(str(exc))})[/dim]"
    return f"{timebuf.hex_bytes(data)}{when}"
