"""Siemens S7-200 SMART: the second controller family.  Its own addressing (V bytes/words, I/Q bits), the
READ_RTC/SET_RTC time buffer, an S7 Modbus map, emulator, device layer and bench — sharing the scan engine,
timebase, pytest plugin and reports with the FBs side.  See ``spec/s7-200smart-rtc.md``.
"""

FAMILY = "s7-200smart"
