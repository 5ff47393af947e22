"""Where the project's suites and bench profiles are, whether hil runs from a checkout or an install."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def project_dir(name: str) -> Path:
    """``suites`` or ``fixtures`` from the current directory if it has one, else from the checkout of hil."""
    here = Path.cwd() / name
    return here if here.exists() else REPO / name


def default_bench() -> Path:
    return project_dir("fixtures") / "benches" / "emulator.toml"
