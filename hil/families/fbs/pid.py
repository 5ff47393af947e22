"""FUN86 TPCTL, the FBs temperature PID instruction (manual ch. 20.7): operand layout and the ``[pid]`` profile section.

Names and layouts only — where an instance's set points, gains, outputs and work registers are, as the bench's
ladder program places them.  What the alarm bits *should* be is stated by the suites, literally from the manual.

Profile shape (every key optional; a missing key takes the manual's example program, EN M0 … WR R300)::

    [pid]                      # one instance, keys directly in [pid] …
    en = "M0"
    [[pid.instances]]          # … or several instances (then no instance keys directly in [pid])
    name = "zone-a"
    en = "M0"                  hc = "M1"   err = "M100"   alm = "M101"
    md = 0                     yn = "Y30"  sn = 0         zn = 10
    sv = "R100"  os = "R110"   pr = "R120" ir = "R130"    dr = "R140"   or = "R200"   wr = "R300"
    sn_register = "R500"       # optional: the ladder takes Sn/Zn from these registers (see example-bench.toml)
    zn_register = "R501"

Every key is validated; blocks of one instance or of different instances that overlap are refused with both
names.  An instance with ``sn_register``/``zn_register`` may be given any Sn/Zn at run time, so its blocks are
sized for 32 points and its points/outputs are not checked against other instances (**[our choice]**: such an
instance exists to check ERR and is switched on only by that suite).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from hil.bench.schema import Key, Section
from hil.core.errors import InvalidValue, ProfileError
from hil.families.fbs.address import Address, parse
from hil.families.fbs.registers import point_bit

MAX_POINTS = 32
WORK_WORDS = 9  # WR … WR+8
OUTPUT_FULL = 16383  # OR value of 100 % output

# Work register offsets (manual 20.7): WR+0/WR+1 "temperature normal" bits of points Sn+0…15 / Sn+16…31,
# WR+2/WR+3 warning bits (pre-alarm or heater loop) likewise.
WR_NORMAL = (0, 1)
WR_WARNING = (2, 3)

# R4005: low byte = PID interval code, high byte = PWM period code → seconds (codes ≥ 5 mean 32 s).
TIMING_SECONDS = (1, 2, 4, 8, 16, 32)


def timing_seconds(code: int) -> int:
    return TIMING_SECONDS[min(code, 5)]


def valid_sn_zn(sn: int, zn: int) -> bool:
    """0 ≤ Sn ≤ 31, 1 ≤ Zn ≤ 32, Sn + Zn ≤ 32 (manual 20.7); anything else: the instruction does nothing, ERR = 1."""
    return 0 <= sn <= 31 and 1 <= zn <= 32 and sn + zn <= 32


# -- the [pid] profile section ----------------------------------------------------------------------------------
# Operand ranges of FUN86 (manual 20.7 operand table): R0–R3839, R5000–R8071, D0–D3999; Yn Y0–Y255.
_WORD_RANGES = {"R": ((0, 3839), (5000, 8071)), "D": ((0, 3999),)}
_SHAPES = {"bit": "a bit (e.g. \"M100\")", "Y": "a Y output; FUN86 drives transistor outputs Yn…",
           "word": "a FUN86 register operand (R0–R3839, R5000–R8071 or D0–D3999)"}


def _is(address: Address, shape: str) -> bool:
    if shape == "bit":
        return address.is_bit
    if shape == "Y":
        return address.kind == "Y"
    return any(lo <= address.index <= hi for lo, hi in _WORD_RANGES.get(address.kind, ()))


def _operand(shape: str) -> Any:
    """The conversion of an operand key: an element of ``shape`` or InvalidValue saying what it is not."""
    def convert(raw: Any) -> Address:
        address = parse(raw)
        if not _is(address, shape):
            raise InvalidValue(f"{address} is not {_SHAPES[shape]}")
        return address
    return convert


def _element_name(raw: Any) -> bool | str:
    return isinstance(raw, str) or "must be an element name such as \"M0\" or \"R100\""


def _key(name: str, shape: str, doc: str, default: str | None = None, **more: Any) -> Key:
    return Key(name, object, doc, default, check=_element_name, convert=_operand(shape), json={"type": "string"},
               **more)


_INSTANCE_KEYS = (
    Key("name", str, "The box's name in reports and suites (distinct per box).", "fun86", pattern=r".+",
        hint="must be a non-empty string", default_doc="\"fun86\" (several boxes: \"fun86-N\")"),
    _key("en", "bit", "EN: the contact that enables the box.", "M0"),
    _key("hc", "bit", "H/C: heating (0) or cooling (1).", "M1"),
    _key("err", "bit", "ERR: the box's error output (bad Sn/Zn).", "M100"),
    _key("alm", "bit", "ALM: the box's alarm output.", "M101"),
    Key("md", int, "Md: the operating mode.", 0, low=0, high=1),
    _key("yn", "Y", "Yn: the first transistor output the box drives (one per point).", "Y30"),
    Key("sn", int, "Sn: the first temperature point the box controls.", 0, low=0, high=31),
    Key("zn", int, "Zn: how many points it controls (Sn + Zn ≤ 32).", 10, low=1, high=32),
    _key("sv", "word", "Sv: the set points, one word per point.", "R100"),
    _key("os", "word", "Os: the deviations (normal band), one word per point.", "R110"),
    _key("pr", "word", "PR: the gains Kc, one word per point.", "R120"),
    _key("ir", "word", "IR: the integral gains Ki, one word per point.", "R130"),
    _key("dr", "word", "DR: the derivative times Td, one word per point.", "R140"),
    _key("or", "word", "OR: the outputs (0–16383), one word per point.", "R200", attr="or_"),
    _key("wr", "word", "WR: the box's work block (9 words).", "R300"),
    _key("sn_register", "word", "Where a test box takes Sn from, so the harness can give it any Sn/Zn (with "
         "zn_register): the ERR checks.", example="R850"),
    _key("zn_register", "word", "Where that box takes Zn from (with sn_register).", example="R851"),
)
PID = Section("pid", "The ladder's FUN86 (TPCTL) boxes: one box's keys directly in [pid], or several boxes, one "
              "[[pid.instances]] each with the same keys (a missing key takes the manual's example program).",
              (*_INSTANCE_KEYS,
               Key("instances", list, "Several boxes: one [[pid.instances]] table each, with the keys above "
                   "(then no box keys directly in [pid]).", [],
                   json={"items": {"$ref": "#/properties/pid"}},  # each box: [pid]'s keys
                   example=[{"name": "oven", "en": "M20", "sv": "R2000", "sn": 4, "zn": 2}])),
              family="fbs")
#: one of several boxes, [[pid.instances]]: the same keys
INSTANCE = Section("pid.instances", PID.doc, _INSTANCE_KEYS, family="fbs", array=True)


@dataclass(frozen=True)
class PidInstance:
    """One FUN86 in the ladder: its contacts, operands, and (optionally) where the ladder takes Sn/Zn from."""

    name: str = PID.default("name")
    en: Address = PID.default("en")
    hc: Address = PID.default("hc")
    err: Address = PID.default("err")
    alm: Address = PID.default("alm")
    md: int = PID.default("md")
    yn: Address = PID.default("yn")
    sn: int = PID.default("sn")
    zn: int = PID.default("zn")
    sv: Address = PID.default("sv")
    os: Address = PID.default("os")
    pr: Address = PID.default("pr")
    ir: Address = PID.default("ir")
    dr: Address = PID.default("dr")
    or_: Address = PID.default("or")
    wr: Address = PID.default("wr")
    sn_register: Address | None = PID.default("sn_register")
    zn_register: Address | None = PID.default("zn_register")

    @property
    def settable(self) -> bool:
        """True when the harness can give this instance any Sn/Zn through registers (the ERR checks)."""
        return self.sn_register is not None and self.zn_register is not None

    @property
    def points(self) -> range:
        """Temperature points this instance controls, as configured (Sn … Sn + Zn − 1)."""
        return range(self.sn, self.sn + self.zn)

    def index(self, point: int) -> int:
        """The operand offset of ``point`` (0 for point Sn)."""
        if point not in self.points:
            raise InvalidValue(f"point {point} is not controlled by FUN86 {self.name!r} (points "
                             f"{self.sn}–{self.sn + self.zn - 1})")
        return point - self.sn

    def operand(self, key: str, point: int) -> Address:
        """The register (``sv``, ``os``, ``pr``, ``ir``, ``dr``, ``or_``) or output (``yn``) of ``point``."""
        return getattr(self, key).offset(self.index(point))

    def bit_position(self, point: int) -> tuple[int, int]:
        """(word offset 0/1 within WR+0/1 or WR+2/3, bit) of ``point``: bit b counts from Sn."""
        return point_bit(self.index(point))

    def blocks(self) -> dict[str, tuple[Address, int]]:
        size = MAX_POINTS if self.settable else self.zn
        out = {k: (getattr(self, k if k != "or" else "or_"), size) for k in ("sv", "os", "pr", "ir", "dr", "or")}
        out["wr"] = (self.wr, WORK_WORDS)
        out["yn"] = (self.yn, size)
        if self.sn_register is not None:
            out["sn_register"] = (self.sn_register, 1)
        if self.zn_register is not None:
            out["zn_register"] = (self.zn_register, 1)
        return out


@dataclass(frozen=True)
class PidConfig:
    instances: tuple[PidInstance, ...] = field(default_factory=lambda: (PidInstance(),))

    def instance(self, name: str | None = None) -> PidInstance:
        if name is None:
            return self.instances[0]
        for inst in self.instances:
            if inst.name == name:
                return inst
        raise KeyError(f"no FUN86 instance named {name!r} (have: {', '.join(i.name for i in self.instances)})")

    def controlling(self, point: int) -> PidInstance | None:
        """The (non-settable) instance whose configured points include ``point``."""
        return next((i for i in self.instances if not i.settable and point in i.points), None)


def parse_pid(section: dict[str, Any], where: str = "<profile>") -> PidConfig:
    """Validate a ``[pid]`` table; ProfileError names the instance, the key and the reason."""
    if not isinstance(section, dict):
        raise ProfileError(f"{where}: [pid] must be a table")
    if "instances" in section:
        extra = set(section) - {"instances"}
        if extra:
            raise ProfileError(f"{where}: [pid] has both instances and instance keys ({', '.join(sorted(extra))}): "
                               f"put every key inside [[pid.instances]]")
        raw = section["instances"]
        if not isinstance(raw, list) or not raw or not all(isinstance(t, dict) for t in raw):
            raise ProfileError(f"{where}: [pid] instances must be a non-empty array of tables ([[pid.instances]])")
    else:
        raw = [section]
    declared = INSTANCE if "instances" in section else PID
    instances = [_parse_instance(t, i, len(raw), where, declared) for i, t in enumerate(raw)]
    names = [i.name for i in instances]
    if len(set(names)) != len(names):
        raise ProfileError(f"{where}: [pid] instance names must differ, got {names}")
    _check_overlaps(instances, where)
    return PidConfig(tuple(instances))


def _parse_instance(table: dict[str, Any], i: int, count: int, where: str, declared: Section) -> PidInstance:
    numbered = f" instances[{i}]" if count > 1 or "name" in table else ""
    label = f"{where}: [pid]{numbered}"
    values = declared.read(table, where, label=f"[pid]{numbered}", nth=i,
                           defaults={"name": PID.default("name") if count == 1 else f"fun86-{i}"})
    values.pop("instances", None)
    if values["sn"] + values["zn"] > MAX_POINTS:
        raise ProfileError(f"{label} sn/zn: Sn + Zn = {values['sn'] + values['zn']} > 32; FUN86 controls points "
                           f"0–31 (a test of ERR sets bad values through sn_register/zn_register instead)")
    if ("sn_register" in table) != ("zn_register" in table):
        raise ProfileError(f"{label}: sn_register and zn_register go together")
    inst = PidInstance(**values)
    for key, (start, size) in inst.blocks().items():
        last = start.index + size - 1
        limit = 255 if start.kind == "Y" else max(hi for lo, hi in _WORD_RANGES[start.kind]
                                                   if lo <= start.index <= hi)
        if last > limit:
            raise ProfileError(f"{label} {key}: the block {start}+{size} runs past {start.kind}{limit}")
    return inst


def _check_overlaps(instances: list[PidInstance], where: str) -> None:
    blocks = []  # (label, kind, first, last)
    for inst in instances:
        for key, (start, size) in inst.blocks().items():
            blocks.append((f"{inst.name}.{key}", start.kind, start.index, start.index + size - 1))
        bits = [("en", inst.en), ("hc", inst.hc), ("err", inst.err), ("alm", inst.alm)]
        for key, a in bits:
            if key in ("err", "alm"):  # outputs of the instruction: nothing else may drive them
                blocks.append((f"{inst.name}.{key}", a.kind, a.index, a.index))
            # EN/H/C are inputs: several instances may share them, but they must not be an output of any block
            for other in instances:
                for okey in ("err", "alm"):
                    oa = getattr(other, okey)
                    if oa == a and key in ("en", "hc"):
                        raise ProfileError(f"{where}: [pid] {inst.name}.{key} = {a} is {other.name}.{okey}, "
                                           f"an output of FUN86")
    for n, (la, ka, fa, ea) in enumerate(blocks):
        for lb, kb, fb, eb in blocks[n + 1:]:
            if ka == kb and fa <= eb and fb <= ea:
                raise ProfileError(f"{where}: [pid] {lb} ({kb}{fb}–{kb}{eb}) overlaps {la} ({ka}{fa}–{ka}{ea})")
    fixed = [i for i in instances if not i.settable]
    for n, one in enumerate(fixed):
        for other in fixed[n + 1:]:
            common = set(one.points) & set(other.points)
            if common:
                raise ProfileError(f"{where}: [pid] {one.name} and {other.name} both control points "
                                   f"{min(common)}–{max(common)} (each point belongs to one FUN86)")
