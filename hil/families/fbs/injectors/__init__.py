"""Fault injectors, one concept a module: the profile's ``[faults.*]`` tables (:mod:`.config`), what every injector
is (:mod:`.injector`), and the kinds that need nothing but the bench — the in-process emulator (:mod:`.emulator`), a
bit on the PLC (:mod:`.plc_bit`), the operator (:mod:`.manual`) — and the relay module on Modbus (:mod:`.modbus_coil`).
The bench's set of injectors is :mod:`hil.families.fbs.faults`'s."""
