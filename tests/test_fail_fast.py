"""When the PLC stops answering, the rest of the session errors at once with the reason."""

from __future__ import annotations

import os

from hil.families.fbs.transport.fatek import FatekTransport
from tests.conftest import EMULATOR_BENCH


def test_remaining_tests_error_at_once_when_the_plc_stops_answering(pytester, monkeypatch):
    # every FATEK request the inner session makes, by the test (and phase) it was made in: counted, not timed
    asked: list[str] = []
    exchange = FatekTransport._exchange

    def counted(self, command):
        asked.append(os.environ.get("PYTEST_CURRENT_TEST", ""))
        return exchange(self, command)

    monkeypatch.setattr(FatekTransport, "_exchange", counted)
    text = EMULATOR_BENCH.read_text().replace('target = "emulator"', 'target = "emulator+fatek-tcp"')
    # the reply timeout a hang guard: the stopped server closes its connection, which the client sees at once (and
    # the reconnection is refused at once); no reply is ever waited out here, so a busy host cannot fail test_works
    bench = pytester.makefile(".toml", bench=text.replace("time_scale = 1.0", "time_scale = 1.0\ntimeout = 30.0"))
    pytester.makepyfile(test_session="""
        import pytest
        from hil.plugin.pytest_plugin import BENCH_SESSION

        @pytest.fixture
        def real(request):  # the harness's own bench object: its tests break the wire from inside a test
            return request.config.stash[BENCH_SESSION].bench

        import time

        def test_works(bench):
            assert bench.plc.io.read("R1000") == 0

        def test_plc_goes_away(bench, real):
            real.raw.server.stop()
            bench.plc.io.read("R1000")

        def test_after_1(bench):
            pass

        def test_after_2(bench):
            pass

        def test_without_bench():
            pass
    """)
    result = pytester.runpytest_inprocess("--bench", str(bench), "-rE", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=2, failed=1, errors=2)
    result.stdout.fnmatch_lines(["*bench not usable: the PLC stopped answering during *test_plc_goes_away*"
                                 "TransportError*"])
    result.stdout.fnmatch_lines(["ERROR*test_after_1*", "ERROR*test_after_2*"])
    # One failing test pays its retries; the two after it error at setup, naming the test the PLC was lost in,
    # without a request of their own: they cost nothing on the wire (how long they take is the host's business)
    assert any("test_plc_goes_away" in when for when in asked), asked
    assert not [when for when in asked if "test_after_" in when], asked
