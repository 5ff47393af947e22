import pytest

from hil.core.errors import TargetError
from hil.io.url import parse_target


@pytest.mark.parametrize("url, scheme, protocol, in_process", [
    ("emulator", "emulator", "local", True),
    ("emulator+fatek-tcp", "emulator+fatek-tcp", "fatek", True),
    ("emulator+modbus-rtu", "emulator+modbus-rtu", "modbus", True),
    ("fatek+tcp://10.0.0.5:500", "fatek+tcp", "fatek", False),
    ("modbus+tcp://plc:1502?unit=3", "modbus+tcp", "modbus", False),
    ("fatek+rfc2217://exporter:3001?station=1", "fatek+rfc2217", "fatek", False),
    ("modbus+rfc2217://exporter:3002?unit=1", "modbus+rfc2217", "modbus", False),
])
def test_target_forms(url, scheme, protocol, in_process):
    target = parse_target(url)
    assert (target.scheme, target.protocol, target.in_process) == (scheme, protocol, in_process)


def test_serial_parameters_are_typed():
    target = parse_target("fatek+serial:///dev/ttyUSB0?baudrate=19200&parity=e&bytesize=7&station=2&timeout=0.5")
    assert target.device == "/dev/ttyUSB0"
    assert target.params == {"baudrate": 19200, "parity": "E", "bytesize": 7, "station": 2, "timeout": 0.5}


def test_rfc2217_targets_name_the_server_and_the_line_settings():
    target = parse_target("fatek+rfc2217://exporter:3001?station=2&baudrate=9600&parity=e&bytesize=7&stopbits=1"
                          "&timeout=0.5&retries=1")
    assert (target.host, target.port, target.device) == ("exporter", 3001, "")
    assert target.serial_port == "rfc2217://exporter:3001"
    assert target.params == {"station": 2, "baudrate": 9600, "parity": "E", "bytesize": 7, "stopbits": 1,
                             "timeout": 0.5, "retries": 1}
    assert parse_target("modbus+rfc2217://[::1]:3002?unit=1").serial_port == "rfc2217://[::1]:3002"
    assert parse_target("modbus+rtu:///dev/ttyS0").serial_port == "/dev/ttyS0"


def test_default_ports():
    assert parse_target("fatek+tcp://plc").port == 500
    assert parse_target("modbus+tcp://plc").port == 502


@pytest.mark.parametrize("url, message", [
    ("emulator+fatek", "unknown emulator target"),
    ("http://plc", "unknown scheme 'http'"),
    ("fatek+tcp://plc?baud=1", "unknown parameter 'baud'"),
    ("modbus+rtu:///dev/ttyS0?unit=x", "unit='x' is not a valid int"),
    ("fatek+serial:///dev/ttyS0?parity=Q", "parity must be N, E or O"),
    ("modbus+rtu://", "names no serial device"),
    ("fatek+rfc2217://exporter", "names no port: an RFC 2217 server has no standard one"),
    ("modbus+rfc2217://:3001", "names no host"),
    ("fatek+rfc2217://exporter:3001?unit=1", "unknown parameter 'unit'"),
])
def test_bad_targets_say_what_is_wrong(url, message):
    with pytest.raises(TargetError, match=message):
        parse_target(url)
