"""``hil probe URL``: is the PLC there, what is it, and a few registers that tell its state."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table

from hil.transport.factory import open_transport

# (label, element) — read only where the wire can reach them.
PROBE_REGISTERS = [
    ("RTC second/minute/hour", "R4128"), ("RTC day/month/year", "R4131"), ("RTC weekday", "R4134"),
    ("RTC chip (D4053)", "D4053"), ("RTC rate code (D4054)", "D4054"),
    ("PID timing R4005", "R4005"), ("heater-loop % R4006", "R4006"), ("heater-loop s R4007", "R4007"),
    ("pre-alarm R4008", "R4008"), ("installed R4010/R4011", "R4010"), ("PID enable R4012/R4013", "R4012"),
]
_COUNTS = {"R4128": 3, "R4131": 3, "R4010": 2, "R4012": 2}


def probe(url: str, console: Console) -> int:
    with open_transport(url) as transport:
        status = transport.status()
        table = Table(title=f"PLC at {transport.description}", show_header=True)
        table.add_column("item")
        table.add_column("value")
        table.add_row("state", status.summary())
        for key, value in status.identity.items():
            table.add_row(key, str(value))
        for label, element in PROBE_REGISTERS:
            reason = transport.unreachable_reason(element)
            if reason:
                table.add_row(label, f"[dim]not reachable: {reason}[/dim]")
                continue
            values = transport.read_words(element, _COUNTS.get(element, 1))
            table.add_row(label, " ".join(f"{v} ({v:04X}H)" for v in values))
        console.print(table)
    return 0
