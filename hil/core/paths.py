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


def _bench_dirs() -> list[Path]:
    """Where short profile names are looked up: this directory's fixtures/benches, then the bundled ones."""
    dirs = [Path.cwd() / "fixtures" / "benches", BUNDLED / "fixtures" / "benches"]
    return [d for n, d in enumerate(dirs) if d.is_dir() and d.resolve() not in {e.resolve() for e in dirs[:n]}]


def bundled_benches() -> dict[str, Path]:
    """Every profile reachable by short name (``s7-200smart``), the first directory's copy where both have one."""
    found: dict[str, Path] = {}
    for directory in _bench_dirs():
        for path in sorted(directory.glob("*.toml")):
            found.setdefault(path.stem, path)
    return found


def bench_path(given: str | Path) -> Path:
    """A bench profile given as a path, or by the short name of a bundled one (``--bench s7-200smart``), or as the
    README spells them (``fixtures/benches/s7-200smart.toml``) where this directory has none: a file that exists
    always wins, so a name never hides a user's own profile."""
    path = Path(given)
    if path.exists() or path.is_absolute():
        return path
    if path.parts[:1] == ("fixtures",) and (BUNDLED / path).is_file():  # the README's fixtures/benches/…, installed
        return BUNDLED / path
    if len(path.parts) == 1 and path.suffix in ("", ".toml"):
        return bundled_benches().get(path.stem, path)
    return path


def suites_dir() -> Path:
    return project_dir("suites")


def bundled_suites() -> dict[str, Path]:
    """Every suite by short name — the file without ``test_`` (``rtc``, ``rtc_validity``), a directory of suites
    by its name (``s7smart``) — so ``hil run -- rtc`` works in a checkout and from an installed wheel alike."""
    root = suites_dir()
    found: dict[str, Path] = {}
    for path in sorted(root.rglob("test_*.py")):
        found.setdefault(path.stem.removeprefix("test_"), path)
    for path in sorted(p for p in root.iterdir() if p.is_dir() and any(p.glob("test_*.py"))):
        found.setdefault(path.name, path)
    return found


def suite_path(arg: str) -> str | None:
    """The test path a ``hil run`` argument means, when it is a suite's short name (``rtc``, ``rtc::test_x``,
    ``rtc-validity``) or a path under ``suites/`` that this directory does not have (the README's
    ``suites/test_rtc.py`` once installed); None for anything else (left to pytest as given)."""
    path, sep, rest = arg.partition("::")
    if Path(path).exists():
        return None
    named = bundled_suites().get(path.replace("-", "_"))
    if named is not None:
        return f"{named}{sep}{rest}"
    parts = Path(path).parts
    if len(parts) > 1 and parts[0] == "suites" and (suites_dir().joinpath(*parts[1:])).exists():
        return f"{suites_dir().joinpath(*parts[1:])}{sep}{rest}"
    return None
