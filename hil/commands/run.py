"""``hil run``: the suites against a bench, with JUnit XML in reports/."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.paths import default_bench, project_dir


def pytest_args(bench: str | None, target: str | None, junitxml: str, extra: list[str]) -> list[str]:
    args = [str(project_dir("suites")), "--bench", bench or str(default_bench()), f"--junitxml={junitxml}",
            "-o", "junit_family=xunit1", "-p", "no:cacheprovider"]
    if target:
        args += ["--target", target]
    return args + extra


def run(bench: str | None, target: str | None, junitxml: str, extra: list[str]) -> int:
    Path(junitxml).parent.mkdir(parents=True, exist_ok=True)
    return int(pytest.main(pytest_args(bench, target, junitxml, extra)))
