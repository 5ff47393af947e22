"""LocalTransport: direct calls into an in-process emulator (no wire), each one serviced at a scan boundary.

Nothing is checked here that a wire server would not check: the emulator's memory refuses what an FBs does not
have (error A, :class:`hil.families.fbs.sim.memory.Refused`) for this transport and the servers alike, and values
are checked by the base class before any transport sends (tests/test_emulator_parity.py)."""

from __future__ import annotations

from hil.families.fbs.address import Address
from hil.families.fbs.sim.memory import Memory
from hil.families.fbs.sim.plc import Emulator
from hil.families.fbs.transport.base import Limits, PlcStatus, Transport


class LocalTransport(Transport):
    # No wire, but keep the FATEK limits so request counts (and the splitting code) match the real protocol.
    limits = Limits()
    emulator: Emulator  # always: the one it calls into

    def __init__(self, emulator: Emulator) -> None:
        super().__init__("emulator (in-process)")
        self.emulator = emulator

    def _read_words(self, first: Address, count: int) -> list[int]:
        return self.emulator.service(lambda mem: mem.read(first, count))

    def _write_words(self, first: Address, values: list[int]) -> None:
        self.emulator.service(lambda mem: mem.write(first, values))

    _read_bits = _read_words
    _write_bits = _write_words

    def _read_many(self, addresses: list[Address]) -> list[int]:
        return self.emulator.service(lambda mem: [mem.get(a) for a in addresses])

    def _write_many(self, items: list[tuple[Address, int]]) -> None:
        def apply(mem: Memory) -> None:
            for address, value in items:
                mem.set(address, value)
        self.emulator.service(apply)

    def _status(self) -> PlcStatus:
        emu = self.emulator
        running = emu.service(lambda mem: emu.running)
        return PlcStatus(running=running, flags=["RUN"] if running else [],
                         identity={"unit": "emulator", "version": emu.version, "seed": str(emu.seed)},
                         via="in-process")
