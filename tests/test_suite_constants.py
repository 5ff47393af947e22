"""A suite takes what it calls "outside the allow-list" from the bench's own profile, never from a constant our
profiles happen to make true: on a bench that allows more, the same test still shows the guard refusing."""

from __future__ import annotations

from tests.broken import run_suites
from tests.conftest import EMULATOR_BENCH


def test_the_refused_register_comes_from_the_profile(pytester):
    text = EMULATOR_BENCH.read_text()
    # a bench that lets its tests write R0-R2999 (R2000, the register the smoke test once took as refused, too)
    wide = pytester.makefile(".toml", wide=text.replace('writable = [\n', 'writable = [\n    "R1-R2999",\n', 1))
    passed, failed = run_suites(pytester, ["test_smoke.py"], None, "-k", "outside_allow_list", bench=wide)
    assert failed == [] and len(passed) == 1, (passed, failed)
