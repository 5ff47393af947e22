"""hil.plugin.order: in a run with lanes on one line, the main lane runs its modules that mostly wait first and the
other lanes theirs that mostly send first — so the background's requests meet the main lane's waits — with the
tests that need a PLC straight from power-on still first; a ``line=`` that is neither is an error naming the test."""

from __future__ import annotations

import pytest

from hil.plugin.order import by_line_use, line_use

MODULES = {
    "test_a_busy": 'import pytest\npytestmark = pytest.mark.lane("main", line="busy")\n'
                   'def test_one(): pass\ndef test_two(): pass\n',
    "test_b_plain": "def test_one(): pass\n",
    "test_b_paced": 'import pytest\npytestmark = pytest.mark.lane("main", line="paced")\ndef test_one(): pass\n',
    "test_c_idle": 'import pytest\npytestmark = pytest.mark.lane("main", line="idle")\n'
                   'def test_one(): pass\n'
                   '@pytest.mark.needs("power_on_state")\ndef test_fresh(): pass\n',
}


def _items(pytester: pytest.Pytester) -> list[pytest.Item]:
    pytester.makeini('[pytest]\nmarkers =\n    lane: a lane\n    needs: a need\n')
    pytester.makepyfile(**MODULES)
    items, _ = pytester.inline_genitems()
    return items


def _order(items: list[pytest.Item]) -> list[str]:
    return [f"{item.module.__name__}::{item.name}" for item in items]


def test_the_main_lane_waits_first_and_a_background_lane_sends_first(pytester):
    items = _items(pytester)
    main, background = list(items), list(items)
    by_line_use(main, background=False)
    by_line_use(background, background=True)
    assert _order(main) == ["test_c_idle::test_fresh", "test_c_idle::test_one", "test_b_plain::test_one",
                            "test_b_paced::test_one", "test_a_busy::test_one", "test_a_busy::test_two"]
    assert _order(background) == ["test_c_idle::test_fresh", "test_a_busy::test_one", "test_a_busy::test_two",
                                  "test_b_paced::test_one", "test_b_plain::test_one", "test_c_idle::test_one"]


def test_a_line_use_that_is_neither_busy_nor_idle_is_an_error_naming_the_test(pytester):
    pytester.makeini('[pytest]\nmarkers =\n    lane: a lane\n')
    pytester.makepyfile(test_x='import pytest\npytestmark = pytest.mark.lane("clock", line="bussy")\n'
                               'def test_one(): pass\n')
    (item,), _ = pytester.inline_genitems()
    said = r'test_x.py::test_one: lane\(…, line=.bussy.\).*"busy".*"paced".*"idle"'
    with pytest.raises(pytest.UsageError, match=said):
        line_use(item)
