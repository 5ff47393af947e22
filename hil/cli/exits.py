"""The exit codes of every ``hil`` command: pytest's (``pytest.ExitCode``), so a script or a CI job reads
``hil run`` and the other commands alike."""

from __future__ import annotations

EXIT_OK, EXIT_FAILED, EXIT_INTERRUPTED, EXIT_INTERNAL, EXIT_USAGE = 0, 1, 2, 3, 4
