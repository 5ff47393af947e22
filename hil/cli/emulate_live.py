"""The live panel of ``hil emulate`` on a terminal: the emulator's clock, temperatures, PID words and request
counters, refreshed twice a second.  It reads memory under the emulator's lock without counting as a request."""

from __future__ import annotations

import datetime as dt
import threading
from typing import Any

from rich.console import Group
from rich.live import Live
from rich.panel import Panel
from rich.table import Table
from rich.text import Text

from hil.families.fbs.rtc_time import RtcTime


class LivePanel:
    def __init__(self, emulator: Any, profile: Any, servers: list, time_scale: float, stop: threading.Event) -> None:
        self.emulator = emulator
        self.profile = profile
        self.servers = servers
        self.time_scale = time_scale
        self.stop = stop
        self.temperature = profile.sections.get("temperature")
        self._live = Live(self.render(), refresh_per_second=2, transient=False)
        self._thread = threading.Thread(target=self._loop, name="hil-emulate-live", daemon=True)

    def __enter__(self) -> LivePanel:
        self._live.__enter__()
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self._thread.join(timeout=2)
        self._live.__exit__(None, None, None)

    def _loop(self) -> None:
        while not self.stop.wait(0.5):
            self._live.update(self.render())

    def _read(self, name: str, count: int = 1) -> list[int]:
        with self.emulator.lock:
            return self.emulator.memory.read(name, count)

    def render(self) -> Panel:
        emu = self.emulator
        grid = Table.grid(padding=(0, 2))
        grid.add_column(style="bold cyan", no_wrap=True)
        grid.add_column()
        for handle in self.servers:
            grid.add_row(handle.kind, Text(str(handle.address)))
        grid.add_row("virtual time", f"{emu.now:,.1f} s (× {self.time_scale:g})")
        try:
            words = self._read("R4128", 7)
            grid.add_row("PLC clock", _clock(words))
        except Exception as exc:  # noqa: BLE001 - a panel never stops the emulator
            grid.add_row("PLC clock", Text(f"unreadable: {exc}"))
        try:
            enable = self._read("R4012", 2)
            timing = self._read("R4005", 4)
            grid.add_row("PID", f"enable R4012/R4013 = {enable[0]:04X}H {enable[1]:04X}H; R4005–R4008 = "
                                + " ".join(f"{w:04X}H" for w in timing))
        except Exception as exc:  # noqa: BLE001
            grid.add_row("PID", Text(f"unreadable: {exc}"))
        grid.add_row("requests", Text(", ".join(f"{k} {v}" for k, v in sorted(emu.stats.items())) or "0"))
        parts: list[Any] = [grid]
        if self.temperature is not None:
            parts.append(self._temperatures())
        return Panel(Group(*parts), title=Text(f"hil emulate — {self.profile.name}"), subtitle="Ctrl-C stops",
                     title_align="left", expand=False)

    def _temperatures(self) -> Table:
        config = self.temperature
        table = Table(title=f"temperatures (°{config.unit})", show_header=False, box=None, padding=(0, 1))
        per_row = 6
        for _ in range(per_row):
            table.add_column(justify="right", no_wrap=True)
        try:
            values = [w - 0x10000 if w & 0x8000 else w for w in self._read(str(config.readings), config.points)]
        except Exception as exc:  # noqa: BLE001
            table.add_row(Text(f"unreadable: {exc}"))
            return table
        cells = [("[red]OPEN[/]" if v == 28767 else f"{v / 10:.1f}") for v in values]
        for i in range(0, len(cells), per_row):
            table.add_row(*[f"[dim]{i + j}:[/] {c}" for j, c in enumerate(cells[i:i + per_row])])
        return table


def _clock(words: list[int]) -> str:
    try:
        return str(RtcTime.from_registers(words))
    except Exception:  # noqa: BLE001 - show the raw words when they do not make a date
        return " ".join(str(w) for w in words) + f"  (host {dt.datetime.now():%H:%M:%S})"
