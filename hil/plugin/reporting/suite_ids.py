"""The bundled suites' test ids on the console as a user types them back, from any directory: ``suites/test_rtc.py::…``.

``hil run`` makes the suites' parent directory pytest's rootdir, so the node ids (JUnit, the history, the HTML
report) read ``suites/…`` wherever hil is installed.  pytest's console, though, shows an id relative to the directory
it was started in (``Config.cwd_relative_nodeid``): from a project's directory an installed suite's id climbs up to
the package (``../../…/site-packages/hil/_data/suites/test_smoke.py::…``).  For the bundled suites the console shows
the node id itself, which ``hil run -- suites/test_smoke.py::…`` takes back from anywhere; every other test, and
every file location (a traceback's, a skip's), stays as pytest shows it: relative to where the run started."""

from __future__ import annotations

from typing import Any

import pytest

from hil.core.paths import suites_dir


def show_suite_ids_from_their_root(config: pytest.Config) -> None:
    """Install the console's id form when this run's rootdir is the bundled suites' parent (``hil run``'s) and it
    was started elsewhere."""
    suites = suites_dir()
    if config.rootpath != suites.parent or config.invocation_params.dir == config.rootpath:
        return
    relative_to_cwd = config.cwd_relative_nodeid

    def as_typed_back(nodeid: Any) -> Any:  # pytest's NodeId (a str before pytest 9): returned as it came
        path = config.rootpath / str(nodeid).partition("::")[0]
        return nodeid if path.is_relative_to(suites) else relative_to_cwd(nodeid)

    # pytest has no hook for the console's form of an id; this is the one function its reporter asks
    config.cwd_relative_nodeid = as_typed_back  # type: ignore[method-assign]  # see above: no hook to use instead
