"""Where the project's suites and bench profiles are, whether hil runs from a checkout or an installed wheel.

The suites and fixtures live at the top of the repository (where the README points); ``hil/_data/suites`` and
``hil/_data/fixtures`` are symlinks to them, so an editable install reads the checkout and a wheel (setuptools
copies what the links point to, see ``[tool.setuptools.package-data]``) carries its own copy.
"""

from __future__ import annotations

from pathlib import Path

#: The bundled suites and fixtures (symlinks in a checkout, real directories in an installed wheel).
BUNDLED = Path(__file__).resolve().parent.parent / "_data"


def project_dir(name: str) -> Path:
    """``suites`` or ``fixtures`` from the current directory if it has one (a user's own), else the bundled."""
    here = Path.cwd() / name
    return here if here.exists() else BUNDLED / name


def default_bench() -> Path:
    return project_dir("fixtures") / "benches" / "emulator.toml"
