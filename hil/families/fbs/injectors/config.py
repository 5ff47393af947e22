"""The ``[faults.<name>]`` tables of a bench profile: which faults and injector kinds exist, and what each table
may say."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from hil.bench.schema import Key, Section, located, toml_value
from hil.core.errors import AddressError, InvalidValue, ProfileError
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
_RIG_URL = "modbus+tcp://HOST:PORT?unit=1 or modbus+rtu:///dev/ttyUSB0?unit=1, modbus+rfc2217://HOST:PORT?unit=1"


def _kind(value: Any) -> str:
    if value not in KINDS:
        raise InvalidValue(f"must be one of {', '.join(KINDS)}, not {value!r}")
    return value


def _modbus_url(value: str) -> str:
    target = parse_target(value)
    if target.protocol != "modbus" or target.in_process:
        raise InvalidValue(f"{target} is not a Modbus URL ({_RIG_URL})")
    return value


def _bit(value: str) -> str:
    try:
        first = parse(value)
    except AddressError as exc:
        raise InvalidValue(f"{exc} (e.g. first = \"Y40\")") from None
    if not first.is_bit:
        raise InvalidValue(f"{first} is not a bit (e.g. first = \"Y40\")")
    return value


_COIL = {"kind": ("modbus-coil",)}
FAULTS = Section("faults", "How the bench injects each fault, one table per fault: [faults.sensor_break] opens a "
                 "sensor, [faults.heater_open] a heater circuit, [faults.ssr_short] bridges an SSR; without its "
                 "table a fault's tests skip.", (
    Key("kind", object, "emulator (the emulator's own), modbus-coil (a relay per point on a Modbus relay module: "
        "coil first_coil + point = 1 acts), plc-bit (a PLC output per point, from first) or manual (the operator, "
        "when asked).", required=True, convert=_kind, example="modbus-coil",
        json={"type": "string", "enum": list(KINDS)}),
    Key("target", str, f"The relay module's URL ({_RIG_URL}); a labgrid place's rig fills it in.",
        convert=_modbus_url, when=_COIL, example="modbus+tcp://192.168.1.60:502?unit=1"),
    Key("first_coil", int, "The coil of point 0.", 0, low=0, high=65535 - 32, when=_COIL),
    Key("timeout", float, "Seconds to wait for the relay module's reply.", 2.0, above=0, unit="s", when=_COIL),
    Key("coils", str, "The coils the rig may switch (its allow-list; a labgrid place's rig gives its own).",
        when=_COIL, example="0-95"),
    Key("first", str, "The PLC output of point 0 (add the outputs to [safety] writable).", convert=_bit,
        when={"kind": ("plc-bit",)}, example="Y40"),
), family="fbs", named=KNOWN_FAULTS)


def check_fault_configs(faults: dict[str, dict[str, Any]], where: str = "<profile>") -> None:
    """Validate every ``[faults.<name>]`` table; ProfileError names the key and what is wrong."""
    for name, table in faults.items():
        if name not in KNOWN_FAULTS:
            raise located(ProfileError(f"{where}: [faults.{name}]: unknown fault (known: {', '.join(KNOWN_FAULTS)})"),
                          f"faults.{name}")
        values = replace(FAULTS, name=f"faults.{name}", named=()).read(table, where)
        needed = {"modbus-coil": "target", "plc-bit": "first"}.get(values["kind"])
        if needed and values[needed] is None:
            raise located(ProfileError(f"{where}: [faults.{name}] {needed} is required with kind = "
                                       f"{values['kind']!r} (such as {needed} = "
                                       f"{toml_value(FAULTS.key(needed).example)})"), f"faults.{name}")
