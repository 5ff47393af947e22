"""Servers that put the emulator on a wire: FATEK (TCP, pty) and Modbus (TCP, RTU on a pty)."""
