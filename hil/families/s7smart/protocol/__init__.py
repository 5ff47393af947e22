"""Pure codecs of the S7-200 SMART: the READ_RTC/SET_RTC time buffer and the MBUS_SLAVE Modbus map."""
