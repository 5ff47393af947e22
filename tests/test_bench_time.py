"""A bench test's timeout is derived from the bench time it plans (bench_time marker) at the profile's time scale,
plus a margin; the pyproject default is for the harness's own tests."""

from __future__ import annotations

from tests.conftest import EMULATOR_BENCH

SUITE = '''
import pytest

@pytest.mark.bench_time(lambda profile: 7200 * profile.time_scale / 10)
def test_planned(bench, request):
    print("TIMEOUT", request.node.get_closest_marker("timeout").args[0])

def test_unplanned(bench, request):
    print("TIMEOUT", request.node.get_closest_marker("timeout").args[0])

def test_harness_own(request):
    print("TIMEOUT", request.node.get_closest_marker("timeout"))
'''


def _bench(tmp_path, target: str, time_scale: float):
    text = EMULATOR_BENCH.read_text().replace('target = "emulator"', f'target = "{target}"')
    text = text.replace("time_scale = 1.0", f"time_scale = {time_scale}")
    path = tmp_path / "bench.toml"
    path.write_text(text)
    return path


def test_timeouts_follow_the_planned_bench_time(pytester, tmp_path):
    pytester.makepyfile(test_x=SUITE)
    # a PLC on a wire at time scale 4: 7200 × 4 / 10 = 2880 bench s → 720 s wall, + 60 s margin
    items, _ = pytester.inline_genitems("--bench", str(_bench(tmp_path, "fatek+tcp://127.0.0.1:9", 4.0)),
                                        "-p", "no:cacheprovider")
    timeouts = {item.name: item.get_closest_marker("timeout") for item in items}
    assert timeouts["test_planned"].args[0] == 780.0
    assert timeouts["test_unplanned"].args[0] == 60 / 4 + 60  # the default plan: 60 bench seconds
    assert timeouts["test_harness_own"] is None  # pyproject's 60 s applies
    # in process, bench time is virtual: the margin alone
    items, _ = pytester.inline_genitems("--bench", str(_bench(tmp_path, "emulator", 1.0)), "-p", "no:cacheprovider")
    assert {item.get_closest_marker("timeout").args[0] for item in items if item.name != "test_harness_own"} == {60.0}
