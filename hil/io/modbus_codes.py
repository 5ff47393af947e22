"""Modbus exception codes and their standard names (the same for every family's Modbus map)."""

EXCEPTION_NAMES = {
    1: "illegal function", 2: "illegal data address", 3: "illegal data value", 4: "server device failure",
    5: "acknowledge", 6: "server device busy", 7: "negative acknowledge", 8: "memory parity error",
    10: "gateway path unavailable", 11: "gateway target device failed to respond",
}

#: the gateway exceptions, which a Modbus/TCP server also sends for a unit id it does not serve
GATEWAY = (10, 11)
