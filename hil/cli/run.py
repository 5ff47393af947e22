"""``hil run``: the suites against a bench, with JUnit XML, an HTML report and wire traces in reports/."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.core.paths import default_bench, project_dir


def pytest_args(bench: str | None, target: str | None, junitxml: str, extra: list[str], *,
                html: str | None = None, operator: str | None = None, station: str | None = None,
                trace: str | None = None, verbosity: int = 0, color: str | None = None) -> list[str]:
    args = [str(project_dir("suites")), "--bench", bench or str(default_bench()), f"--junitxml={junitxml}",
            "-o", "junit_family=xunit1", "-p", "no:cacheprovider"]
    if target:
        args += ["--target", target]
    if html:
        args += ["--hil-html", html]
    if operator:
        args += ["--operator", operator]
    if station:
        args += ["--station", station]
    if trace:
        args += ["--hil-trace", trace]
    if verbosity:
        args.append("-" + ("v" if verbosity > 0 else "q") * abs(verbosity))
    if color:
        args.append(f"--color={color}")
    return args + extra


def run(bench: str | None, target: str | None, junitxml: str, extra: list[str], **options: object) -> int:
    Path(junitxml).parent.mkdir(parents=True, exist_ok=True)
    return int(pytest.main(pytest_args(bench, target, junitxml, extra, **options)))  # type: ignore[arg-type]
