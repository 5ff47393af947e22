"""``plc.temperature``: read the temperature table, work block and readings, and drive the installed mask.

Procedures and decoding only — which words to read and what their fields are called.  Whether a value is right
is for the suite to say, literally from the manual.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from hil.core.errors import HilError
from hil.families.fbs import faces
from hil.families.fbs import registers as reg
from hil.families.fbs.device.waiting import POLLS_PER_PERIOD, poll_until
from hil.families.fbs.registers import signed16 as signed  # (a reading word as the signed 0.1° value it holds)
from hil.families.fbs.temperature import TemperatureConfig
from hil.families.fbs.temperature_records import BREAK_WORDS_AT, TableView, WorkView

if TYPE_CHECKING:
    from hil.families.fbs.device.core import PlcCore


class Temperature(faces.Temperature):
    """``plc.temperature``: the temperature modules of one FBs PLC (contract and documentation:
    :class:`hil.families.fbs.faces.Temperature`)."""

    def __init__(self, plc: PlcCore, config: TemperatureConfig | None = None) -> None:
        self.plc = plc
        self._config = config

    @property
    def configured(self) -> bool:
        return self._config is not None

    @property
    def config(self) -> TemperatureConfig:
        if self._config is None:
            raise HilError("the bench profile has no [temperature] section: say where the table, readings and "
                           "work block are and which modules are fitted (see fixtures/benches/example-bench.toml)")
        return self._config

    @config.setter
    def config(self, value: TemperatureConfig | None) -> None:
        self._config = value

    # -- reading --------------------------------------------------------------------------------------------------
    def read_table(self) -> TableView:
        return TableView(self.plc.io.read_words(self.config.table, 4 + len(self.config.modules)))

    def read_work(self) -> WorkView:
        return WorkView(self.plc.io.read_words(self.config.work, 4 + 4 * len(self.config.modules)))

    def break_words(self) -> tuple[int, int]:
        low, high = self.plc.io.read_words(self.config.work.offset(BREAK_WORDS_AT), 2)
        return low, high

    def execution_code(self) -> int:
        """TW+0's high byte alone (one word read: all a check of "56H: measuring" needs)."""
        return self.plc.io.read(str(self.config.work)) >> 8

    def readings(self) -> list[int]:
        return [signed(w) for w in self.plc.io.read_words(self.config.readings, self.config.points)]

    def reading(self, point: int) -> int:
        return signed(self.plc.io.read_words(self.config.readings.offset(point), 1)[0])

    # -- the installed mask ---------------------------------------------------------------------------------------
    @staticmethod
    def mask_register(point: int) -> str:
        """R4010 holds points 0–15, R4011 points 16–31."""
        return (reg.INSTALLED_LOW, reg.INSTALLED_HIGH)[reg.point_bit(point)[0]]

    def installed(self, point: int) -> bool:
        return bool(self.plc.io.read(self.mask_register(point)) >> reg.point_bit(point)[1] & 1)

    # -- time -----------------------------------------------------------------------------------------------------
    def update_period(self) -> float:
        return self.config.update_period()

    def wait_for_update(self, periods: float = 1.5) -> None:
        """Let every point be measured again after a change (a margin over one period for scan and wire time)."""
        self.plc.time.wait(self.update_period() * periods)
        self.plc.settle()

    @property
    def poll_interval(self) -> float:
        """Bench seconds between two looks while waiting for a reading to change: the modules' own cadence
        (:func:`~hil.families.fbs.device.waiting.poll_until`'s fraction of the update period)."""
        return self.update_period() / POLLS_PER_PERIOD

    def wait_until(self, event: Callable[[], bool], periods: float = 1.5) -> bool:
        """Poll ``event`` (a read of the PLC) until it holds, at the modules' own cadence (a fraction of the
        update period: :func:`~hil.families.fbs.device.waiting.poll_until`; 0.25 s for a 16TC at 0.1 °), with the
        manual's worst case — every point measured once more, ``periods`` × the update period — as the timeout;
        True if it held.  A test then asserts what it expects as it would after the full wait: an event that never
        comes fails there, a fast PLC costs only the time it takes.  The event must be news — something the test's
        stimulus produces that did not hold before it (a value other than the one read before, a code the previous
        state did not show): a module that refreshes on its own period still shows the previous state for up to a
        period, and a condition that already held would read that as the answer."""
        period = self.update_period()
        return poll_until(self.plc.time, event, period=period, within=period * periods)
