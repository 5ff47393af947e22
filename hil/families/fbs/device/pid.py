"""``plc.pid``: FUN86 temperature PID — set points, deviations, gains, outputs, alarm words, and a closed-loop trace.

Procedures and decoding only (which registers, which bits); whether a value is right is for the suite to say.
Configured by the bench from the profile's ``[pid]`` (see :mod:`hil.families.fbs.pid`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING

from hil.core.errors import HilError
from hil.families.fbs import faces
from hil.families.fbs import registers as reg
from hil.families.fbs.address import parse
from hil.families.fbs.device.temperature import Temperature
from hil.families.fbs.device.waiting import poll_until
from hil.families.fbs.pid import MAX_POINTS, PidConfig, PidInstance, timing_seconds
from hil.families.fbs.pid_records import AlarmWords, Sample, Trace
from hil.families.fbs.registers import signed16
from hil.families.fbs.transport.base import NameLike

if TYPE_CHECKING:
    from hil.families.fbs.address import Address
    from hil.families.fbs.device.core import PlcCore


class Pid(faces.Pid):
    """``plc.pid``: the FUN86 boxes of one FBs PLC (contract and documentation: :class:`hil.families.fbs.faces.Pid`).

    ``temperature`` is the PLC's temperature area: FUN86 takes its PVs from the readings it names unless R4003/R4004
    say otherwise (:meth:`readings_start`)."""

    def __init__(self, plc: PlcCore, temperature: Temperature, config: PidConfig | None = None) -> None:
        self.plc = plc
        self.temperature = temperature
        self._config = config

    @property
    def configured(self) -> bool:
        return self._config is not None and bool(self._config.instances)

    @property
    def config(self) -> PidConfig:
        if self._config is None or not self._config.instances:  # (not configured)
            raise HilError("the bench profile has no [pid] section: say where the ladder's FUN86 operands are "
                           "(see fixtures/benches/example-bench.toml)")
        return self._config

    @config.setter
    def config(self, value: PidConfig | None) -> None:
        self._config = value

    def side_effects(self, written: Iterable[Address]) -> list[Address]:
        """What the PLC rewrites itself because of these writes: on EN's rising edge FUN86 loads its default
        gains into PR/IR/DR of every point of the box (fbs-pid.md), so a test that only switches EN on still
        changes the tuned gains; while EN is on it writes OR, WR and drives Yn, and a later EN = 0 leaves them.
        The guard journals these as originals.  A box that takes Sn/Zn from registers reaches the points its
        registers give: :meth:`_reach`."""
        if not self.configured:
            return []
        written = set(written)
        out: list = []
        for inst in self.config.instances:
            reach = self._reach(inst, written)
            if not reach:
                continue
            for key in ("pr", "ir", "dr", "or", "wr", "yn"):
                first, count = inst.blocks()[key]
                out += [first.offset(i) for i in range(count if key == "wr" else min(count, reach))]
        return out

    #: the operand blocks FUN86 only reads while its EN is 1 — its inputs — (a suite's working state:
    #: idle_operands).  Not OR and WR, its outputs: a test judges what FUN86 writes there, so a value an earlier
    #: test left (an output above 0, a latched warning) must not be what it finds.  (PR, IR and DR it also writes
    #: on its first execution, which only a PLC just powered on shows: that test runs first, before any sets them.)
    WORKING_BLOCKS = ("sv", "os", "pr", "ir", "dr")

    def idle_operands(self) -> list[Address]:
        """The words of :attr:`WORKING_BLOCKS` of every box whose EN reads 0 now (one read of every EN): FUN86
        reads none of them while EN stays 0, and a test sets the ones it relies on before switching EN on, so
        a suite may keep them as working state between its tests (hil.plugin.working_state).  A box the ladder
        runs (EN 1), or whose EN the wire cannot read, is left out: its words go back after every test."""
        if not self.configured:
            return []
        io = self.plc.io  # a box whose EN this wire cannot read is not known to be off: left out
        instances = [inst for inst in self.config.instances if io.unreachable_reason(str(inst.en)) is None]
        ens = io.read_many([str(inst.en) for inst in instances]) if instances else []
        out: list = []
        for inst in (inst for inst, en in zip(instances, ens) if not en):
            for first, count in (inst.blocks()[key] for key in self.WORKING_BLOCKS):
                out += [first.offset(i) for i in range(count)]
        return out

    def _reach(self, inst: PidInstance, written: set) -> int:
        """How many points (from the box's first operand) ``written`` may make FUN86 act on: a box of constant
        Sn/Zn its Zn once EN is written; a box with Sn/Zn registers any of the 32 once EN or a register is written.

        Decided from the names alone, never from what the PLC holds now: recovery asks the same question of the
        profile's whole allow-list after a crash (hil.bench.replay), when EN and the registers may read anything —
        an answer that depended on them refused side effects a dead run had left (WR of a box at all-ones)."""
        registers = {inst.sn_register, inst.zn_register} if inst.settable else set()
        if not (registers | {inst.en}) & written:
            return 0
        return MAX_POINTS if registers else inst.zn

    def instance(self, name: str | None = None) -> PidInstance:
        return self.config.instance(name)

    def of(self, point: int) -> PidInstance:
        inst = self.config.controlling(point)
        if inst is None:
            raise HilError(f"no FUN86 instance of the profile controls temperature point {point}")
        return inst

    # -- EN, H/C, ERR, ALM ------------------------------------------------------------------------------------------
    def enable(self, inst: PidInstance, on: bool = True, heating: bool | None = True) -> None:
        items: dict[NameLike, int] = {str(inst.en): int(on)}
        if heating is not None:
            items[str(inst.hc)] = int(heating)
        self.plc.io.write_many(items)

    def restart(self, inst: PidInstance) -> None:
        self.plc.io.write(str(inst.en), 0)
        self.plc.settle()  # the 0 held across whole scans (proved by the scan counter where declared)
        self.plc.io.write(str(inst.en), 1)
        self.plc.settle()

    def err(self, inst: PidInstance) -> bool:
        return bool(self.plc.io.read(str(inst.err)))

    def alm(self, inst: PidInstance) -> bool:
        return bool(self.plc.io.read(str(inst.alm)))

    def set_sn_zn(self, inst: PidInstance, sn: int, zn: int) -> None:
        if not inst.settable:
            raise HilError(f"FUN86 {inst.name!r} takes Sn/Zn as constants: the profile names no sn_register/"
                           f"zn_register")
        registers: dict[NameLike, int] = {str(inst.sn_register): sn & 0xFFFF, str(inst.zn_register): zn & 0xFFFF}
        self.plc.io.write_many(registers)

    # -- per point ------------------------------------------------------------------------------------------------
    def _reg(self, key: str, point: int, inst: PidInstance | None = None) -> str:
        inst = inst or self.of(point)
        return str(inst.operand(key, point))

    def set_set_point(self, point: int, tenths: int) -> None:
        self.plc.io.write(self._reg("sv", point), tenths & 0xFFFF)

    def deviation(self, point: int) -> int:
        return signed16(self.plc.io.read(self._reg("os", point)))

    def set_deviation(self, point: int, tenths: int) -> None:
        self.plc.io.write(self._reg("os", point), tenths & 0xFFFF)

    def gains(self, point: int) -> tuple[int, int, int]:
        kc, ki, td = self.plc.io.read_many([self._reg(k, point) for k in ("pr", "ir", "dr")])
        return kc, ki, td

    def gains_of(self, inst: PidInstance) -> dict[int, tuple[int, int, int]]:
        """(Kc, Ki, Td) of every point of ``inst``: PR, IR and DR each read as one block."""
        blocks = [self.plc.io.read_words(str(getattr(inst, k)), inst.zn) for k in ("pr", "ir", "dr")]
        return {p: (blocks[0][i], blocks[1][i], blocks[2][i]) for i, p in enumerate(inst.points)}

    def set_gains(self, point: int, kc: int, ki: int, td: int) -> None:
        gains: dict[NameLike, int] = {self._reg(key, point): value
                                      for key, value in (("pr", kc), ("ir", ki), ("dr", td))}
        self.plc.io.write_many(gains)

    def output(self, point: int) -> int:
        return self.plc.io.read(self._reg("or_", point))

    def output_bit(self, point: int) -> int:
        return self.plc.io.read(self._reg("yn", point))

    def output_and_bit(self, point: int) -> tuple[int, int]:
        """(OR, Yn) of the point, in one request (one scan)."""
        value, bit = self.plc.io.read_many([self._reg("or_", point), self._reg("yn", point)])
        return value, bit

    def output_bits(self, points: Iterable[int]) -> list[int]:
        """The PWM outputs of ``points``, in one request (one scan)."""
        return self.plc.io.read_many([self._reg("yn", p) for p in points])

    def readings_start(self) -> str:
        """Where FUN86 takes PVs: R4004 when R4003 = A55AH and R4004 names R0–R3839/D0–D3999, else the table's."""
        key, code = self.plc.io.read_words(reg.PID_SOURCE_KEY, 2)
        if key == 0xA55A and (10000 <= code <= 13839 or 20000 <= code <= 23999):
            return f"R{code - 10000}" if code < 20000 else f"D{code - 20000}"
        return str(self.temperature.config.readings)

    def pv(self, point: int) -> int:
        return signed16(self.plc.io.read(str(parse(self.readings_start()).offset(point))))

    def pvs(self, points: Iterable[int]) -> dict[int, int]:
        start = parse(self.readings_start())
        points = list(points)
        words = self.plc.io.read_words(str(start), max(points) + 1)
        return {p: signed16(words[p]) for p in points}

    @staticmethod
    def enable_register(point: int) -> str:
        """R4012 holds points 0–15, R4013 points 16–31."""
        return (reg.PID_ENABLE_LOW, reg.PID_ENABLE_HIGH)[reg.point_bit(point)[0]]

    def set_enabled(self, point: int, on: bool) -> None:
        name = self.enable_register(point)
        self.plc.io.write(name, reg.with_bit(self.plc.io.read(name), reg.point_bit(point)[1], on))

    # -- alarm words ------------------------------------------------------------------------------------------------
    def alarm_words(self, inst: PidInstance, sn: int | None = None) -> AlarmWords:
        w0, w1, w2, w3 = self.plc.io.read_words(str(inst.wr), 4)
        return AlarmWords(inst, (w0, w1, w2, w3), inst.sn if sn is None else sn)

    def alarms(self, instances: Iterable[PidInstance]) -> dict[str, AlarmWords]:
        """WR+0 … WR+3 and ALM of every box in ``instances``, by name, in one planned read — the fewest frames
        (:mod:`hil.families.fbs.transport.plan`), one scan's values where they fit one frame — rather than a
        request per box and another per ALM."""
        instances = list(instances)
        names = [n for inst in instances for n in ([str(inst.wr.offset(i)) for i in range(4)] + [str(inst.alm)])]
        values = self.plc.io.read_many(names)
        out = {}
        for k, inst in enumerate(instances):
            w0, w1, w2, w3, alm = values[5 * k:5 * k + 5]
            out[inst.name] = AlarmWords(inst, (w0, w1, w2, w3), inst.sn, bool(alm))
        return out

    # -- timing -----------------------------------------------------------------------------------------------------
    def timing(self) -> tuple[int, int]:
        word = self.plc.io.read(reg.PID_TIMING)
        return timing_seconds(word & 0xFF), timing_seconds(word >> 8)

    def wait_until(self, event: Callable[[], bool], steps: float = 2.0) -> bool:
        """Poll ``event`` (a read of the PLC) at FUN86's own cadence — a fraction of the PID interval of R4005,
        :func:`~hil.families.fbs.device.waiting.poll_until` — until it holds (True), for at most ``steps`` PID
        intervals plus a PWM period (False): an output follows a change within one PID step, a Y within the PWM
        period after it.  Not back to back: FUN86 changes its outputs only once per interval."""
        interval, pwm = self.timing()
        return poll_until(self.plc.time, event, period=interval, within=steps * interval + pwm)

    # -- closed loop ----------------------------------------------------------------------------------------------
    def record(self, point: int, seconds: float, every: float = 5.0) -> Trace:
        inst = self.of(point)
        trace = Trace(point)
        time = self.plc.time
        start = time.now()
        while True:
            sv = signed16(self.plc.io.read(str(inst.operand("sv", point))))
            out = self.plc.io.read(str(inst.operand("or_", point)))
            pv = self.pv(point)
            t = time.now() - start
            trace.samples.append(Sample(t, pv, sv, out))
            if t >= seconds:
                return trace
            time.wait(min(every, seconds - t) if seconds - t > 0 else every)
