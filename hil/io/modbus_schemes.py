"""The Modbus wire's schemes, protocol and emulator wires (:mod:`hil.core.registry`): the client is the one in
:mod:`hil.io.modbus_client`; every family that maps its memory onto Modbus registers these (idempotent)."""

from __future__ import annotations

from hil.core.registry import COMMON, FENCE, PROTOCOLS, SERIAL, Protocol, Scheme, Wire, register_scheme, register_wire


def register_modbus() -> None:
    PROTOCOLS.register("modbus", Protocol("modbus", address_param="unit", serial_scheme="modbus+rtu"))
    register_scheme(Scheme("modbus+tcp", "modbus", {**COMMON, "unit": int}, network=True, default_port=502,
                           lanes=True, example="modbus+tcp://HOST:502?unit=1"))
    register_scheme(Scheme("modbus+rtu", "modbus", {**COMMON, **SERIAL, **FENCE, "unit": int},
                           example="modbus+rtu:///dev/ttyUSB0?baudrate=9600&parity=E&unit=1"))
    register_scheme(Scheme("modbus+rfc2217", "modbus", {**COMMON, **SERIAL, **FENCE, "unit": int}, network=True,
                           example="modbus+rfc2217://HOST:PORT?unit=1"))
    register_wire(Wire("modbus-tcp", "modbus", "tcp", "Modbus/TCP"))
    register_wire(Wire("modbus-rtu", "modbus", "pty", "Modbus RTU on a pseudo-terminal", bytesize=8,
                       aliases=("modbus-pty",)), {**SERIAL, **FENCE})


__all__ = ["register_modbus"]
