"""The ``[faults.<name>]`` tables of a bench profile: which faults and injector kinds exist, and what each table
may say."""

from __future__ import annotations

from typing import Any

from hil.core.errors import AddressError, ProfileError, TargetError
from hil.families.fbs.address import parse
from hil.io.url import parse_target

KINDS = ("emulator", "modbus-coil", "plc-bit", "manual")
KNOWN_FAULTS = ("sensor_break", "heater_open", "ssr_short")
# What each fault does to point p, for the operator's prompt and the docs.  heater_open / ssr_short act on the
# heater circuit of a FUN86-controlled point (the emulator's thermal plant, or a relay/contactor on a bench).
FAULT_ACTIONS = {"sensor_break": ("DISCONNECT the sensor", "RECONNECT the sensor"),
                 "heater_open": ("OPEN the heater circuit", "CLOSE the heater circuit"),
                 "ssr_short": ("BRIDGE the SSR (heater full on)", "REMOVE the SSR bridge")}
PLANT_FAULTS = ("heater_open", "ssr_short")
_KEYS = {"emulator": {"kind"}, "modbus-coil": {"kind", "target", "first_coil", "timeout", "coils"},
         "plc-bit": {"kind", "first"}, "manual": {"kind"}}


def check_fault_configs(faults: dict[str, dict[str, Any]], where: str = "<profile>") -> None:
    """Validate every ``[faults.<name>]`` table; ProfileError names the key and what is wrong."""
    for name, table in faults.items():
        label = f"{where}: [faults.{name}]"
        if name not in KNOWN_FAULTS:
            raise ProfileError(f"{label}: unknown fault (known: {', '.join(KNOWN_FAULTS)})")
        kind = table.get("kind")
        if kind not in KINDS:
            raise ProfileError(f"{label} kind: must be one of {', '.join(KINDS)}, not {kind!r}")
        unknown = set(table) - _KEYS[kind]
        if unknown:
            raise ProfileError(f"{label}: unknown key(s) for kind = {kind!r}: {', '.join(sorted(unknown))} "
                               f"(known: {', '.join(sorted(_KEYS[kind]))})")
        if kind == "modbus-coil":
            try:
                target = parse_target(str(table.get("target", "")))
            except TargetError as exc:
                raise ProfileError(f"{label} target: {exc}") from None
            if target.protocol != "modbus" or target.in_process:
                raise ProfileError(f"{label} target: {target} is not a Modbus URL (modbus+tcp://HOST:PORT?unit=1 "
                                   f"or modbus+rtu:///dev/ttyUSB0?unit=1, modbus+rfc2217://HOST:PORT?unit=1)")
            first = table.get("first_coil", 0)
            if not isinstance(first, int) or isinstance(first, bool) or not 0 <= first <= 65535 - 32:
                raise ProfileError(f"{label} first_coil: must be 0–65503, not {first!r}")
        if kind == "plc-bit":
            try:
                first = parse(str(table.get("first", "")))
            except AddressError as exc:
                raise ProfileError(f"{label} first: {exc} (e.g. first = \"Y40\")") from None
            if not first.is_bit:
                raise ProfileError(f"{label} first: {first} is not a bit (e.g. first = \"Y40\")")
