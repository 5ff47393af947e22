"""How the harness reaches an S7-200 SMART: the io over the one Modbus client, S7 (python-snap7), in process."""
