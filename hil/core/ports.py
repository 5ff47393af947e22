"""The TCP port each wire's scheme uses when a URL names none (hil.io.url parses URLs; hil.core.lock keys benches)."""

DEFAULT_PORTS = {"fatek+tcp": 500, "modbus+tcp": 502, "s7+tcp": 102}
#: URL schemes whose target is a HOST:PORT endpoint (an RFC 2217 server has no standard port: none in the table)
NETWORK_SCHEMES = ("tcp", "rfc2217")

__all__ = ["DEFAULT_PORTS", "NETWORK_SCHEMES"]
