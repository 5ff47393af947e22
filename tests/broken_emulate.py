"""``hil emulate`` with a deliberately broken emulator, as a separate process: the bench path of the broken-PLC tests.

    python -m tests.broken_emulate MODULE:FACTORY:DEFECT [hil emulate arguments]

``FACTORY(DEFECT)`` (e.g. ``with_rtc(M1955NeverSet)`` of a ``tests/test_*catch_broken*`` module) gives a
:class:`tests.broken.BrokenEmulator`; the emulator ``hil emulate`` serves is built through it.  Test code only:
the product has no way to load a broken model.
"""

from __future__ import annotations

import importlib
import sys


def main(argv: list[str]) -> int:
    spec, *rest = argv
    module_name, factory, defect = spec.split(":")
    module = importlib.import_module(module_name)
    broken = getattr(module, factory)(getattr(module, defect))
    from hil.cli import emulate as emulate_cli
    emulate_cli.build_emulator = lambda profile, epoch: broken.pytest_hil_make_emulator(profile, epoch)
    from hil.cli.main import main as hil_main
    return hil_main(["emulate", *rest])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
