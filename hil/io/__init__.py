"""Wires, whatever the controller family: target URLs, serial lines, wire traces, Modbus exception names."""
