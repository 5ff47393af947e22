"""Fault injectors, one concept a module: the profile's ``[faults.*]`` tables (:mod:`.config`), what every injector
is (:mod:`.injector`), and the kinds that need nothing but the bench — the in-process emulator (:mod:`.emulator`), a
bit on the PLC (:mod:`.plc_bit`), the operator (:mod:`.manual`).  The relay module on Modbus and the bench's set of
injectors are :mod:`hil.families.fbs.faults`'s."""
