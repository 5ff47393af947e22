"""The compiled span kernel: long stretches of a running FUN86 PLC without a request, in C.

A PLC with temperature modules, running FUN86 loops and the thermal plant needs a scan at every PID interval (and
its models measure ten points a second); in Python that is ~0.5 ms of arithmetic per virtual second.  Between two
requests nothing but the models touches memory, so :func:`advance` packs their state into flat records, lets
``hil.emulator._kernel`` (C, built at install when a compiler is there) run the engine's loop — the same scans at
the same virtual times, the same arithmetic in the same order — and unpacks the result.

It applies only where it is exactly the Python models (:func:`_pack` says why not, otherwise): the stock model
classes (a broken variant overrides a seam → Python), averaging 1, no plant faults, no dead time, every enabled
FUN86 instance running on the temperature model's readings, no register written by one part and read by another.
``tests/test_kernel.py`` runs the same virtual hours both ways and compares every register and model state.
"""

from __future__ import annotations

import array
import os
from typing import TYPE_CHECKING

from hil.fbs.pid import valid_sn_zn
from hil.fbs.temperature import MAX_POINTS, SENSOR_BY_CODE, TABLE_MARKER

try:  # the extension is optional (setup.py): without it every span runs in Python
    from hil.emulator import _kernel
except ImportError:  # pragma: no cover - depends on the install
    _kernel = None

if TYPE_CHECKING:
    from hil.emulator.core import Emulator

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


def advance(emu: "Emulator", target: float) -> bool:
    """Scan ``emu`` up to ``target`` as :meth:`Emulator.advance_to`'s loop would; False if the kernel does not
    apply (then nothing was changed).  Call with the lock held, after the scan that follows a request."""
    if not available() or target - emu.now < MIN_SPAN:
        return False
    packed = _pack(emu, target)
    if packed is None:
        return False
    scans = emu.scans
    buffers = [r.data if isinstance(r, _Records) else r for r in packed.buffers()]
    trace = getattr(emu, "kernel_trace", None)
    if trace is None:
        _kernel.run(*buffers)
    else:  # tests: what every scan of the span left in WR / ALM / Yn / OR of each running instance
        size = 1 + 7 * len(packed.running)
        scans_max = int((target - emu.now) / emu.scan_time) + 2
        out = array.array("d", bytes(8 * size * scans_max))
        for n in range(_kernel.run(*buffers, out)):
            record = out[n * size:(n + 1) * size]
            trace.append((record[0], [tuple(int(v) for v in record[1 + 7 * i:8 + 7 * i])
                                      for i in range(len(packed.running))]))
    if packed.engine.get(0, "scans") != scans:
        packed.unpack()
    emu.stats["kernel_spans"] += 1
    emu.stats["kernel_scans"] += emu.scans - scans
    return True


class _Packed:
    """The models' state as kernel records, and the way back."""

    def __init__(self, emu: "Emulator", parts: dict) -> None:
        self.emu = emu
        self.__dict__.update(parts)

    def buffers(self) -> tuple:
        return (self.engine, self.modules, self.tpoints, self.plant_records, self.instances, self.pids,
                self.normals)

    def unpack(self) -> None:
        emu, tm, fun86, plant = self.emu, self.tm, self.fun86, self.plant
        mem = emu.memory
        eng = self.engine
        emu.now = eng.get(0, "now")
        emu.scans = int(eng.get(0, "scans"))
        # temperature modules: schedule, last samples, break bits, readings written
        for i, k in enumerate(self.module_index):
            tm._next[k] = self.modules.get(i, "next")
            tm._mux[k] = int(self.modules.get(i, "mux"))
        readings = mem.words[self.readings.kind]
        tp = self.tpoints
        breaks = 0
        for point in range(MAX_POINTS):
            if tp.get(point, "breakbit"):
                breaks |= 1 << point
            if not tp.get(point, "written"):
                continue
            readings[self.readings.index + point] = int(tp.get(point, "reading"))
            if tp.get(point, "has_sample"):
                samples = tm._samples.get(point)
                if samples is None:
                    import collections  # noqa: PLC0415 - only when a point starts sampling inside a span
                    samples = tm._samples[point] = collections.deque(maxlen=tm.config.averaging)
                samples.append(tp.get(point, "sample"))
            else:
                tm._samples.pop(point, None)
        tm._breaks = breaks
        tm._quiet = None
        tm.log = {}
        # FUN86: instance and point state, OR / Yn / WR / ALM, the published waveforms
        words, bits = mem.words, mem.bits
        for i, (inst, st) in enumerate(self.running):
            st.next_pid = self.instances.get(i, "next_pid")
            first = int(self.instances.get(i, "first"))
            wr = inst.wr
            words[wr.kind][wr.index:wr.index + 4] = [int(self.instances.get(i, f)) for f in
                                                      ("normal0", "normal1", "warn0", "warn1")]
            bits[inst.alm.kind][inst.alm.index] = int(self.instances.get(i, "alm"))
            for b in range(st.zn):
                r = first + b
                ps = st.points[st.sn + b]
                get = self.pids.get
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
        fun86.waveforms_version = int(eng.get(0, "version"))
        # the plant: each point's anchor and waveform
        pl = self.plant_records
        for i, heated in enumerate(self.heated):
            heated.t0, heated.temp0 = pl.get(i, "t0"), pl.get(i, "temp0")
            if pl.get(i, "wave"):
                heated.wave = (pl.get(i, "started"), pl.get(i, "period"), pl.get(i, "on"), int(pl.get(i, "u_on")),
                               int(pl.get(i, "u_off")), pl.get(i, "wst"))
            else:
                heated.wave = (int(pl.get(i, "u")),)
            heated._memo = []
        plant._last_outputs = None
        # what the last scan's other parts wrote: the clock's registers, the temperature work block
        if self.rtc is not None:
            self.rtc.scan(emu)
        tm.scan(emu)  # no measurement is due at this instant: it only rewrites the work block


def _model_types() -> tuple:
    from hil.emulator.models.fun86 import Fun86Model  # noqa: PLC0415 - the models import the engine
    from hil.emulator.models.plant import ThermalPlant, _Source, _Waved  # noqa: PLC0415
    from hil.emulator.models.rtc import RtcModel  # noqa: PLC0415
    from hil.emulator.models.temperature import Fixed, Ramp, TemperatureModel  # noqa: PLC0415
    return RtcModel, TemperatureModel, Fun86Model, ThermalPlant, _Source, _Waved, Fixed, Ramp


def _pack(emu: "Emulator", target: float) -> _Packed | None:  # noqa: C901, PLR0911, PLR0912, PLR0915
    """The models' state as kernel records, or None when the kernel would not be exactly the Python models."""
    RtcModel, TemperatureModel, Fun86Model, ThermalPlant, _Source, _Waved, Fixed, Ramp = _model_types()
    by_type = {type(m): m for m in emu.models}
    if len(by_type) != len(emu.models) or not set(by_type) <= {RtcModel, TemperatureModel, Fun86Model,
                                                               ThermalPlant}:
        return None
    tm, fun86, plant, rtc = (by_type.get(TemperatureModel), by_type.get(Fun86Model), by_type.get(ThermalPlant),
                             by_type.get(RtcModel))
    if tm is None or fun86 is None or plant is None:
        return None
    if (not plant.waved or any(plant.faults.values()) or plant._fun86 is not fun86 or not fun86.pwm_exact
            or fun86.temperature_model is not tm or tm.config.averaging != 1 or tm.log is None):
        return None
    mem = emu.memory
    table = tm.config.table
    twords = mem.words[table.kind]
    if twords[table.index] != TABLE_MARKER:
        return None
    header = tuple(twords[table.index:table.index + 4 + min(twords[table.index + 1], 8)])
    state, readings, work, codes, table_modules, _total = tm._layout(header)
    if state != "measuring" or readings is None or work is None or readings.kind not in mem.words:
        return None
    if tm.log_start != (readings.kind, readings.index) or readings.index + MAX_POINTS > len(mem.words[readings.kind]):
        return None
    _mismatch, _expected, _entries, measured = tm._plan(codes, table_modules, twords[table.index + 2])

    written: set[tuple[str, int]] = {(readings.kind, readings.index + p) for p in range(MAX_POINTS)}
    written |= {(work.kind, work.index + n) for n in range(4 + 4 * len(codes))}
    read: set[tuple[str, int]] = {(table.kind, table.index + n) for n in range(len(header))}
    read |= {("R", n) for n in range(4003, 4014)}

    # -- temperature modules and points
    modules = _Records("modules", len(measured))
    module_index = []
    for i, (k, first, code) in enumerate(measured):
        module = tm.fitted[k]
        sensor = SENSOR_BY_CODE.get(code >> 8)
        modules.set(i, first=first, points=module.points, step=tm._step(module), next=tm._next[k], mux=tm._mux[k],
                    has_sensor=sensor is not None, low=sensor.low_c if sensor else 0.0,
                    high=sensor.high_c if sensor else 0.0)
        module_index.append(k)
    measured_points = {first + n for _k, first, _code in measured for n in range(tm.fitted[_k].points)}
    heated_index = {id(h): i for i, h in enumerate(plant.points.values())}
    tpoints = _Records("tpoints", MAX_POINTS)
    bank = mem.words[readings.kind]
    for point in range(MAX_POINTS):
        source = tm.sources.get(point)
        values = {"source": 0, "c0": 0.0}
        if point in measured_points:
            if type(source) is Fixed:
                values = {"source": 0, "c0": float(source.celsius)}
            elif type(source) is Ramp:
                values = {"source": 1, "c0": source.start, "c1": source.per_s, "c2": source.low, "c3": source.high}
            elif type(source) is _Source and type(source.heated) is _Waved and id(source.heated) in heated_index \
                    and source.point == point:
                values = {"source": 2, "plant": heated_index[id(source.heated)]}
            else:
                return None
        samples = tm._samples.get(point)
        tpoints.set(point, installed=tm.installed(mem, point), broken=point in tm.broken,
                    upper=tm._source_upper(source), has_sample=bool(samples),
                    sample=samples[-1] if samples else 0.0, reading=bank[readings.index + point],
                    breakbit=tm._breaks >> point & 1, **values)

    # -- FUN86 instances: each is off, invalid (both unchanged from scan to scan) or running on these readings
    instances_list, pid_rows, running = [], [], []
    outputs: dict[tuple[str, int], int] = {}
    for inst, st in zip(fun86.config.instances, fun86.states):
        read |= {(inst.en.kind, inst.en.index), (inst.hc.kind, inst.hc.index)}
        if not mem.bits[inst.en.kind][inst.en.index]:
            if st.running or st.waiting:
                return None
            continue
        if inst.settable:
            read |= {(a.kind, a.index) for a in (inst.sn_register, inst.zn_register)}
        sn, zn = fun86.sn_zn(mem, inst)
        if not valid_sn_zn(sn, zn):
            continue
        if not st.running or st.waiting or not st.executed or (sn, zn) != (st.sn, st.zn):
            return None
        start = fun86.readings_start(mem)
        if start is None or (start.kind, start.index) != (readings.kind, readings.index):
            return None
        r = mem.words["R"]
        first = len(pid_rows)
        instances_list.append(dict(sn=sn, zn=zn, first=first, interval=st.interval, pwm=st.pwm, started=st.started,
                                   next_pid=st.next_pid, heating=mem.bits[inst.hc.kind][inst.hc.index],
                                   limit=r[4008], loop_percent=fun86.loop_threshold(mem), loop_seconds=r[4007],
                                   md=inst.md))
        running.append((inst, st))
        for a in (inst.sv, inst.os, inst.pr, inst.ir, inst.dr):
            read |= {(a.kind, a.index + b) for b in range(zn)}
        for a, count in ((inst.or_, zn), (inst.wr, 4)):
            for b in range(count):
                if (a.kind, a.index + b) in written:
                    return None
                written.add((a.kind, a.index + b))
        for b in range(zn):
            key = (inst.yn.kind, inst.yn.index + b)
            if key in outputs:
                return None
            outputs[key] = first + b
        words = mem.words
        for b in range(zn):
            point = sn + b
            ps = st.points[point]
            wave = fun86.waveforms.get((inst.yn.kind, inst.yn.index + b))
            sv, os_ = (words[inst.sv.kind][inst.sv.index + b], words[inst.os.kind][inst.os.index + b])
            row = dict(point=point, tpoint=point, enabled=fun86.enabled(mem, point),
                       kc=words[inst.pr.kind][inst.pr.index + b], ki=words[inst.ir.kind][inst.ir.index + b],
                       td=words[inst.dr.kind][inst.dr.index + b], sv=sv - 0x10000 if sv & 0x8000 else sv,
                       os=os_ - 0x10000 if os_ & 0x8000 else os_, integral=ps.integral,
                       has_prev=ps.pv_prev is not None, pv_prev=ps.pv_prev or 0, prealarm=ps.prealarm,
                       has_loop=ps.loop_since is not None, loop_since=ps.loop_since or 0.0,
                       out=words[inst.or_.kind][inst.or_.index + b], y=mem.bits[inst.yn.kind][inst.yn.index + b])
            if wave is not None:
                row.update(has_wave=1, w_started=wave[0], w_pwm=wave[1], w_on=wave[2], w_yon=wave[3], w_yoff=wave[4])
            pid_rows.append(row)
    if not running or read & written:
        return None
    # the alarm bits and outputs must not be what another part reads
    bit_writes = set(outputs) | {(inst.alm.kind, inst.alm.index) for inst, _st in running}
    if len(bit_writes) != len(outputs) + len(running) or bit_writes & {k for k in read if k[0] not in mem.words}:
        return None

    # -- the plant
    plant_records = _Records("plant", len(plant.points))
    heated_list = []
    for i, (point, heated) in enumerate(plant.points.items()):
        p, wave = heated.p, heated.wave
        address = plant.heaters[point]
        ref = outputs.get((address.kind, address.index))
        values = dict(ambient=p.ambient, gain=p.gain, tau=p.tau, noise=p.noise, seed=plant.seed, point=point,
                      t0=heated.t0, temp0=heated.temp0, drive=ref is not None, ref=ref or 0,
                      bit=1 if mem.bits[address.kind][address.index] else 0)
        if len(wave) == 1:
            values.update(wave=0, u=wave[0])
        else:
            values.update(wave=1, started=wave[0], period=wave[1], on=wave[2], u_on=wave[3], u_off=wave[4],
                          wst=wave[5])
        plant_records.set(i, **values)
        heated_list.append(heated)

    engine = _Records("engine", 1)
    engine.set(0, now=emu.now, target=target, scan_time=emu.scan_time, scans=emu.scans,
               version=fun86.waveforms_version, fahrenheit=tm.config.unit != "C", fast=tm.config.rate == "fast")
    instances = _Records("instances", len(instances_list))
    for i, values in enumerate(instances_list):
        instances.set(i, **values)
    pids = _Records("pids", len(pid_rows))
    for i, values in enumerate(pid_rows):
        pids.set(i, **values)
    return _Packed(emu, dict(tm=tm, fun86=fun86, plant=plant, rtc=rtc, engine=engine, modules=modules,
                             module_index=module_index, tpoints=tpoints, readings=readings, plant_records=plant_records,
                             heated=heated_list, instances=instances, pids=pids, running=running,
                             normals=_normals(plant.seed)))


def _normals(seed: int) -> array.array:
    table = _NORMALS.get(seed)
    if table is None:
        from hil.emulator.models.plant import _normals as normals  # noqa: PLC0415
        table = _NORMALS[seed] = array.array("d", normals(seed))
    return table

