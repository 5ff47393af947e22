"""What a test sees of an FBs bench, as Protocols (``hil.api`` re-exports them under short names).

They are the stable, documented surface, written once: the guard-enforcing proxy of the bench and of the PLC's I/O
is built from them (:mod:`hil.bench.view`), and the areas (``hil.families.fbs.device``) subclass them, so ``mypy``
checks each against its Protocol where it is defined and the areas inherit these docstrings.  Units: temperatures
in 0.1 ° of the profile's ``[temperature] unit``; outputs OR 0–16383 (= 100 %); bench seconds.  Sections:
``spec/fbs-*.md`` (restated from the FBs manual: RTC chapter 17, temperature module chapter 16, FUN86 chapter 20).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable, Iterable, Mapping, Sequence
from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, Protocol

from hil.bench.faces import BenchTime, BenchWithFaults, FaultInjector, Faults, PlcIO

if TYPE_CHECKING:
    from hil.families.fbs.address import Address
    from hil.families.fbs.pid import PidConfig, PidInstance
    from hil.families.fbs.pid_records import AlarmWords, Trace
    from hil.families.fbs.rtc_records import RtcChip, RtcFlags, RtcSnapshot, SetResult
    from hil.families.fbs.rtc_time import RtcTime
    from hil.families.fbs.temperature import TemperatureConfig
    from hil.families.fbs.temperature_records import TableView, WorkView
    from hil.families.fbs.transport.base import Limits
    from hil.io.status import PlcStatus

    Name = str | Address
else:
    Name = object


class FbsIO(PlcIO, Protocol):
    """An FBs PLC's elements (``bench.plc.io``, the ``io`` fixture): ``X``/``Y``/``M``/``S``/``T``/``C`` bits,
    ``R``/``D`` words, ``WM16``-style packed bits, ``DR0``-style 32-bit pairs (spec/fatek-protocol.md).  Reads
    are fenced: no late or repeated reply is taken for an answer.  Writes go through the guard."""

    @property
    def limits(self) -> Limits:
        """The protocol's per-request limits (how large requests are split)."""
        ...

    @property
    def requests_per_read(self) -> int:
        """Round trips one read of a handful of names costs on this wire."""
        ...

    def exclusive(self) -> AbstractContextManager[None]:
        """``with io.exclusive():`` — the wire is this procedure's across several requests: where other processes
        take turns on it (a run's lanes on one serial line), none of theirs comes between, and it waits for its
        turn once rather than before each request."""
        ...

    @property
    def reads_since_write(self) -> int:
        """Reads answered since this wire's last request that may have changed the PLC: on a port that answers at
        a scan's end each spanned a scan, and a settle counts them (0 on a wire that does not count its reads)."""
        ...

    def read_words(self, address: Name, count: int = 1) -> list[int]:
        """``count`` consecutive words from ``address`` in one request where the protocol allows (one scan)."""
        ...

    def read_bits(self, address: Name, count: int = 1) -> list[int]:
        """``count`` consecutive bits (0/1) from ``address``."""
        ...

    def read_many(self, names: Iterable[Name], *, one_scan: bool = True) -> list[int]:
        """Several unrelated elements, in one request (one scan) unless ``one_scan`` is False."""
        ...

    def write_words(self, address: Name, values: Sequence[int]) -> None:
        """Consecutive words from ``address`` (each 0–65535), through the guard."""
        ...

    def write_bits(self, address: Name, values: Sequence[int | bool]) -> None:
        """Consecutive bits from ``address``, through the guard."""
        ...

    def write_many(self, items: Mapping[Name, int] | Iterable[tuple[Name, int]], *,
                   one_scan: bool = True) -> None:
        """Several elements in order, in one request where the protocol allows, through the guard."""
        ...

    def status(self) -> PlcStatus:
        """RUN/STOP, the ladder-check and error flags (FATEK command 40); ``status().summary()`` says it."""
        ...

    def require(self, names: Iterable[Name], action: str, error: type[Exception] | None = None) -> None:
        """Raise before anything is sent when this wire cannot reach one of ``names`` (``action`` names what)."""
        ...

    def budget(self, write: bool = False) -> float | None:
        """The longest one request may take, retries included (seconds), or None when unbounded."""
        ...

    def set_running(self, run: bool) -> None:
        """RUN (True) or STOP (False), FATEK command 41: destructive, only with ``allow_destructive``; restored."""
        ...

    def bit_action(self, name: Name, action: int) -> None:
        """FATEK command 42 on a writable bit: 1 disable, 2 enable, 3 set, 4 reset; its enable state restored."""
        ...


class Rtc(Protocol):
    """The PLC's real-time clock (``bench.plc.rtc``, the ``rtc`` fixture): R4128–R4134 second … weekday, R4135
    hour << 8 | minute, M1952 hold/set, M1953 ±30 s, M1954 installed, M1955 error, D4053 chip, D4054 rate
    (spec/fbs-rtc.md).  The guard puts the clock back at its original offset from the bench's time."""

    def read(self) -> RtcTime:
        """R4128–R4134 in one request (one scan); ``.to_datetime()`` gives a ``datetime`` (ValueError when the
        fields hold no valid date)."""
        ...

    def read_all(self) -> RtcSnapshot:
        """Time, R4135 and the flags M1952–M1955 in one round trip (one scan)."""
        ...

    def read_hour_minute(self) -> int:
        """R4135: hour << 8 | minute (binary), what a ladder compares a shift-change time with."""
        ...

    def read_flags(self) -> RtcFlags:
        """M1952–M1955 (hold, adjust, installed, error)."""
        ...

    @property
    def installed(self) -> bool:
        """M1954: an RTC chip is fitted."""
        ...

    @property
    def chip(self) -> RtcChip:
        """D4053: the chip (``int(chip)`` the code, ``chip.name`` its name)."""
        ...

    @property
    def rate_code(self) -> int:
        """D4054: the S-35390A rate adjustment code (``hil drift decode``)."""
        ...

    def set(self, time: dt.datetime | RtcTime) -> SetResult:
        """The manual's procedure: M1952 := 1, R4128–R4134, M1952 := 0, then M1955.  ``bool(result)`` is True
        when the PLC took it; an invalid ``RtcTime`` is sent as is, for a test that checks the refusal."""
        ...

    def sync_to(self, clock: Callable[[], dt.datetime]) -> SetResult:
        """Set the clock to ``clock()`` at its next whole second (``bench.time.calendar`` for bench time)."""
        ...

    def sync_to_host(self) -> SetResult:
        """Set the clock to the bench's calendar time (``bench.time.calendar()``) at the next whole second."""
        ...

    def time_transition(self, timeout: float = 3.0) -> tuple[dt.datetime, float, float]:
        """The clock's next second transition: (the time shown from then on, the bench time it happened, the
        width in seconds of the bracket around it)."""
        ...

    def adjust_30s(self) -> None:
        """Fire the ±30 s correction (M1953 0 → 1 → 0)."""
        ...


class Temperature(Protocol):
    """The temperature modules' table, readings and work block (``bench.plc.temperature``, the ``temperature``
    fixture), where the profile's ``[temperature]`` says the ladder keeps them (spec/fbs-temperature.md)."""

    @property
    def configured(self) -> bool:
        """True when the profile has a ``[temperature]`` section."""
        ...

    @property
    def config(self) -> TemperatureConfig:
        """The profile's ``[temperature]``: ``table``, ``readings``, ``work``, ``modules``, ``unit`` …"""
        ...

    def read_table(self) -> TableView:
        """The temperature table (SR … SR+3+N): marker, module count, modules and sensor types."""
        ...

    def read_work(self) -> WorkView:
        """The work block: execution code (56H when running), mismatch bits, break words."""
        ...

    def break_words(self) -> tuple[int, int]:
        """TW+1 and TW+2 alone, the break bits of points 0–15 and 16–31 (one read of two words: all a poll for
        the break bits needs, a sixth of the whole block's characters on a slow line)."""
        ...

    def readings(self) -> list[int]:
        """Every configured point's reading, signed, in 0.1 ° of the unit (28767 for a broken fitted sensor)."""
        ...

    def reading(self, point: int) -> int:
        """One point's reading, signed, in 0.1 °.  0 until the module has measured the point once: wait with
        :meth:`wait_for_update` after power-on or a change."""
        ...

    def installed(self, point: int) -> bool:
        """The point's bit in R4010 (points 0–15) / R4011 (16–31)."""
        ...

    def update_period(self) -> float:
        """Bench seconds in which every point is measured once (the slowest module at the configured rate)."""
        ...

    def wait_for_update(self, periods: float = 1.5) -> None:
        """Let every point be measured again (``periods`` update periods of bench time), then settle."""
        ...

    def wait_until(self, event: Callable[[], bool], periods: float = 1.5) -> bool:
        """Poll ``event`` (a read of the PLC) at the modules' cadence until it holds (True), for at most
        ``periods`` update periods (False); assert afterwards as after the full wait."""
        ...


class Pid(Protocol):
    """The ladder's FUN86 (TPCTL) boxes the profile's ``[[pid.instances]]`` describe (``bench.plc.pid``, the
    ``pid`` fixture): set points SV, deviations Os, gains PR/IR/DR, outputs OR, alarm words WR (spec/fbs-pid.md).
    Switching EN on makes FUN86 load its default gains (Kc 110, Ki 17, Td 50) over the point's PR/IR/DR: set the
    gains you mean after :meth:`enable` (the guard journals both and restores the originals)."""

    @property
    def configured(self) -> bool:
        """True when the profile describes at least one FUN86 box."""
        ...

    @property
    def config(self) -> PidConfig:
        """The profile's ``[pid]``: its ``instances``."""
        ...

    def instance(self, name: str | None = None) -> PidInstance:
        """The box named ``name`` in the profile (the only one when None)."""
        ...

    def of(self, point: int) -> PidInstance:
        """The box that controls temperature point ``point``."""
        ...

    def enable(self, inst: PidInstance, on: bool = True, heating: bool | None = True) -> None:
        """EN (and H/C: True heating, False cooling, None leaves it) of a box, in one write."""
        ...

    def restart(self, inst: PidInstance) -> None:
        """EN 0 → 1 across whole scans (a new R4005 takes effect only then)."""
        ...

    def err(self, inst: PidInstance) -> bool:
        """The box's ERR output (bad Sn/Zn)."""
        ...

    def alm(self, inst: PidInstance) -> bool:
        """The box's ALM output (any warning bit of its points)."""
        ...

    def set_set_point(self, point: int, tenths: int) -> None:
        """SV of ``point`` in 0.1 °."""
        ...

    def deviation(self, point: int) -> int:
        """Os of ``point`` in 0.1 °: the "normal" band is SV ± Os."""
        ...

    def set_deviation(self, point: int, tenths: int) -> None:
        """Os of ``point`` in 0.1 °."""
        ...

    def gains(self, point: int) -> tuple[int, int, int]:
        """(Kc, Ki, Td) from PR/IR/DR of ``point``."""
        ...

    def set_gains(self, point: int, kc: int, ki: int, td: int) -> None:
        """PR/IR/DR of ``point`` (after :meth:`enable`, which loads the defaults)."""
        ...

    def output(self, point: int) -> int:
        """OR of ``point``, 0–16383 (16383 = 100 %)."""
        ...

    def output_bit(self, point: int) -> int:
        """The point's PWM output Yn + (point − Sn), 0/1."""
        ...

    def pv(self, point: int) -> int:
        """The PV FUN86 uses for ``point``, signed, 0.1 ° (its reading; 0 before the first measurement)."""
        ...

    def pvs(self, points: Iterable[int]) -> dict[int, int]:
        """PVs of several points in one read."""
        ...

    def set_enabled(self, point: int, on: bool) -> None:
        """The point's enable bit in R4012 (0–15) / R4013 (16–31); a disabled point's output is off."""
        ...

    def alarm_words(self, inst: PidInstance, sn: int | None = None) -> AlarmWords:
        """WR+0 … WR+3 of a box, decoded per point: ``normal(p)`` (SV − Os ≤ PV ≤ SV + Os), ``warning(p)``
        (high-temperature pre-alarm PV ≥ R4008 for 10 scans, or the heater-loop warning), ``normal_points()`` …"""
        ...

    def alarms(self, instances: Iterable[PidInstance]) -> dict[str, AlarmWords]:
        """WR+0 … WR+3 and ALM (``.alm``) of every box in ``instances``, by name, in one planned read (one scan's
        values where they fit one frame)."""
        ...

    def timing(self) -> tuple[int, int]:
        """(PID interval, PWM period) in seconds, from R4005."""
        ...

    def wait_until(self, event: Callable[[], bool], steps: float = 2.0) -> bool:
        """Poll ``event`` at FUN86's cadence until it holds (True), for at most ``steps`` PID intervals plus a
        PWM period (False)."""
        ...

    def record(self, point: int, seconds: float, every: float = 5.0) -> Trace:
        """Sample (t, PV, SV, output) of ``point`` every ``every`` bench seconds for ``seconds``:
        ``trace.settled_at(band)``, ``trace.columns()``, ``trace.to_csv()``."""
        ...


class Plc(Protocol):
    """An FBs PLC as a test holds it (``bench.plc``): its guarded I/O and its areas."""

    @property
    def io(self) -> FbsIO:
        """The PLC's elements, reads and guarded writes."""
        ...

    @property
    def rtc(self) -> Rtc:
        """The real-time clock (R4128–R4135, M1952–M1955, D4053/D4054)."""
        ...

    @property
    def temperature(self) -> Temperature:
        """The temperature modules (the profile's ``[temperature]``)."""
        ...

    @property
    def pid(self) -> Pid:
        """The FUN86 boxes (the profile's ``[pid]``)."""
        ...

    @property
    def time(self) -> BenchTime:
        """The bench's time (the same object as ``bench.time``)."""
        ...

    def status(self) -> PlcStatus:
        """RUN/STOP and the error flags (FATEK command 40)."""
        ...

    def settle(self, scans: int | None = None) -> None:
        """Wait for whole scans after the last write (the profile's ``settle_scans``; proved by the ladder's
        scan counter when ``[bench] scan_counter`` names one, unless ``[bench] answers_at_scan_end`` says the
        port keeps port 0's rule: then, as without a counter, round trips that each span a scan — the reads
        already answered since the last write among them)."""
        ...

    def read_settled(self, names: list[str]) -> list[int]:
        """Settle, then read ``names`` — in one round trip fewer than :meth:`settle` and a read: with a scan
        counter it is read in the same frame as ``names``, until that frame shows a whole scan after the last
        write."""
        ...


class FbsFaults(Faults, Protocol):
    """The FBs bench's fault injectors: the profile's ``[faults.sensor_break]``, ``heater_open``, ``ssr_short``."""

    @property
    def sensor_break(self) -> FaultInjector | None:
        """Opens a thermocouple's circuit (the module then reads 28767 for the point)."""
        ...

    @property
    def heater_open(self) -> FaultInjector | None:
        """Opens a heater circuit (the heater-loop warning's cause)."""
        ...

    @property
    def ssr_short(self) -> FaultInjector | None:
        """Shorts a point's SSR: full heating whatever the output."""
        ...


class Bench(BenchWithFaults, Protocol):
    """The ``bench`` fixture on an FBs bench."""

    @property
    def plc(self) -> Plc:
        """The PLC under test behind the guard."""
        ...

    @property
    def faults(self) -> FbsFaults:
        """The profile's fault injectors."""
        ...


__all__ = ["Bench", "FbsFaults", "FbsIO", "Pid", "Plc", "Rtc", "Temperature"]
