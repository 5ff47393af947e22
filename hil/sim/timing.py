"""When the emulator's models publish: at once (``instant``, the default) or as a bench may (``bench``).

The manual lets a PLC do several things later than the scan that causes them: a temperature module refreshes its
readings once per update period, a rewritten temperature table takes effect at the next cycle, FUN86 acts on its
PID interval, and no two scans need last as long.  ``bench`` timing does each of those later, at a phase drawn
from one seed within the manual's envelope, so a suite that reads our emulator's instant answer fails here as it
would on a bench.  It is a scheduling decision only: the models' arithmetic is the same code in both modes.

Each draw comes from its own stream, named after what it times (``Random(f"{seed}:{name}")``, whose string seeding
is stable across Python versions and runs), so adding a module or a model never moves another's phase.
"""

from __future__ import annotations

import random
from dataclasses import dataclass

MODES = ("instant", "bench")


@dataclass(frozen=True)
class Timing:
    """The emulator's timing mode, its seed and, in ``bench`` mode, the scan lengths' range in seconds."""

    mode: str = "instant"
    seed: int = 0
    scan_range: tuple[float, float] | None = None

    @property
    def bench(self) -> bool:
        return self.mode == "bench"

    def stream(self, name: str) -> random.Random:
        """The random stream for what ``name`` times (the same name and seed: the same draws)."""
        return random.Random(f"{self.seed}:{name}")

    def phase(self, name: str, period: float) -> float:
        """The delay, in (0, ``period``], before the first time ``name`` acts: 0 in instant mode.  Never 0 in bench
        mode: "later" must be able to mean a whole period later, and never means "in the same scan"."""
        if not self.bench:
            return 0.0
        return period * (1.0 - self.stream(name).random())  # random() is in [0, 1): the phase in (0, period]

    def describe(self) -> str:
        """The mode as a report shows it (the seed is reported on its own)."""
        if not self.bench:
            return "instant"
        if self.scan_range is None:
            return "bench"
        return f"bench (scans {self.scan_range[0] * 1000:g}–{self.scan_range[1] * 1000:g} ms)"


INSTANT = Timing()
