"""The public API a test author writes against (issue 29; issue 28 item 3): typed (mypy --strict on hil.api, the
faces, the shipped fixtures and the example project; the concrete classes checked against the Protocols),
documented (every exported name and every member of a face has a docstring; docs/api.md is generated from them and
current), and the bench fixture a proxy of exactly the face's names."""

from __future__ import annotations

import inspect
import subprocess
import sys

import pytest

import hil.api
from hil.api.reference import render
from hil.bench.faces import BenchView, FaultInjector, members
from hil.families.fbs import faces

# loaded before pytester's inner run, which forgets what it imports (numpy loads once per process)
from hil.families.fbs.sim import build  # noqa: F401
from tests.conftest import REPO

#: the public API's own modules, checked strictly; what they import from hil is followed silently (internal)
CHECKED = ["hil/api", "hil/bench/faces.py", "hil/families/fbs/faces.py", "hil/families/s7smart/faces.py",
           "hil/plugin/fixtures.py", "hil/families/fbs/fixtures.py", "tests/api_conformance.py",
           "examples/heat_treatment/tests"]


@pytest.mark.timeout(180)
def test_mypy_strict_passes_on_the_public_api_and_the_example_project(tmp_path) -> None:
    done = subprocess.run([sys.executable, "-m", "mypy", "--strict", "--follow-imports=silent", "--cache-dir",
                           str(tmp_path / "cache"), *CHECKED], cwd=REPO, capture_output=True, text=True, timeout=170)
    assert done.returncode == 0, done.stdout + done.stderr


def test_every_exported_name_and_face_member_has_a_docstring() -> None:
    missing = [name for name in hil.api.__all__ if not inspect.getdoc(getattr(hil.api, name))]
    for name in hil.api.__all__:
        face = getattr(hil.api, name)
        if isinstance(face, type) and getattr(face, "_is_protocol", False):
            missing += [f"{name}.{m}" for m in members(face)
                        if not (inspect.getattr_static(face, m).__doc__ or "").strip()
                        or inspect.getattr_static(face, m).__doc__ == type(inspect.getattr_static(face, m)).__doc__]
    assert not missing, f"undocumented: {missing}"


def test_the_api_reference_is_generated_from_the_docstrings_and_current() -> None:
    written = (REPO / "docs" / "api.md").read_text()
    assert written == render(), "docs/api.md is stale: python -m hil.api.reference > docs/api.md"
    for name in hil.api.__all__:
        assert f"## `{name}`" in written


def test_the_bench_fixture_is_a_proxy_of_exactly_its_face(pytester: pytest.Pytester) -> None:
    """What a test holds has the face's names and no others: no raw link, no guard, no journal to reach round."""
    pytester.makepyfile(test_faces="""
        def test_names(bench, rtc, pid, temperature, io, plc, faults):
            from hil.bench.faces import FaultInjector, members
            from hil.families.fbs import faces
            def public(obj):
                return {n for n in dir(obj) if not n.startswith("_")}
            assert public(bench) == set(members(faces.Bench)), public(bench) ^ set(members(faces.Bench))
            assert public(io) == set(members(faces.FbsIO)) and io is not None
            assert public(bench.faults) == set(members(faces.FbsFaults))
            assert public(bench.faults.sensor_break) == set(members(FaultInjector))
            assert plc is bench.plc and io.description == bench.plc.io.description
            for hidden in ("raw", "io", "journal", "recover", "begin_test", "close"):
                assert not hasattr(bench, hidden), hidden
            for hidden in ("inner", "durable", "restore", "_write_words"):
                assert not hasattr(io, hidden), hidden
    """)
    result = pytester.runpytest_inprocess("--bench", str(REPO / "fixtures" / "benches" / "emulator.toml"),
                                          "-p", "no:cacheprovider", "-p", "no:hypothesispytest")
    result.assert_outcomes(passed=1)


def test_a_family_neutral_face_is_what_a_bench_without_a_face_gets() -> None:
    assert {"plc", "wait", "settle", "cannot_reach", "time", "profile"} <= set(members(BenchView))
    assert members(FaultInjector)["inject"] is True and members(FaultInjector)["kind"] is False
    assert set(members(faces.Bench)) - set(members(BenchView)) == {"faults"}


def test_the_guide_covers_each_item_of_writing_tests_for_your_bench() -> None:
    guide = " ".join((REPO / "docs" / "writing-tests.md").read_text().split())
    for item in ("**Start**", "**The profile for your own boxes**", "**The fixtures**", "**Waiting is in bench time.**",
                 "**Measurements with limits**", "**The guard**", "**Markers**", "**Running it**",
                 "**API reference**"):
        assert item in guide, item
    for said in ("[[pid.instances]]", "bench.wait", "virtual", "wait_for_update", "alarm_words(box).warning",
                 "measure(", "low=", "WriteRefused", "read back", "needs(", "`slow`", "`destructive`",
                 "bench_time(", "hil run --bench bench.toml -- tests", "pytest --bench bench.toml tests",
                 "api.md", "py.typed", "examples/heat_treatment", "hil init"):
        assert said in guide, said
    for fixture in ("bench", "plc", "io", "rtc", "pid", "temperature", "faults", "measure", "report"):
        assert f"`{fixture}`" in guide, fixture
