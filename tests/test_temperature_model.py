"""The emulator's temperature model, the fault rig, the fault injectors and ``hil probe --bench``."""

from __future__ import annotations

import datetime as dt

import pytest

from hil.bench.profile import load_profile, profile_from_dict
from hil.families.fbs.bench import Bench
from hil.families.fbs.sim import Emulator
from hil.families.fbs.sim.models.temperature import Fixed, Ramp, TemperatureModel
from hil.families.fbs.temperature import MODULES, parse_temperature
from tests.conftest import EMULATOR_BENCH

SR, RD, TW = 3000, 3020, 3060


def _model(modules=(("16TC", "K"), ("16TC", "J")), fitted=None, **extra):
    config = parse_temperature({"table": f"R{SR}", "readings": f"R{RD}", "work": f"R{TW}",
                                "modules": [{"type": t, "sensor": s} for t, s in modules], **extra})
    emu = Emulator()
    model = TemperatureModel(config, fitted=fitted)
    emu.add_model(model)
    return emu, model


def _words(emu, start, count):
    return emu.memory.words["R"][start:start + count]


def test_power_on_writes_the_table_and_measuring_starts_after_one_full_cycle():
    emu, _ = _model()
    assert _words(emu, SR, 6) == [0xA556, 2, 10000 + RD, 10000 + TW, 0x0203, 0x0103]
    emu.advance(3.0)
    assert _words(emu, TW, 1)[0] >> 8 == 0x00  # 16TC normal: 6 s for every point
    emu.advance(3.1)
    work = _words(emu, TW, 12)
    assert work[0] == 0x5600 and work[1:3] == [0, 0] and work[3] == 32 << 8 | 2
    assert work[4] == 0x0200 and work[5] == 16 << 8 | 0 and work[6] == 10000 + RD
    assert work[8] == 0x0108 and work[9] == 16 << 8 | 1 and work[10] == 10000 + RD + 16
    assert _words(emu, RD, 2) == [250, 253]


def test_points_are_multiplexed_one_at_a_time():
    emu, model = _model(modules=(("2TC", "K"),))
    emu.advance(0.5)
    model.set_source(0, Fixed(100.0))
    model.set_source(1, Fixed(200.0))
    emu.advance(0.6)  # 2TC normal: 2 s per cycle → one point per second; point 0 was measured at 1 s
    assert _words(emu, RD, 2) == [1000, 0]
    emu.advance(1.0)
    assert _words(emu, RD, 2) == [1000, 2000]


@pytest.mark.parametrize("count", [0, 9])
def test_bad_module_count_gives_FE(count):
    emu, _ = _model()
    emu.memory.words["R"][SR + 1] = count
    emu.advance(0.1)
    assert _words(emu, TW, 1)[0] >> 8 == 0xFE


def test_more_than_32_points_gives_FF():
    emu, _ = _model()
    words = emu.memory.words["R"]
    words[SR + 1] = 3
    words[SR + 6] = 0x0103  # a third 16TC: 48 points
    emu.advance(0.1)
    assert _words(emu, TW, 4)[0] >> 8 == 0xFF and _words(emu, TW, 4)[3] >> 8 == 48


def test_no_marker_means_nothing_is_measured():
    emu, _ = _model()
    emu.memory.words["R"][SR] = 0xA555
    emu.advance(10)
    assert _words(emu, TW, 4) == [0, 0, 0, 0] and _words(emu, RD, 32) == [0] * 32


def test_table_naming_a_module_that_is_not_fitted_sets_its_mismatch_bit():
    emu, _ = _model(modules=(("16TC", "K"), ("6TC", "K"), ("2TC", "K")),
                    fitted=[MODULES["16TC"], MODULES["6RTD"]])
    emu.advance(7)
    head = _words(emu, TW, 1)[0]
    assert head & 0xFF == 0b110  # module 2 is a 6RTD, module 3 is missing
    assert head >> 8 == 0x56  # the points of the matching module are all measured
    assert _words(emu, RD + 16, 8) == [0] * 8


def test_break_mask_and_repair():
    emu, model = _model()
    emu.advance(7)
    model.open(17)
    emu.advance(7)
    assert _words(emu, RD + 17, 1) == [28767] and _words(emu, TW + 1, 2) == [0, 1 << 1]
    emu.memory.words["R"][4011] &= ~(1 << 1)
    emu.advance(7)
    assert _words(emu, RD + 17, 1) == [0] and _words(emu, TW + 1, 2) == [0, 0]
    emu.memory.words["R"][4011] = 0xFFFF
    emu.advance(7)
    assert _words(emu, RD + 17, 1) == [28767]
    model.repair(17)
    emu.advance(7)
    assert _words(emu, RD + 17, 1) == [round((25 + 0.3 * 17) * 10)] and _words(emu, TW + 1, 2) == [0, 0]


def test_unmasked_point_without_sensor_fault_reads_zero():
    emu, _ = _model()
    emu.memory.words["R"][4010] = 0xFFFE
    emu.advance(7)
    assert _words(emu, RD, 2) == [0, 253]


def test_fahrenheit_fast_rate_and_averaging():
    emu, model = _model(modules=(("6RTD", "PT100"),), unit="F", rate="fast")
    model.set_source(0, Fixed(100.0))
    model.set_source(1, Fixed(-200.0))
    emu.advance(1.1)
    assert _words(emu, RD, 6)[0] == 2120
    assert emu.memory.words["R"][RD + 1] == (-3280) & 0xFFFF  # −328.0 °F, a signed word
    from hil.families.fbs.device.temperature import signed
    assert all(signed(w) % 10 == 0 for w in _words(emu, RD, 6))

    emu, model = _model(modules=(("2TC", "K"),), averaging=4)
    model.set_source(0, Ramp(0.0, 10.0))  # +10 °C/s, measured every 2 s at t = 1, 3, 5, 7
    emu.advance(7.05)
    assert _words(emu, RD, 1) == [400]  # mean of 10, 30, 50, 70 °C


def test_sources_from_the_profile():
    emu, _ = _model(modules=(("2TC", "K"),), sources={"1": {"kind": "fixed", "celsius": 500}})
    emu.advance(2.1)
    assert _words(emu, RD, 2) == [250, 5000]


def test_out_of_range_point_is_refused():
    _, model = _model()
    with pytest.raises(ValueError, match="point 32"):
        model.open(32)


# -- the rig --------------------------------------------------------------------------------------------------
def test_rig_coils_open_and_close_sensors():
    from pymodbus.client import ModbusTcpClient

    from hil.families.fbs.sim.rig import start_rig_modbus_tcp
    emu, model = _model()
    handle = start_rig_modbus_tcp(emu, first_coil=100)
    try:
        host, _, port = handle.address.rpartition(":")
        client = ModbusTcpClient(host, port=int(port), timeout=2)
        assert client.connect()
        assert not client.write_coil(105, True, device_id=1).isError()
        assert model.broken == {5}
        assert not client.write_coils(116, [True, True], device_id=1).isError()
        assert model.broken == {5, 16, 17}
        assert not client.write_coil(105, False, device_id=1).isError()
        assert model.broken == {16, 17}
        assert client.read_coils(100, count=32, device_id=1).bits[16:18] == [True, True]
        assert client.write_coil(99, True, device_id=1).isError()  # below first_coil: ILLEGAL_ADDRESS
        client.close()
    finally:
        handle.stop()


def test_rig_heater_banks_open_and_short_heaters_of_the_plant():
    from pymodbus.client import ModbusTcpClient

    from hil.families.fbs.sim.build import build_emulator
    from hil.families.fbs.sim.models.plant import ThermalPlant
    from hil.families.fbs.sim.rig import start_rig_modbus_tcp
    emu = build_emulator(load_profile(EMULATOR_BENCH), dt.datetime(2024, 2, 28, 12))
    plant = emu.model(ThermalPlant)
    heated = sorted(plant.heaters)
    unheated = next(p for p in range(32) if p not in plant.heaters)
    handle = start_rig_modbus_tcp(emu, first_coil=10)
    try:
        host, _, port = handle.address.rpartition(":")
        client = ModbusTcpClient(host, port=int(port), timeout=2)
        assert client.connect()
        assert not client.write_coil(10 + 32 + heated[0], True, device_id=1).isError()
        assert not client.write_coil(10 + 64 + heated[1], True, device_id=1).isError()
        assert plant.faults == {"heater_open": {heated[0]}, "ssr_short": {heated[1]}}
        assert client.read_coils(10 + 32 + heated[0], count=1, device_id=1).bits[0] is True
        assert not client.write_coils(10 + 32 + heated[0], [False], device_id=1).isError()
        assert plant.faults["heater_open"] == set()
        # a point the plant does not heat: refused, nothing switched, the coil stays 0
        reply = client.write_coil(10 + 32 + unheated, True, device_id=1)
        assert reply.isError() and reply.exception_code == 2
        assert client.read_coils(10 + 32 + unheated, count=1, device_id=1).bits[0] is False
        assert client.write_coil(10 + 96, True, device_id=1).isError()  # past the last bank
        client.close()
    finally:
        handle.stop()


def test_rig_needs_temperature_modules():
    from hil.families.fbs.sim.rig import build_rig_device
    with pytest.raises(ValueError, match="no temperature modules"):
        build_rig_device(Emulator())


# -- injectors and the bench ------------------------------------------------------------------------------------
def _bench(faults: dict, writable: list[str] = (), allow_destructive: bool = False) -> Bench:
    data = {"bench": {"name": "t"}, "safety": {"writable": ["M1000-M1031", "R4010-R4011", *writable],
                                               "allow_destructive": allow_destructive},
            "temperature": {"table": "R3000", "readings": "R3020", "work": "R3060",
                            "modules": [{"type": "6TC", "sensor": "K"}]},
            "faults": faults}
    return Bench(profile_from_dict(data))


def test_plc_bit_injector_writes_through_the_guard_and_is_undone_at_end_of_test():
    bench = _bench({"sensor_break": {"kind": "plc-bit", "first": "M1000"}})
    bench.begin_test()
    bench.faults.sensor_break.open(3)
    assert bench.plc.io.read("M1003") == 1
    bench.end_test()
    assert bench.plc.io.read("M1003") == 0 and bench.faults.sensor_break.opened == set()
    bench.close()


def test_plc_bit_outside_the_allow_list_is_unavailable():
    bench = _bench({"sensor_break": {"kind": "plc-bit", "first": "M1040"}})
    assert "writable" in bench.faults.unavailable("sensor_break")
    assert bench.faults.sensor_break is None
    bench.close()


def test_plc_bit_on_outputs_needs_the_destructive_opt_in():
    faults = {"sensor_break": {"kind": "plc-bit", "first": "Y40"}}
    bench = _bench(faults, writable=["Y40-Y47"])
    assert "--hil-allow-destructive" in bench.faults.unavailable("sensor_break")
    bench.close()
    bench = _bench(faults, writable=["Y40-Y47"], allow_destructive=True)
    assert bench.faults.unavailable("sensor_break") is None
    bench.close()


def test_emulator_injector_is_undone_at_end_of_test():
    bench = _bench({"sensor_break": {"kind": "emulator"}})
    model = bench.raw.emulator.model(TemperatureModel)
    bench.begin_test()
    bench.faults.sensor_break.open(2)
    assert model.broken == {2}
    bench.end_test()
    assert model.broken == set()
    bench.close()


def test_missing_and_manual_injectors_explain_themselves(monkeypatch):
    bench = _bench({})
    assert bench.faults.unavailable("sensor_break") == "the bench profile has no [faults.sensor_break] injector"
    bench.close()
    bench = _bench({"sensor_break": {"kind": "manual"}})
    monkeypatch.setattr("sys.stdin.isatty", lambda: False, raising=False)
    assert "stdin is not a terminal" in bench.faults.unavailable("sensor_break")
    bench.close()


def test_manual_injector_asks_the_operator():
    from hil.families.fbs.injectors.manual import ManualSensorBreak
    asked = []
    injector = ManualSensorBreak(ask=asked.append)
    injector.open(4)
    injector.undo()
    assert asked[0].startswith("DISCONNECT the sensor of temperature point 4")
    assert asked[1].startswith("RECONNECT")


def test_unreachable_relay_module_is_reported():
    from hil.families.fbs.injectors.injector import FaultError
    from hil.families.fbs.injectors.modbus_coil import ModbusCoilSensorBreak
    injector = ModbusCoilSensorBreak("modbus+tcp://127.0.0.1:9?unit=1", timeout=0.2)
    with pytest.raises(FaultError, match="cannot reach the sensor-break relay module"):
        injector.open(0)
    # The coil's original is read (and journaled) before it is switched: that read failed, so nothing was switched
    # and there is nothing to undo.
    assert injector.originals == {} and injector.opened == set()
    injector.undo()


def test_probe_shows_the_temperature_points(capsys):
    from hil.cli.main import main
    assert main(["probe", "--bench", str(EMULATOR_BENCH)]) == 0
    out = capsys.readouterr().out
    assert "temperature points (2 modules, 32 points)" in out
    assert "FBs-16TC" in out and "A556H" in out and "56H" in out


def test_emulator_profile_is_self_consistent():
    config = parse_temperature(load_profile(EMULATOR_BENCH).areas["temperature"])
    assert config.points == 32  # the break suites need points 0, 15, 16 and 31
