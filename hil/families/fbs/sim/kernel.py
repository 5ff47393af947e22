"""The compiled span kernel: long stretches of a running FUN86 PLC without a request, in C.

A PLC with temperature modules, running FUN86 loops and the thermal plant needs a scan at every PID interval (and
its models measure ten points a second); in Python that is ~0.5 ms of arithmetic per virtual second.  Between two
requests nothing but the models touches memory, so :func:`advance` packs their state into flat records, lets
``hil.families.fbs.sim._kernel`` (C, built at install when a compiler is there) run the engine's loop — the same scans at
the same virtual times, the same arithmetic in the same order — and unpacks the result.

It applies only where it is exactly the Python models (:class:`_Span` checks, else raises _Inapplicable): the
stock model classes (a broken variant overrides a seam → Python), known sensors, no plant faults, no dead time,
every enabled FUN86 instance running on the temperature model's readings, the models in scan order temperature →
FUN86 → plant, no register written by one part and read by another, none of the clock's (it is scanned once, at
the end of a span).
``tests/test_kernel.py`` and ``tests/test_kernel_edges.py`` run the same virtual hours both ways and compare every
scan's outputs, every register and every model state.
"""

from __future__ import annotations

import array
import collections
import os
from typing import TYPE_CHECKING

from hil.families.fbs.address import parse
from hil.families.fbs import registers as reg
from hil.families.fbs.registers import signed16
from hil.families.fbs.pid import valid_sn_zn
from hil.families.fbs.temperature import MAX_POINTS, SENSOR_BY_CODE, TABLE_MARKER

try:  # the extension is optional (setup.py): without it every span runs in Python
    from hil.families.fbs.sim import _kernel
except ImportError:  # pragma: no cover - depends on the install
    _kernel = None

if TYPE_CHECKING:
    from hil.families.fbs.sim.plc import Emulator

#: virtual seconds below which packing costs more than the kernel saves (the result is the same either way).
#: Measured on the full PLC (32 loops): a request + span costs 0.78 ms with the kernel whatever the span (packing),
#: 0.54 / 0.88 / 1.86 ms in Python for 4 / 8 / 20 s
MIN_SPAN = 8.0

_FIELDS: dict[str, dict[str, int]] = (
    {kind: {name: i for i, name in enumerate(names)} for kind, names in _kernel.FIELDS.items()} if _kernel else {})


def available() -> bool:
    """Whether the compiled kernel is installed and not switched off (``HIL_KERNEL=0``)."""
    return _kernel is not None and os.environ.get("HIL_KERNEL", "1") != "0"


class _Records:
    """Fixed-layout float64 records of one kind, addressed by field name."""

    def __init__(self, kind: str, count: int) -> None:
        self.fields = _FIELDS[kind]
        self.size = len(self.fields)
        self.data = array.array("d", bytes(8 * self.size * count))

    def set(self, i: int, **values: float) -> None:
        base = i * self.size
        for name, value in values.items():
            self.data[base + self.fields[name]] = value

    def get(self, i: int, name: str) -> float:
        return self.data[i * self.size + self.fields[name]]


_NORMALS: dict[int, array.array] = {}


def _elements(*names: str) -> set[tuple[str, int]]:
    return {(a.kind, a.index) for a in map(parse, names)}


#: what the RTC model reads and writes: R4128–R4135, M1952–M1955, D4053 (chip), D4054 (rate code)
_RTC_ELEMENTS = (_elements(*(f"R{n}" for n in range(parse(reg.RTC_SECOND).index,
                                                     parse(reg.RTC_HOUR_MINUTE).index + 1)))
                 | _elements(reg.RTC_HOLD, reg.RTC_ADJUST_30S, reg.RTC_INSTALLED, reg.RTC_SET_ERROR, reg.RTC_CHIP,
                             reg.RTC_RATE_CODE))


def advance(emu: "Emulator", target: float) -> bool:
    """Scan ``emu`` up to ``target`` as :meth:`Emulator.advance_to`'s loop would; False if the kernel does not
    apply (then nothing was changed).  Call with the lock held, after the scan that follows a request."""
    if not available() or target - emu.now < MIN_SPAN:
        return False
    try:
        span = _Span(emu, target)
    except _Inapplicable:
        return False
    scans = emu.scans
    span.run(getattr(emu, "kernel_trace", None))
    if span.engine.get(0, "scans") != scans:
        span.unpack()
    emu.stats["kernel_spans"] += 1
    emu.stats["kernel_scans"] += emu.scans - scans
    return True


class _Inapplicable(Exception):
    """Here the kernel would not be exactly the Python models."""


def _require(condition: object) -> None:
    if not condition:
        raise _Inapplicable


class _Span:
    """One request-free span: the models' state packed into records, run in C, unpacked."""

    def __init__(self, emu: "Emulator", target: float) -> None:
        self.emu, self.mem = emu, emu.memory
        self._models()
        #: (kind, index) of every word/bit the kernel writes, and of every one it reads as constant: must not meet
        self.written: set[tuple[str, int]] = set()
        self.read = _elements(*(f"R{n}" for n in range(parse(reg.PID_SOURCE_KEY).index,  # R4003–R4013: PID and
                                                         parse(reg.PID_ENABLE_HIGH).index + 1)))  # module settings
        self._pack_temperature()
        self._pack_fun86()
        self._pack_plant()
        _require(not self.read & self.written)
        # the clock is scanned once, at the end of the span: nothing the kernel reads or writes may be its
        _require(self.rtc is None or not _RTC_ELEMENTS & (self.read | self.written))
        self.engine = _Records("engine", 1)
        self.engine.set(0, now=emu.now, target=target, scan_time=emu.scan_time, scans=emu.scans,
                        version=self.fun86.waveforms_version, fahrenheit=self.tm.config.unit != "C",
                        fast=self.tm.config.rate == "fast", averaging=self.tm.config.averaging)

    # -- packing ---------------------------------------------------------------------------------------------------
    def _models(self) -> None:
        """Exactly the stock models (a subclass overrides a seam), a waved plant without faults."""
        from hil.families.fbs.sim.models.fun86 import Fun86Model  # noqa: PLC0415 - the models import the engine
        from hil.families.fbs.sim.models.plant import ThermalPlant  # noqa: PLC0415
        from hil.families.fbs.sim.models.rtc import RtcModel  # noqa: PLC0415
        from hil.families.fbs.sim.models.temperature import TemperatureModel  # noqa: PLC0415
        by_type = {type(m): m for m in self.emu.models}
        _require(len(by_type) == len(self.emu.models)
                 and set(by_type) <= {RtcModel, TemperatureModel, Fun86Model, ThermalPlant})
        self.tm, self.fun86 = by_type.get(TemperatureModel), by_type.get(Fun86Model)
        self.plant, self.rtc = by_type.get(ThermalPlant), by_type.get(RtcModel)
        tm, fun86, plant = self.tm, self.fun86, self.plant
        _require(tm is not None and fun86 is not None and plant is not None)
        self.heated_index = {id(h): i for i, h in enumerate(plant.points.values())}  # a plant point's record
        models = self.emu.models  # a scan runs them in this order; the kernel's is temperature → FUN86 → plant
        _require(models.index(tm) < models.index(fun86) < models.index(plant))
        _require(plant.waved and not any(plant.faults.values()) and plant._fun86 is fun86 and fun86.pwm_exact
                 and fun86.temperature_model is tm and tm.log is not None)

    def _pack_temperature(self) -> None:
        tm, mem = self.tm, self.mem
        table = tm.config.table
        twords = mem.words[table.kind]
        _require(twords[table.index] == TABLE_MARKER)
        header = tuple(twords[table.index:table.index + 4 + min(twords[table.index + 1], 8)])
        state, readings, work, codes, table_modules, _total = tm._layout(header)
        _require(state == "measuring" and readings is not None and work is not None and readings.kind in mem.words)
        _require(tm.log_start == (readings.kind, readings.index)
                 and readings.index + MAX_POINTS <= len(mem.words[readings.kind]))
        measured = tm._plan(codes, table_modules, twords[table.index + 2])[3]
        self.readings = readings
        self.written |= {(readings.kind, readings.index + p) for p in range(MAX_POINTS)}
        self.written |= {(work.kind, work.index + n) for n in range(4 + 4 * len(codes))}
        self.read |= {(table.kind, table.index + n) for n in range(len(header))}

        self.modules = _Records("modules", len(measured))
        self.module_index = []
        for i, (k, first, code) in enumerate(measured):
            module, sensor = tm.fitted[k], SENSOR_BY_CODE.get(code >> 8)
            _require(sensor is not None)  # the range clamp keeps every reading within C's integers
            self.modules.set(i, first=first, points=module.points, step=tm._step(module), next=tm._next[k],
                             mux=tm._mux[k], has_sensor=1, low=sensor.low_c, high=sensor.high_c)
            self.module_index.append(k)
        measured_points = {first + n for k, first, _code in measured for n in range(tm.fitted[k].points)}
        self.tpoints = _Records("tpoints", MAX_POINTS)
        bank = mem.words[readings.kind]
        for point in range(MAX_POINTS):
            source = tm.sources.get(point)
            samples = list(tm._samples.get(point, ()))
            self.tpoints.set(point, installed=tm.installed(mem, point), broken=point in tm.broken,
                             upper=tm._source_upper(source), samples=len(samples),
                             **{f"s{i}": value for i, value in enumerate(samples)},
                             reading=bank[readings.index + point],
                             breakbit=tm._breaks >> point & 1,
                             **(self._source(point, source) if point in measured_points else {}))

    def _source(self, point: int, source: object) -> dict:
        """A measured point's source as the kernel knows them: fixed, ramp, or a point of this plant."""
        from hil.families.fbs.sim.models.plant import _Source, _Waved  # noqa: PLC0415
        from hil.families.fbs.sim.models.temperature import Fixed, Ramp  # noqa: PLC0415
        if type(source) is Fixed:
            return {"source": 0, "c0": float(source.celsius)}
        if type(source) is Ramp:
            return {"source": 1, "c0": source.start, "c1": source.per_s, "c2": source.low, "c3": source.high}
        _require(type(source) is _Source and type(source.heated) is _Waved and source.point == point)
        index = self.heated_index.get(id(source.heated))
        _require(index is not None)
        return {"source": 2, "plant": index}

    def _pack_fun86(self) -> None:
        """Each instance is off or invalid (its scans change nothing then) or running on the temperature readings."""
        fun86, mem = self.fun86, self.mem
        self.running, instances, rows = [], [], []
        self.outputs: dict[tuple[str, int], int] = {}  # Yn… of the running instances → their pid record
        for inst, st in zip(fun86.config.instances, fun86.states):
            self.read |= {(inst.en.kind, inst.en.index), (inst.hc.kind, inst.hc.index)}
            if not mem.bits[inst.en.kind][inst.en.index]:
                _require(not st.running and not st.waiting)
                continue
            if inst.settable:
                self.read |= {(a.kind, a.index) for a in (inst.sn_register, inst.zn_register)}
            sn, zn = fun86.sn_zn(mem, inst)
            if not valid_sn_zn(sn, zn):
                continue
            _require(st.running and not st.waiting and st.executed and (sn, zn) == (st.sn, st.zn))
            start = fun86.readings_start(mem)
            _require(start is not None and (start.kind, start.index) == (self.readings.kind, self.readings.index))
            r = mem.words["R"]
            instances.append(dict(sn=sn, zn=zn, first=len(rows), interval=st.interval, pwm=st.pwm,
                                  started=st.started, next_pid=st.next_pid,
                                  heating=mem.bits[inst.hc.kind][inst.hc.index],
                                  limit=r[parse(reg.PREALARM_LIMIT).index], loop_percent=fun86.loop_threshold(mem),
                                  loop_seconds=r[parse(reg.HEATER_LOOP_SECONDS).index], md=inst.md))
            self.running.append((inst, st))
            self._claim(inst, zn, len(rows))
            rows += [self._pid_row(inst, st, b) for b in range(zn)]
        _require(self.running)
        self.instances = _Records("instances", len(instances))
        for i, values in enumerate(instances):
            self.instances.set(i, **values)
        self.pids = _Records("pids", len(rows))
        for i, values in enumerate(rows):
            self.pids.set(i, **values)

    def _claim(self, inst, zn: int, first: int) -> None:  # noqa: ANN001
        """Record what a running instance reads and writes; two instances may not write the same element."""
        for a in (inst.sv, inst.os, inst.pr, inst.ir, inst.dr):
            self.read |= {(a.kind, a.index + b) for b in range(zn)}
        writes = [(a.kind, a.index + b) for a, count in ((inst.or_, zn), (inst.wr, 4)) for b in range(count)]
        writes += [(inst.yn.kind, inst.yn.index + b) for b in range(zn)] + [(inst.alm.kind, inst.alm.index)]
        _require(not self.written & set(writes) and len(set(writes)) == len(writes))
        self.written |= set(writes)
        self.outputs.update({(inst.yn.kind, inst.yn.index + b): first + b for b in range(zn)})

    def _pid_row(self, inst, st, b: int) -> dict:  # noqa: ANN001
        words, fun86, point = self.mem.words, self.fun86, st.sn + b
        ps = st.points[point]
        row = dict(point=point, enabled=fun86.enabled(self.mem, point),
                   kc=words[inst.pr.kind][inst.pr.index + b], ki=words[inst.ir.kind][inst.ir.index + b],
                   td=words[inst.dr.kind][inst.dr.index + b], sv=signed16(words[inst.sv.kind][inst.sv.index + b]),
                   os=signed16(words[inst.os.kind][inst.os.index + b]), integral=ps.integral,
                   has_prev=ps.pv_prev is not None, pv_prev=ps.pv_prev or 0, prealarm=ps.prealarm,
                   has_loop=ps.loop_since is not None, loop_since=ps.loop_since or 0.0,
                   out=words[inst.or_.kind][inst.or_.index + b], y=self.mem.bits[inst.yn.kind][inst.yn.index + b])
        wave = fun86.waveforms.get((inst.yn.kind, inst.yn.index + b))
        if wave is not None:
            row.update(has_wave=1, w_started=wave[0], w_pwm=wave[1], w_on=wave[2], w_yon=wave[3], w_yoff=wave[4])
        return row

    def _pack_plant(self) -> None:
        plant, bits = self.plant, self.mem.bits
        self.plant_records = _Records("plant", len(plant.points))
        self.heated = list(plant.points.values())
        for i, (point, heated) in enumerate(plant.points.items()):
            p, wave, heater = heated.p, heated.wave, plant.heaters[point]
            ref = self.outputs.get((heater.kind, heater.index))  # a running instance drives it, or it is constant
            if ref is None:
                self.read.add((heater.kind, heater.index))
            seed = plant.seed & 0xFFFFFFFFFFFFFFFF  # all the noise index keeps of it (plant.py _noise_index)
            values = dict(ambient=p.ambient, gain=p.gain, tau=p.tau, noise=p.noise, seed_lo=seed & 0xFFFFFFFF,
                          seed_hi=seed >> 32, point=point,
                          t0=heated.t0, temp0=heated.temp0, drive=ref is not None, ref=ref or 0,
                          bit=1 if bits[heater.kind][heater.index] else 0)
            if len(wave) == 1:
                values.update(wave=0, u=wave[0])
            else:
                values.update(wave=1, started=wave[0], period=wave[1], on=wave[2], u_on=wave[3], u_off=wave[4],
                              wst=wave[5])
            self.plant_records.set(i, **values)

    # -- running -----------------------------------------------------------------------------------------------------
    def run(self, trace: list | None) -> None:
        buffers = [self.engine.data, self.modules.data, self.tpoints.data, self.plant_records.data,
                   self.instances.data, self.pids.data, _normals(self.plant.seed)]
        if trace is None:
            _kernel.run(*buffers)
            return
        # tests: what every scan of the span left in WR / ALM / Yn / OR of each running instance
        per = 1 + 7 * len(self.running)
        scans = int((self.engine.get(0, "target") - self.emu.now) / self.emu.scan_time) + 2
        out = array.array("d", bytes(8 * per * scans))
        for n in range(_kernel.run(*buffers, out)):
            record = out[n * per:(n + 1) * per]
            trace.append((record[0], [tuple(int(v) for v in record[1 + 7 * i:8 + 7 * i])
                                      for i in range(len(self.running))]))

    # -- unpacking -----------------------------------------------------------------------------------------------
    def unpack(self) -> None:
        emu = self.emu
        emu.now = self.engine.get(0, "now")
        emu.scans = int(self.engine.get(0, "scans"))
        self._unpack_temperature()
        self._unpack_fun86()
        self._unpack_plant()
        # what the last scan's other parts wrote: the clock's registers (a formula of the time), the work block
        if self.rtc is not None:
            self.rtc.scan(emu)
        self.tm.scan(emu)  # no measurement is due at this instant: it only rewrites the work block

    def _unpack_temperature(self) -> None:
        tm, tp = self.tm, self.tpoints
        for i, k in enumerate(self.module_index):
            tm._next[k] = self.modules.get(i, "next")
            tm._mux[k] = int(self.modules.get(i, "mux"))
        readings = self.mem.words[self.readings.kind]
        breaks = 0
        for point in range(MAX_POINTS):
            if tp.get(point, "breakbit"):
                breaks |= 1 << point
            if not tp.get(point, "written"):
                continue
            readings[self.readings.index + point] = int(tp.get(point, "reading"))
            count = int(tp.get(point, "samples"))
            if count:
                tm._samples[point] = collections.deque((tp.get(point, f"s{i}") for i in range(count)),
                                                       maxlen=tm.config.averaging)
            else:
                tm._samples.pop(point, None)
        tm._breaks = breaks
        tm._quiet = None
        tm.log = {}  # as the last FUN86 scan left it

    def _unpack_fun86(self) -> None:
        words, bits, fun86, get = self.mem.words, self.mem.bits, self.fun86, self.pids.get
        for i, (inst, st) in enumerate(self.running):
            st.next_pid = self.instances.get(i, "next_pid")
            first = int(self.instances.get(i, "first"))
            words[inst.wr.kind][inst.wr.index:inst.wr.index + 4] = [
                int(self.instances.get(i, f)) for f in ("normal0", "normal1", "warn0", "warn1")]
            bits[inst.alm.kind][inst.alm.index] = int(self.instances.get(i, "alm"))
            for b in range(st.zn):
                r, ps = first + b, st.points[st.sn + b]
                ps.integral = get(r, "integral")
                ps.pv_prev = int(get(r, "pv_prev")) if get(r, "has_prev") else None
                ps.prealarm = int(get(r, "prealarm"))
                ps.loop_since = get(r, "loop_since") if get(r, "has_loop") else None
                words[inst.or_.kind][inst.or_.index + b] = int(get(r, "out"))
                bits[inst.yn.kind][inst.yn.index + b] = int(get(r, "y"))
                if get(r, "has_wave"):
                    fun86.waveforms[(inst.yn.kind, inst.yn.index + b)] = (
                        get(r, "w_started"), get(r, "w_pwm"), get(r, "w_on"), bool(get(r, "w_yon")),
                        bool(get(r, "w_yoff")))
        fun86.waveforms_version = int(self.engine.get(0, "version"))

    def _unpack_plant(self) -> None:
        get = self.plant_records.get
        for i, heated in enumerate(self.heated):
            heated.t0, heated.temp0 = get(i, "t0"), get(i, "temp0")
            if get(i, "wave"):
                heated.wave = (get(i, "started"), get(i, "period"), get(i, "on"), int(get(i, "u_on")),
                               int(get(i, "u_off")), get(i, "wst"))
            else:
                heated.wave = (int(get(i, "u")),)
            heated._memo = []  # a cache of the old waveform's cycles
        self.plant._last_outputs = None


def _normals(seed: int) -> array.array:
    """The plant's table of normals (hil/emulator/models/plant.py) as a float64 buffer, once per seed."""
    table = _NORMALS.get(seed)
    if table is None:
        from hil.families.fbs.sim.models.plant import _normals as normals  # noqa: PLC0415
        table = _NORMALS[seed] = array.array("d", normals(seed))
    return table
