"""Simulator core: register store, dialect, broadcast, persistence and behaviours, PDU level.

The transport tests (tests/runtime/sim/test_simulator_server.py) put the same simulators behind real
servers; here requests are PDUs (function code + data) so every dialect case is cheap to reach.
"""

from __future__ import annotations

import importlib
import json
import struct
from pathlib import Path
from typing import Any

import pytest

from drivemap.runtime.sim.behaviours import Behaviour, behaviour_class, behaviour_for
from drivemap.runtime.sim.simulator import Simulator, SimulatorError

MODELS = ["ev", "v2", "edx", "vfd1000"]


def sim_class(model: str) -> Any:
    return importlib.import_module(f"drivemap_models.{model}.simulator").Simulator


def read(addr: int, qty: int) -> bytes:
    return struct.pack(">BHH", 0x03, addr, qty)


def write(addr: int, value: int) -> bytes:
    return struct.pack(">BHH", 0x06, addr, value & 0xFFFF)


def write_many(addr: int, values: list[int], count: int | None = None) -> bytes:
    body = b"".join(struct.pack(">H", v & 0xFFFF) for v in values)
    return struct.pack(">BHHB", 0x10, addr, len(values), len(body) if count is None else count) + body


def exc(fc: int, code: int) -> bytes:
    return bytes([fc | 0x80, code])


# ---- generated module ---------------------------------------------------------------------------
@pytest.mark.parametrize("model", MODELS)
def test_generated_simulator_is_bound_to_spec_and_behaviour(model: str) -> None:
    module = importlib.import_module(f"drivemap_models.{model}.simulator")
    spec = importlib.import_module(f"drivemap_models.{model}.spec").SPEC
    sim = module.Simulator()
    assert sim.spec is spec and module.MODEL == model
    assert type(sim.behaviour) is behaviour_class(model)
    assert type(sim.behaviour) is not Behaviour  # the four seed models have behaviour
    assert callable(module.main)


def test_models_without_a_module_get_the_plain_stub() -> None:
    assert behaviour_class("no_such_model") is Behaviour
    assert type(behaviour_for("no_such_model")) is Behaviour


# ---- store ----------------------------------------------------------------------------------------
def test_defaults_and_presets_ev() -> None:
    sim = sim_class("ev")([1, 2])
    assert sim.handle(1, read(0x0308, 2)) == bytes.fromhex("03 04 0B B8 0B B8")
    assert sim.handle(2, read(0x0900, 8)) == bytes([3, 16]) + b"".join(struct.pack(">H", v) for v in [1, 2, 8, 6, 10, 11, 0, 0])
    sim.set("digital_speed[1]", 1234, unit=2)
    assert sim.get("digital_speed[1]", 2) == 1234 and sim.get("digital_speed[1]", 1) == 3000
    sim.set_raw("alarm_no", 7)
    assert sim.get_raw("alarm_no", 1) == sim.get_raw("alarm_no", 2) == 7
    with pytest.raises(SimulatorError):
        sim.set("no_such_register", 1)
    with pytest.raises(SimulatorError):
        sim.set("digital_speed", 1)  # an array needs an element
    with pytest.raises(SimulatorError):
        sim.set_raw("motor_speed", 0x10000)
    with pytest.raises(SimulatorError):
        sim.unit(3)


def test_scaled_and_signed_values() -> None:
    sim = sim_class("v2")()
    sim.set("frequency_command_monitor", 60.0)
    assert sim.handle(1, read(0x0123, 1)) == bytes.fromhex("03 02 17 70")
    sim.set("pid_input", -12.5)
    assert sim.handle(1, read(0x012B, 1)) == bytes.fromhex("03 02 FF 83")
    assert sim.get("pid_input") == -12.5


def test_units_outside_the_map_are_refused() -> None:
    with pytest.raises(SimulatorError):
        sim_class("ev")([16])
    with pytest.raises(SimulatorError):
        sim_class("ev")([0])


def test_answers_only_its_own_units() -> None:
    sim = sim_class("ev")([1, 2])
    assert sim.handle(3, read(0x0308, 1)) is None
    assert sim.handle(2, read(0x0308, 1)) is not None


def test_pages_ev_watch_data_select() -> None:
    sim = sim_class("ev")()
    sim.set("bus_voltage", 24.0)
    sim.set("accel_time_monitor", 0.5)
    assert sim.handle(1, read(0x0009, 1)) == bytes.fromhex("03 02 09 60")
    assert sim.handle(1, write(0x090A, 1)) == write(0x090A, 1)
    assert sim.handle(1, read(0x0009, 1)) == bytes.fromhex("03 02 00 05")


# ---- dialect ----------------------------------------------------------------------------------------
DIALECT = {
    # model: (illegal_function, illegal_address, illegal_quantity, out_of_range, read_only, busy, bad_length)
    "ev": (0x01, 0x02, 0x03, 0x04, 0x02, 0x04, None),
    "v2": (0x51, 0x52, 0x53, 0x54, 0x55, 0x55, 0x53),
    "edx": (0x51, 0x52, 0x53, 0x54, 0x55, 0x55, 0x53),
    "vfd1000": (0x01, 0x02, 0x03, 0x03, 0x02, 0x06, 0x03),
}


def _codes(model: str) -> dict[str, int | None]:
    spec = importlib.import_module(f"drivemap_models.{model}.spec").SPEC
    out: dict[str, int | None] = {}
    for case in ("illegal_function", "illegal_address", "illegal_quantity", "out_of_range", "read_only", "busy", "bad_length"):
        out[case] = Simulator(spec).exception_code(case)
    return out


@pytest.mark.parametrize("model", MODELS)
def test_exception_codes_come_from_the_map(model: str) -> None:
    expected = dict(zip(
        ("illegal_function", "illegal_address", "illegal_quantity", "out_of_range", "read_only", "busy", "bad_length"),
        DIALECT[model], strict=True,
    ))
    assert _codes(model) == expected


def _first(sim: Simulator, pred: Any) -> Any:
    for reg in sim.spec.registers:
        if pred(reg):
            return reg
    raise AssertionError("no register fits")


@pytest.mark.parametrize("model", MODELS)
def test_every_exception_path(model: str) -> None:
    sim: Simulator = sim_class(model)()
    fn, addr_code, qty_code, range_code, ro_code, busy_code, len_code = DIALECT[model]
    # unsupported function code (04h is in no map)
    assert sim.handle(1, struct.pack(">BHH", 0x04, 0, 1)) == exc(0x04, fn)
    # bad address: 0xFFF0 is mapped in no map
    assert sim.handle(1, read(0xFFF0, 1)) == exc(0x03, addr_code)
    assert sim.handle(1, write(0xFFF0, 1)) == exc(0x06, addr_code)
    # quantity above the maximum (and 0)
    limit = sim.spec.protocol.function(0x03).max_quantity or 125
    assert sim.handle(1, read(0x0000, limit + 1)) == exc(0x03, qty_code)
    assert sim.handle(1, read(0x0000, 0)) == exc(0x03, qty_code)
    # write to a read-only register
    ro = _first(sim, lambda r: r.access == "r" and r.page is None)
    assert sim.handle(1, write(ro.address, 0)) == exc(0x06, ro_code)
    # value out of range
    bounded = [r for r in sim.spec.registers if r.writable and (r.max is not None or r.enum_values) and not r.refuse_while_running and r.words == 1]
    if bounded:
        reg = bounded[0]
        bad = max(reg.enum_values) + 1 if reg.enum_values else int(round(((reg.max or 0) - reg.offset) / reg.scale)) + 1
        assert sim.handle(1, write(reg.address, bad)) == exc(0x06, range_code)
    # 10h whose byte count does not match the quantity
    if sim.spec.protocol.function(0x10) is not None:
        reply = sim.handle(1, write_many(0x0000, [1, 2], count=2))
        assert reply == (None if len_code is None else exc(0x10, len_code))


def test_write_only_register_vfd1000() -> None:
    sim = sim_class("vfd1000")()
    assert sim.handle(1, read(0x1000, 1)) == exc(0x03, 0x02)  # 1000H is write-only
    assert sim.handle(1, write(0x1000, 0x0005)) == write(0x1000, 0x0005)


def test_busy_v2_parameters_while_running() -> None:
    sim = sim_class("v2")()
    assert sim.handle(1, write(0x0005, 7)) == write(0x0005, 7)
    assert sim.handle(1, write(0x0101, 0x0001)) == write(0x0101, 0x0001)  # RUN
    assert sim.handle(1, write(0x0005, 8)) == exc(0x06, 0x55)
    assert sim.get("parameters[5]") == 7
    assert sim.handle(1, write(0x0101, 0x0000)) is not None
    assert sim.handle(1, write(0x0005, 8)) == write(0x0005, 8)


def test_busy_ev_eeprom_while_running_records_8d() -> None:
    """001 §4.6 NOTE only advises the RAM twins while running: refused only with the opt-in option."""
    sim = sim_class("ev")()
    assert sim.handle(1, write(0x1400, 1)) == write(0x1400, 1)
    assert sim.handle(1, write(0x0308, 1000)) == write(0x0308, 1000)  # advice, not a refusal
    sim = sim_class("ev")(refuse_advised_while_running=True)
    assert sim.handle(1, write(0x1400, 1)) == write(0x1400, 1)
    assert sim.handle(1, write(0x0308, 1000)) == exc(0x06, 0x04)
    assert sim.get("comm_error_history[0]") == 0x8D
    assert sim.handle(1, write(0x3F08, 1000)) == write(0x3F08, 1000)  # RAM twin is allowed


def test_refused_multiple_write_changes_nothing() -> None:
    sim = sim_class("ev")()
    # 3F08h ok, 3F09h out of range (max 10000): nothing is written
    assert sim.handle(1, write_many(0x3F08, [500, 20000])) == exc(0x10, 0x04)
    assert sim.get("digital_speed_ram[0]") == 3000


def test_ev_comm_error_history_newest_first() -> None:
    sim = sim_class("ev")()
    sim.handle(1, struct.pack(">BHH", 0x04, 0, 1))  # 88h
    sim.handle(1, read(0x0308, 17))  # 8Ch
    sim.handle(1, write(0x0308, 5))  # 8Ch (below min 60)
    sim.handle(1, read(0xFFF0, 1))  # 02h: nothing recorded
    sim.frame_error(1)  # 84h
    assert sim.handle(1, read(0x4800, 10)) == bytes([3, 20]) + b"".join(
        struct.pack(">H", v) for v in [0x84, 0x8C, 0x8C, 0x88, 0, 0, 0, 0, 0, 0]
    )
    assert sim.handle(1, write(0x0A26, 1)) is not None
    assert sim.get("comm_error_history[0]") == 0


def test_ev_bad_length_gets_no_reply_but_is_recorded() -> None:
    sim = sim_class("ev")()
    assert sim.handle(1, write_many(0x3F08, [1, 2], count=3)) is None
    assert sim.get("comm_error_history[0]") == 0x84


def test_injected_exception_is_one_shot() -> None:
    sim = sim_class("v2")([1, 2])
    sim.inject_exception(0x52)
    assert sim.handle(2, read(0x0123, 1)) == exc(0x03, 0x52)
    assert sim.handle(1, read(0x0123, 1)) == bytes.fromhex("03 02 00 00")
    sim.inject_exception(0x20, unit=1)
    assert sim.handle(1, bytes.fromhex("08 00 00 A5 37")) == bytes.fromhex("88 20")
    assert sim.handle(1, bytes.fromhex("08 00 00 A5 37")) == bytes.fromhex("08 00 00 A5 37")
    sim.inject_exception(0x52)
    assert sim.handle(1, write(0x0102, 0x1770)) == exc(0x06, 0x52)
    assert sim.get("frequency_command") == 0  # an injected exception is not executed


def test_loopback_only_where_listed() -> None:
    assert sim_class("edx")().handle(1, bytes.fromhex("08 00 00 A5 37")) == bytes.fromhex("08 00 00 A5 37")
    assert sim_class("ev")().handle(1, bytes.fromhex("08 00 00 A5 37")) == exc(0x08, 0x01)
    assert sim_class("v2")().handle(1, bytes.fromhex("08 00 01 A5 37")) == exc(0x08, 0x51)


def test_reserved_addresses() -> None:
    sim = sim_class("vfd1000")()
    assert sim.handle(1, read(0x300D, 3)) == bytes.fromhex("03 06 00 00 00 00 00 00")  # 300E-300F readable
    assert sim.handle(1, write(0x300E, 1)) == exc(0x06, 0x02)
    v2 = sim_class("v2")()
    assert v2.handle(1, read(0x0121, 1)) == exc(0x03, 0x52)  # readability unknown: refused


# ---- broadcast ----------------------------------------------------------------------------------------
def test_broadcast_write_applies_to_every_unit_without_reply() -> None:
    sim = sim_class("ev")([1, 2])
    assert sim.handle(0, bytes.fromhex("10 3F 08 00 02 04 03 E8 01 F4")) is None
    for unit in (1, 2):
        assert sim.get("digital_speed_ram[0]", unit) == 1000
        assert sim.get("digital_speed_ram[1]", unit) == 500
    assert sim.handle(0, read(0x0308, 1)) is None  # a broadcast read is ignored


def test_broadcast_ignored_where_the_map_allows_none() -> None:
    sim = sim_class("v2")([1, 2])
    assert sim.handle(0, write(0x0102, 0x1770)) is None
    assert sim.get("frequency_command", 1) == sim.get("frequency_command", 2) == 0


def test_broadcast_ev_appendix_directions() -> None:
    """Appendix I broadcast example 1: NET-IN = 1101b runs slave 1 forward and slave 2 reverse."""
    sim = sim_class("ev")([1, 2])
    for unit, funcs, always in ((1, [1, 2, 0, 0, 0, 0, 0, 0], 0), (2, [0, 0, 1, 2, 0, 0, 0, 0], 10)):
        for i, f in enumerate(funcs):
            sim.set_raw(f"net_x_input_function[{i}]", f, unit=unit)
        sim.set_raw("always_on_input_1", always, unit=unit)
    sim.set("digital_speed_ram[1]", 600, unit=2)
    assert sim.handle(0, bytes.fromhex("06 14 00 00 0D")) is None
    sim.advance(2.0)
    assert sim.get("motor_state", 1) == 2 and sim.get("motor_direction", 1) == 0
    assert sim.get("motor_speed", 1) == 3000
    assert sim.get("motor_state", 2) == 2 and sim.get("motor_direction", 2) == 1
    assert sim.get("motor_speed", 2) == 600  # M0 always on selects No.1


# ---- behaviours ---------------------------------------------------------------------------------------
def test_ev_start_ramp_and_stop() -> None:
    sim = sim_class("ev")()
    sim.set("digital_speed_ram[0]", 1500)
    sim.set("digital_accel_time_ram[0]", 1.0)  # 1 s per 3000 r/min
    sim.handle(1, write(0x1400, 0b1))  # NET-X0 = START/STOP
    assert sim.get("motor_state") == 2
    sim.advance(0.25)
    assert 700 <= sim.get("motor_speed") <= 800
    sim.advance(1.0)
    assert sim.get("motor_speed") == 1500 and sim.get("command_speed") == 1500
    sim.handle(1, write(0x1400, 0))  # decelerate
    sim.advance(0.1)
    assert 0 < sim.get("motor_speed") < 1500 and sim.get("motor_state") == 2
    sim.advance(1.0)
    assert sim.get("motor_speed") == 0 and sim.get("motor_state") == 0


def test_ev_immediate_stop_and_speed_select() -> None:
    sim = sim_class("ev")()
    sim.set("digital_speed_ram[3]", 900)
    sim.handle(1, write(0x1400, 0b110001))  # START + M0 (X4) + M1 (X5) -> No.3
    sim.advance(2.0)
    assert sim.get("motor_speed") == 900
    sim.handle(1, write(0x1400, 0b1000))  # START off, STOP-MODE (X3) on: immediate stop
    sim.advance(0.02)
    assert sim.get("motor_speed") == 0 and sim.get("motor_state") == 0


def test_ev_eeprom_write_updates_ram_twin() -> None:
    sim = sim_class("ev")()
    assert sim.handle(1, write(0x0309, 1200)) is not None
    assert sim.get("digital_speed_ram[1]") == 1200


def test_ev_alarm_and_reset() -> None:
    sim = sim_class("ev")()
    sim.handle(1, write(0x1400, 1))
    sim.advance(0.5)
    sim.set_raw("alarm_no", 7)
    sim.advance(0.02)
    assert sim.get("motor_state") == 5 and sim.get("motor_speed") == 0
    assert sim.get("alarm_history[0]") == 7
    sim.handle(1, write(0x0A00, 1))
    assert sim.get("alarm_no") == 0 and sim.get("motor_state") != 5
    sim.handle(1, write(0x0A22, 1))
    assert sim.get("alarm_history[0]") == 0


def test_ev_configuration_applies_pending_c_parameters() -> None:
    sim = sim_class("ev")()
    # make NET-X1 START/STOP instead of CCW/CW: pending until Configuration
    assert sim.handle(1, write(0x0901, 1)) is not None
    assert sim.get("net_x_input_function[1]") == 1  # reads back the written value
    sim.handle(1, write(0x1400, 0b10))
    sim.advance(0.1)
    assert sim.get("motor_state") == 0  # old assignment (CCW/CW) still in effect
    sim.handle(1, write(0x0A27, 1))
    sim.advance(0.1)
    assert sim.get("motor_state") == 2


@pytest.mark.parametrize("model, command, status, run, rev, freq, monitor", [
    ("v2", 0x0101, 0x0120, 0x01, 0x02, 0x0102, 0x0123),
    ("edx", 0x00E6, 0x00EF, 0x01, 0x02, 0x00E7, 0x00F2),
])
def test_inverter_run_bits_show_in_status(model: str, command: int, status: int, run: int, rev: int, freq: int, monitor: int) -> None:
    sim = sim_class(model)()
    assert sim.handle(1, read(status, 1)) == bytes.fromhex("03 02 00 04")  # READY
    sim.handle(1, write_many(command, [run | rev, 0x1770]))
    assert sim.handle(1, read(status, 1)) == bytes.fromhex("03 02 00 07")  # RUNNING, REVERSE, READY
    assert sim.handle(1, read(monitor, 1)) == bytes.fromhex("03 02 17 70")
    sim.handle(1, write(command, 0))
    assert sim.handle(1, read(status, 1)) == bytes.fromhex("03 02 00 04")


def test_edx_output_frequency_follows_command() -> None:
    sim = sim_class("edx")()
    sim.handle(1, write_many(0x00E6, [0x0001, 0x1770]))
    sim.advance(0.3)
    assert 0 < sim.get("output_frequency") < 6000
    sim.advance(1.0)
    assert sim.get("output_frequency") == 6000
    sim.handle(1, write(0x00E6, 0))
    sim.advance(1.0)
    assert sim.get("output_frequency") == 0


def test_vfd1000_control_command_state_and_frequency() -> None:
    sim = sim_class("vfd1000")()
    assert sim.get("inverter_state") == 3  # standby
    sim.handle(1, write(0x2000, 5000))  # 50.00 %
    sim.handle(1, write(0x1000, 0x0002))  # reverse running
    assert sim.get("inverter_state") == 2
    sim.advance(1.0)
    assert sim.get("operating_frequency") == sim.get("set_frequency") == 2500
    sim.handle(1, write(0x1000, 0x0005))  # stop
    sim.advance(1.0)
    assert sim.get("inverter_state") == 3 and sim.get("operating_frequency") == 0
    sim.set_raw("fault_code", 4)
    sim.advance(0.02)
    assert sim.get("inverter_state") == 4
    sim.handle(1, write(0x1000, 0x0007))
    assert sim.get("inverter_state") == 3 and sim.get("fault_code") == 0


def test_presets_survive_ticks() -> None:
    for model, name, value in (("ev", "motor_speed", 1234), ("edx", "output_frequency", 77), ("vfd1000", "operating_frequency", 88)):
        sim = sim_class(model)()
        sim.set(name, value)
        sim.advance(0.1)
        assert sim.get(name) == value, model


# ---- persistence --------------------------------------------------------------------------------------
def test_eeprom_persists_ram_resets(tmp_path: Path) -> None:
    state = tmp_path / "ev-state.json"
    sim = sim_class("ev")([1, 2], state_file=state)
    assert sim.handle(2, write(0x0308, 1500)) is not None  # EEPROM
    assert sim.handle(2, write(0x3F09, 700)) is not None  # RAM
    data = json.loads(state.read_text())
    assert data["model"] == "ev" and data["units"]["2"]["digital_speed[0]"] == 1500
    assert "digital_speed_ram[1]" not in data["units"]["2"]
    assert not list(tmp_path.glob(".*tmp"))  # temp file replaced atomically
    again = sim_class("ev")([1, 2], state_file=state)
    assert again.get("digital_speed[0]", 2) == 1500 and again.get("digital_speed[0]", 1) == 3000
    assert again.get("digital_speed_ram[1]", 2) == 3000  # RAM reset (loaded from EEPROM at power-up)
    assert again.get("digital_speed_ram[0]", 2) == 1500


def test_state_file_of_another_model_is_refused(tmp_path: Path) -> None:
    state = tmp_path / "s.json"
    state.write_text(json.dumps({"model": "v2", "units": {}}))
    with pytest.raises(SimulatorError):
        sim_class("ev")(state_file=state)


def test_reply_delay() -> None:
    assert sim_class("ev")().reply_delay() == 0
    assert sim_class("ev")(realistic_timing=True).reply_delay() == pytest.approx(0.004)
    assert sim_class("v2")(realistic_timing=True).reply_delay() == pytest.approx(0.010)


# ---- every printed example, PDU level (the serial round trip is test_roundtrip.py) ---------------------
def _examples() -> list[Any]:
    from drivemap.compiler import compile_map, map_paths

    out = []
    for path in map_paths():
        model = compile_map(path)
        for ex in model.examples:
            if ex.wire_request and ex.illegible is None:
                out.append(pytest.param(model, ex, id=f"{model.name}-{ex.name}"))
    return out


@pytest.mark.parametrize("model, ex", _examples())
def test_printed_example_answered_exactly(model: Any, ex: Any) -> None:
    from drivemap.frontend.frames import parse

    request = parse(ex.wire_request, ex.mode)
    units = [1, 2] if ex.meaning.broadcast else [ex.meaning.unit]
    sim = sim_class(model.name)(units)
    for name, value in ex.preset:
        sim.set(name, value, unit=None if ex.meaning.broadcast else ex.meaning.unit)
    if ex.inject_exception is not None:
        sim.inject_exception(ex.inject_exception)
    answer = sim.handle(request.body[0], request.body[1:])
    if ex.wire_response is None:
        assert answer is None
        for name, value in ex.meaning.values:
            for unit in units:
                assert sim.get(name, unit) == pytest.approx(value)
    else:
        expected = parse(ex.wire_response, ex.mode)
        assert answer is not None and bytes([request.body[0]]) + answer == expected.body
