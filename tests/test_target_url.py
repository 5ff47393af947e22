import pytest

from hil.core.errors import TargetError
from hil.io.url import parse_target


@pytest.mark.parametrize("url, scheme, protocol, in_process", [
    ("emulator", "emulator", "local", True),
    ("emulator+fatek-tcp", "emulator+fatek-tcp", "fatek", True),
    ("emulator+modbus-rtu", "emulator+modbus-rtu", "modbus", True),
    ("fatek+tcp://10.0.0.5:500", "fatek+tcp", "fatek", False),
    ("modbus+tcp://plc:1502?unit=3", "modbus+tcp", "modbus", False),
])
def test_target_forms(url, scheme, protocol, in_process):
    target = parse_target(url)
    assert (target.scheme, target.protocol, target.in_process) == (scheme, protocol, in_process)


def test_serial_parameters_are_typed():
    target = parse_target("fatek+serial:///dev/ttyUSB0?baudrate=19200&parity=e&bytesize=7&station=2&timeout=0.5")
    assert target.device == "/dev/ttyUSB0"
    assert target.params == {"baudrate": 19200, "parity": "E", "bytesize": 7, "station": 2, "timeout": 0.5}


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
])
def test_bad_targets_say_what_is_wrong(url, message):
    with pytest.raises(TargetError, match=message):
        parse_target(url)
