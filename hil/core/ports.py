"""The TCP port each wire's scheme uses when a URL names none (hil.io.url parses URLs; hil.core.lock keys benches)."""

DEFAULT_PORTS = {"fatek+tcp": 500, "modbus+tcp": 502, "s7+tcp": 102}

__all__ = ["DEFAULT_PORTS"]
