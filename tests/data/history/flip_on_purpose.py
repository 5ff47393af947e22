"""A bench test made to flip on purpose (tests/test_history_runs.py): its outcome is the harness's choice
(``HIST_FLIP``), on the same PLC and profile.  Not named test_*: only a run that names this file collects it."""

import os


def test_flip(bench, measure):
    measure("steady", 1.0, unit="V", low=0, high=2)
    assert os.environ["HIST_FLIP"] == "pass"
