"""The status panel every family's ``hil probe`` prints first."""

from __future__ import annotations

from rich.markup import escape
from rich.panel import Panel
from rich.table import Table

from hil.io.status import PlcStatus


def status_panel(status: PlcStatus, description: str, **extra: str) -> Panel:
    """The PLC's state (coloured: green RUN, yellow STOP), the wire, ``extra`` rows and its identity."""
    running = {True: "green", False: "yellow", None: "dim"}[status.running]
    grid = Table.grid(padding=(0, 2))
    grid.add_column(style="bold cyan", no_wrap=True)
    grid.add_column(overflow="fold")  # a long URL folds onto the next line, never cut
    # the target as a row, not in the title: a title is cut at the panel's width, a row wraps (a long URL whole)
    grid.add_row("target", escape(description))
    grid.add_row("state", f"[{running}]{escape(status.summary())}[/]")
    grid.add_row("via", escape(status.via or description))
    for key, value in [*extra.items(), *status.identity.items()]:
        grid.add_row(escape(key), escape(str(value)))
    return Panel(grid, title="PLC", title_align="left", expand=False,
                 border_style=running)
