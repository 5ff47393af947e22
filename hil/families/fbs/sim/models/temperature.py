"""FBs temperature modules in the emulator (manual ch. 20.1–20.4; spec/fbs-temperature.md).

What the model does every scan, as the FBs OS does:

* reads the temperature table at SR (the profile's ``table``); without A556H at SR+0 nothing is measured;
* checks it (module count 1–8 else FEH, at most 32 points else FFH), compares each table module with the module
  actually fitted (``fitted``; mismatch → bit k of TW+0's low byte, its points are not measured);
* measures the fitted modules' points one at a time (the modules multiplex), each module going round all its
  points once per update time; each measurement reads the point's installed bit (R4010/R4011) then writes its
  reading and its break bit (TW+1/TW+2);
* writes the execution code 56H once every point has been measured once.

Each point's true temperature comes from a *source*: any callable ``source(t) -> °C`` of virtual time
(:class:`Fixed`, :class:`Ramp`, or a thermal plant later), set with :meth:`TemperatureModel.set_source`.

The decisions a broken PLC could get wrong are small methods (``installed``, ``point_result``,
``break_position``, ``execution_code``) so the harness's tests can build broken variants as tiny subclasses.
On a real PLC the ladder/WinProladder writes the table; here :meth:`power_on` plays that part.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Sequence

from hil.core.errors import InvalidValue
from hil.sim.model import Model
from hil.families.fbs import registers as reg
from hil.families.fbs.registers import signed16
from hil.families.fbs.temperature import (BREAK_VALUE, EXEC_BAD_MODULE_COUNT, EXEC_IDLE, EXEC_MEASURING,
                                 EXEC_TOO_MANY_POINTS, MAX_MODULES, MAX_POINTS, MODULE_BY_CODE, SENSOR_BY_CODE,
                                 TABLE_MARKER, ModuleType, TemperatureConfig, decode_start, to_unit)

if TYPE_CHECKING:
    from hil.families.fbs.sim.plc import Emulator
    from hil.families.fbs.sim.memory import Memory

Source = Callable[[float], float]  # virtual seconds since power-on → true temperature, °C

_MASK_LOW = int(reg.INSTALLED_LOW[1:])  # R4010


@dataclass(frozen=True)
class Fixed:
    celsius: float

    def __call__(self, t: float) -> float:
        return self.celsius


@dataclass(frozen=True)
class Ramp:
    start: float
    per_s: float
    low: float = -math.inf
    high: float = math.inf

    def __call__(self, t: float) -> float:
        return min(max(self.start + self.per_s * t, self.low), self.high)


def source_from_spec(spec: dict) -> Source:
    if spec["kind"] == "fixed":
        return Fixed(float(spec["celsius"]))
    return Ramp(float(spec["start"]), float(spec["per_s"]), float(spec.get("low", -math.inf)),
                float(spec.get("high", math.inf)))


class TemperatureModel(Model):
    name = "temperature"

    def __init__(self, config: TemperatureConfig, *, fitted: Sequence[ModuleType] | None = None,
                 write_table: bool = True) -> None:
        self.config = config
        #: The modules physically plugged in, in expansion order (default: those the profile names).
        self.fitted: list[ModuleType] = list(fitted if fitted is not None else (m.type for m in config.modules))
        self.write_table = write_table
        self.sources: dict[int, Source] = {}
        for point in range(config.points):
            _, module = config.point_module(point)
            low, high = module.sensor.low_c, module.sensor.high_c
            base = 25.0 if low <= 25.0 <= high else low + 50.0
            self.sources[point] = Fixed(round(base + 0.3 * point, 1))
        for point, spec in config.sources.items():
            self.sources[point] = source_from_spec(spec)
        self.broken: set[int] = set()
        self.state = "idle"
        self._samples: dict[int, collections.deque[float]] = {}
        self._measured: set[int] = set()
        self._next: list[float] = [0.0] * len(self.fitted)  # virtual time of each fitted module's next point
        #: the fitted modules the table had measured at the last full scan (a mismatched or unlisted module's
        #: schedule stands still: it must not look due)
        self._active: tuple[int, ...] = tuple(range(len(self.fitted)))
        self._mux: list[int] = [0] * len(self.fitted)  # the point (within the module) measured next
        self._breaks = 0  # 32 break bits as the model last wrote them
        self._break_key: int | None = None  # _breaks for which _break_value was computed
        self._break_value = (0, 0)
        self._layout_cache: dict[tuple[int, ...], tuple] = {}
        self._plan_cache: dict[tuple, tuple] = {}
        #: the last scan's result while nothing can change it: (table words, next measurement due, bank, first
        #: index, block) — a scan with the same table before that time only rewrites the block (see scan)
        self._quiet: tuple | None = None
        #: while a FUN86 model runs: point → [(time, reading)] measured since its last scan (it replays them), and
        #: where those readings are (kind, first index)
        self.log: dict[int, list[tuple[float, int]]] | None = None
        self.log_start: tuple[str, int] | None = None
        self._upper_cache: dict[int, tuple] = {}

    # -- faults and sources (fault injectors, plants) ---------------------------------------------------------
    def set_source(self, point: int, source: Source) -> None:
        self._check_point(point)
        self.sources[point] = source
        self._samples.pop(point, None)

    def open(self, point: int) -> None:
        """Open point's sensor circuit (a broken thermocouple); seen at the point's next measurement."""
        self._check_point(point)
        self.broken.add(point)

    def repair(self, point: int) -> None:
        self._check_point(point)
        self.broken.discard(point)

    @staticmethod
    def _check_point(point: int) -> None:
        if not 0 <= point < MAX_POINTS:
            raise InvalidValue(f"temperature point {point} is outside 0–{MAX_POINTS - 1}")

    # -- the seams broken variants override ----------------------------------------------------------------------
    def installed(self, mem: "Memory", point: int) -> bool:
        """Point's bit in R4010 (points 0–15) or R4011 (16–31)."""
        return bool(mem.words["R"][_MASK_LOW + point // 16] >> (point % 16) & 1)

    def point_result(self, point: int, installed: bool, broken: bool, live: int) -> tuple[int, bool]:
        """(reading, break bit) of one measurement."""
        if not installed:
            return 0, False
        if broken:
            return BREAK_VALUE, True
        return live, False

    def break_position(self, point: int) -> tuple[int, int]:
        """(offset from TW, bit) of the point's break bit."""
        return 1 + point // 16, point % 16

    def execution_code(self, state: str, all_measured: bool) -> int:
        if state == "bad_module_count":
            return EXEC_BAD_MODULE_COUNT
        if state == "too_many_points":
            return EXEC_TOO_MANY_POINTS
        if state == "measuring" and all_measured:
            return EXEC_MEASURING
        return EXEC_IDLE

    # -- the engine ---------------------------------------------------------------------------------------------
    def power_on(self, emu: "Emulator") -> None:
        if self.write_table:
            emu.memory.write(self.config.table, self.config.table_words())
        self._quiet = None
        for k, module in enumerate(self.fitted):
            self._next[k] = emu.now + self._step(module)

    def next_event(self, now: float) -> float:
        # Measurements are caught up at the next scan, each at its scheduled time (see _measure_module), so a
        # time jump loses nothing and the model never needs a scan of its own between requests.
        return math.inf

    def next_measurement(self) -> float:
        """Virtual time of the next scheduled measurement of any point (a PID acting on PV may need a scan then)."""
        return min((self._next[k] for k in self._active), default=math.inf)

    def _step(self, module: ModuleType) -> float:
        return module.update_s[self.config.rate] / module.points

    def _layout(self, key: tuple[int, ...]) -> tuple:
        """The table's decoded layout (state, readings, work, codes, modules, total), cached on its raw words."""
        cached = self._layout_cache.get(key)
        if cached is None:
            count = key[1]
            readings, work = decode_start(key[2]), decode_start(key[3])
            codes = list(key[4:])
            table_modules = [MODULE_BY_CODE.get(c & 0xFF) for c in codes]
            total = sum(m.points for m in table_modules if m)
            if count == 0 or count > MAX_MODULES:
                state = "bad_module_count"
            elif total > MAX_POINTS:
                state = "too_many_points"
            else:
                state = "measuring"
            if len(self._layout_cache) > 64:
                self._layout_cache.clear()
            cached = self._layout_cache[key] = (state, readings, work, codes, table_modules, total)
        return cached

    def _plan(self, codes: list[int], table_modules: list, readings_word: int) -> tuple:
        """(mismatch bits, points expected, TW entries with the mux words 0, [(k, first point, code)] measured),
        cached on the table and the fitted modules."""
        key = (tuple(codes), readings_word, tuple(id(m) for m in self.fitted))
        plan = self._plan_cache.get(key)
        if plan is None:
            mismatch, expected, entries, measured = 0, set(), [], []
            first = 0
            for k, (code, tm) in enumerate(zip(codes, table_modules)):
                points = tm.points if tm else 0
                matches = tm is not None and k < len(self.fitted) and self.fitted[k] is tm
                if not matches:
                    mismatch |= 1 << k
                else:
                    expected.update(range(first, first + points))
                    measured.append((k, first, code))
                entries += [(code & 0xFF00) | (8 * k & 0xFF), points << 8 | k, (readings_word + first) & 0xFFFF, 0]
                first += points
            if len(self._plan_cache) > 64:
                self._plan_cache.clear()
            plan = self._plan_cache[key] = (mismatch, frozenset(expected), tuple(entries), tuple(measured))
        return plan

    def scan(self, emu: "Emulator") -> None:
        quiet = self._quiet
        if quiet is not None:
            header, due, bank, first, block, words, sr = quiet
            # (the table's words equal to the recorded header, marker and count included — equal count, equal
            # length — is the same test as the full path's header comparison below)
            if emu.now + 1e-9 < due and words[sr:sr + len(header)] == header:
                # Same table, no measurement due: the model's state (mux, breaks, measured points) cannot have
                # changed since the last scan, so neither has the block — rewrite it (the host may have scribbled
                # over it).
                bank[first:first + len(block)] = block
                return
        mem = emu.memory
        words = mem.words[self.config.table.kind]
        sr = self.config.table.index
        self._active = ()
        if words[sr] != TABLE_MARKER:
            self.state = "idle"
            return
        count = words[sr + 1]
        header = tuple(words[sr:sr + 4 + min(count, MAX_MODULES)])
        self._quiet = None
        state, readings, work, codes, table_modules, total = self._layout(header)
        if work is None:  # nowhere to report anything
            self.state = "idle"
            return
        self.state = state
        mismatch = 0
        expected: frozenset[int] = frozenset()
        entries: list[int] = []
        if self.state == "measuring" and readings is not None:
            plan = self._plan(codes, table_modules, words[sr + 2])
            mismatch, expected, entries, measured = plan
            self._active = tuple(k for k, _first, _code in measured)
            now = emu.now
            for k, first, code in measured:
                if self._next[k] <= now + 1e-9:
                    self._measure_module(emu, k, first, code >> 8, readings)
            entries = list(entries)
            for k in range(min(len(codes), len(self._mux))):
                entries[4 * k + 3] = self._mux[k]
        all_measured = bool(expected) and expected <= self._measured
        head = self.execution_code(self.state, all_measured) << 8 | mismatch
        low, high = self._break_words()
        block = [head, low, high, (total if self.state != "bad_module_count" else 0) << 8 | count & 0xFF]
        block += entries
        bank = mem.words.get(work.kind)
        if bank is not None:
            block = [v & 0xFFFF for v in block]
            bank[work.index:work.index + len(block)] = block
            if self.state == "measuring" and readings is not None:
                due = min((self._next[k] for k, _first, _code in measured), default=math.inf)
                self._quiet = (list(header), due, bank, work.index, block, words, sr)
        else:
            mem.write(work, block)

    def _break_words(self) -> tuple[int, int]:
        """TW+1 and TW+2 from the break bits, each placed where :meth:`break_position` says."""
        if self._breaks == self._break_key:
            return self._break_value
        self._break_key, self._break_value = self._breaks, self._compute_break_words()
        return self._break_value

    def _compute_break_words(self) -> tuple[int, int]:
        words = {1: 0, 2: 0}
        for point in range(MAX_POINTS):
            if self._breaks >> point & 1:
                offset, bit = self.break_position(point)
                words[offset] = words.get(offset, 0) | 1 << bit
        return words[1] & 0xFFFF, words[2] & 0xFFFF

    def _measure_module(self, emu: "Emulator", k: int, first: int, sensor_code: int, readings) -> None:  # noqa: ANN001
        module = self.fitted[k]
        step = self._step(module)
        cycle = module.update_s[self.config.rate]
        # After a long jump only the last `averaging` cycles can still show in a reading: skip whole cycles
        # before them (the multiplexer ends each cycle where it began, so the schedule is unchanged).
        keep = (self.config.averaging + 1) * cycle
        if emu.now - self._next[k] > keep and self.log is None:  # (a FUN86 replaying the readings needs them all)
            self._next[k] += math.floor((emu.now - self._next[k] - keep) / cycle) * cycle
        if self._plain():
            self._measure_plain(emu, k, first, sensor_code, readings, module.points, step)
            return
        while self._next[k] <= emu.now + 1e-9:
            point = first + self._mux[k]
            self._measure_point(emu, point, sensor_code, readings, self._next[k])
            self._mux[k] = (self._mux[k] + 1) % module.points
            self._next[k] += step

    def _plain(self) -> bool:
        """No seam of a measurement is overridden (a broken variant's are): the inlined loop below applies."""
        cls = type(self)
        return cls is TemperatureModel or all(getattr(cls, name) is getattr(TemperatureModel, name) for name in
                                              ("installed", "point_result", "_live", "_measure_point"))

    def _measure_plain(self, emu: "Emulator", k: int, first: int, sensor_code: int, readings,  # noqa: ANN001
                       points: int, step: float) -> None:
        """_measure_point for each due measurement of module k, inlined (the same arithmetic, in the same order)."""
        mem = emu.memory
        mask = mem.words["R"][_MASK_LOW:_MASK_LOW + 2]
        out, base = mem.words[readings.kind], readings.index
        broken, sources, samples_of = self.broken, self.sources, self._samples
        sensor = SENSOR_BY_CODE.get(sensor_code)
        low, high = (sensor.low_c, sensor.high_c) if sensor is not None else (None, None)
        fahrenheit = self.config.unit != "C"
        fast = self.config.rate == "fast"
        averaging = self.config.averaging
        log = self.log
        if log is not None:
            self.log_start = (readings.kind, readings.index)
        limit = emu.now + 1e-9
        at, mux = self._next[k], self._mux[k]
        breaks, measured = self._breaks, self._measured.add
        while at <= limit:
            point = first + mux
            if mask[point // 16] >> (point % 16) & 1 and point not in broken:
                celsius = sources[point](at)
                if low is not None:
                    celsius = min(max(celsius, low), high)
                value = celsius * 9 / 5 + 32 if fahrenheit else celsius
                samples = samples_of.get(point)
                if samples is None:
                    samples = samples_of[point] = collections.deque(maxlen=averaging)
                samples.append(value)
                mean = value if len(samples) == 1 else mean_of(samples)
                reading = int(round(mean)) * 10 if fast else int(round(mean * 10))
                breaks &= ~(1 << point)
            else:
                samples_of.pop(point, None)
                if point in broken and mask[point // 16] >> (point % 16) & 1:
                    reading = BREAK_VALUE
                    breaks |= 1 << point
                else:
                    reading = 0
                    breaks &= ~(1 << point)
            word = reading & 0xFFFF
            out[base + point] = word
            if log is not None:
                entries = log.get(point)
                if entries is None:
                    log[point] = [(at, signed16(word))]
                else:
                    entries.append((at, signed16(word)))
            measured(point)
            mux = (mux + 1) % points
            at += step
        self._next[k], self._mux[k], self._breaks = at, mux, breaks

    def _measure_point(self, emu: "Emulator", point: int, sensor_code: int, readings,  # noqa: ANN001
                       at: float) -> None:
        """One measurement of ``point`` as scheduled at virtual time ``at`` (≤ now when caught up)."""
        mem = emu.memory
        installed = self.installed(mem, point)
        broken = point in self.broken
        live = self._live(at, point, sensor_code) if installed and not broken else 0
        if broken or not installed:
            self._samples.pop(point, None)  # [our choice] a repaired sensor reads its live value at once
        reading, flagged = self.point_result(point, installed, broken, live)
        mem.words[readings.kind][readings.index + point] = reading & 0xFFFF
        if self.log is not None:
            self.log_start = (readings.kind, readings.index)
            self.log.setdefault(point, []).append((at, signed16(reading & 0xFFFF)))
        if flagged:
            self._breaks |= 1 << point
        else:
            self._breaks &= ~(1 << point)
        self._measured.add(point)

    def readings_upper(self, mem: "Memory", points) -> float:  # noqa: ANN001
        """The highest reading any of ``points`` can show from now on (``inf`` when the model cannot tell)."""
        cache = self._upper_cache
        samples_of = self._samples
        top = -math.inf
        for point in points:
            source = self.sources.get(point)
            hit = cache.get(point)
            if hit is None or hit[0] is not source:
                hit = cache[point] = (source, self._source_upper(source))
            value = hit[1]
            samples = samples_of.get(point)
            if samples:
                value = max(value, max(samples))
            if value > top:
                top = value
        if (type(self).point_result is not TemperatureModel.point_result or type(self)._live is not TemperatureModel._live
                or math.isinf(top) or any(p in self.broken or not self.installed(mem, p) for p in points)):
            return math.inf
        return (math.ceil(top) + 1) * 10 if self.config.rate == "fast" else math.ceil(top * 10) + 1

    def _source_upper(self, source) -> float:  # noqa: ANN001
        """A source's highest value, in the configured unit (``inf`` when unknown)."""
        if isinstance(source, Fixed):
            celsius = source.celsius
        elif isinstance(source, Ramp):  # falling: never above where it started
            celsius = source.high if source.per_s > 0 else min(max(source.start, source.low), source.high)
        elif hasattr(source, "upper_bound"):
            celsius = source.upper_bound()
        else:
            return math.inf
        return math.inf if math.isinf(celsius) else to_unit(celsius, self.config.unit)

    def _live(self, now: float, point: int, sensor_code: int) -> int:
        """The reading of a working sensor: source → unit → range → averaging → resolution, in 0.1°."""
        sensor = SENSOR_BY_CODE.get(sensor_code)
        celsius = self.sources[point](now)
        if sensor is not None:
            celsius = min(max(celsius, sensor.low_c), sensor.high_c)
        value = to_unit(celsius, self.config.unit)
        samples = self._samples.setdefault(point, collections.deque(maxlen=self.config.averaging))
        samples.append(value)
        mean = mean_of(samples)
        if self.config.rate == "fast":  # 1° resolution, still shown in 0.1° units
            return int(round(mean)) * 10
        return int(round(mean * 10))


def mean_of(samples) -> float:  # noqa: ANN001
    """The average of the last readings, added oldest first: not sum(), whose float algorithm changed in Python
    3.12 (compensated) — the same profile gives the same readings on every Python."""
    total = 0.0
    for value in samples:
        total += value
    return total / len(samples)


def build_temperature_model(config: TemperatureConfig) -> TemperatureModel:
    return TemperatureModel(config)
