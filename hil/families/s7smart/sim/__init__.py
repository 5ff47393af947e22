"""The S7-200 SMART emulator (memory, clock, test program) and its servers (S7 protocol, Modbus/TCP)."""
