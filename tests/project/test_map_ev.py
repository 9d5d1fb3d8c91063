"""maps/ev.yaml checked against values read in the EV manual (001_47d2095fcebbe4cf.txt).

Each case id cites the manual section the expected values come from. The map is read through
the export contract (drivemap.backends.export.export_model).
"""

from __future__ import annotations

import pytest

from drivemap.build import export_model


@pytest.fixture(scope="module")
def ev() -> dict:
    return export_model("ev")


@pytest.fixture(scope="module")
def regs(ev: dict) -> dict:
    out: dict[str, dict] = {}
    for reg in ev["registers"]:
        # paged registers share an address, never a name
        assert reg["name"] not in out, f"duplicate register name {reg['name']}"
        out[reg["name"]] = reg
    return out


NET_INPUT_FUNCTION = {
    "NC": 0, "START_STOP": 1, "CCW_CW": 2, "FREE": 5, "STOP_MODE": 6, "EBRAKE_ALM_RST": 7, "ALM_RST": 8,
    "M0": 10, "M1": 11, "M2": 12, "EBRAKE": 13, "DRV_EN": 14, "STOP": 17, "EXT_ERROR": 21,
}
PAGE0 = {"selector": "watch_data_select", "value": 0}
PAGE1 = {"selector": "watch_data_select", "value": 1}

# (case id citing the section, register name, expected fields)
CASES = [
    ("001-4.1-net_in", "net_in", dict(
        address=0x1400, access="rw", type="u16", scale=1, storage="volatile", param=None,
        bits=[{"name": f"X{i}", "offset": i, "width": 1} for i in range(8)])),
    ("001-4.1-sc_cc_mode", "sc_cc_mode", dict(
        address=0x0200, param="02-01", access="rw", default=0, reflect="configuration",
        enum={"SC_MODE": 0, "CC_MODE": 1})),
    ("001-1.1-net_x_input_function[0]", "net_x_input_function[0]", dict(
        address=0x0900, param="09-01", access="rw", default=1, reflect="configuration", enum=NET_INPUT_FUNCTION)),
    ("001-4.1-net_x_input_function[2]", "net_x_input_function[2]", dict(
        address=0x0902, param="09-03", default=8, reflect="configuration")),
    ("001-4.1-net_x_input_function[5]", "net_x_input_function[5]", dict(
        address=0x0905, param="09-06", default=11)),
    # §1.1 prints 0905h for 09-07, §4.1 prints 0906h (known issue): the map uses 0906h
    ("001-4.1-net_x_input_function[6]", "net_x_input_function[6]", dict(
        address=0x0906, param="09-07", default=0, reflect="configuration")),
    ("001-4.1-net_x_input_function[7]", "net_x_input_function[7]", dict(
        address=0x0907, param="09-08", default=0)),
    ("001-1.1-comm_error_action", "comm_error_action", dict(
        address=0x0909, param="09-10", default=0,
        enum={"ALARM": 0, "NET_IO_CLEAR": 1, "ALARM_AND_NET_IO_CLEAR": 2})),
    ("001-1.1-watch_data_select", "watch_data_select", dict(
        address=0x090A, param="09-11", access="rw", default=0, enum={"PAGE_0": 0, "PAGE_1": 1})),
    ("001-1.1-rs485_timeout", "rs485_timeout", dict(
        address=0x090B, param="09-12", unit="ms", min=0, max=1000, default=0)),
    # range printed 1~10 with initial value 0 (known issue): default unknown
    ("001-1.1-rs485_error_count", "rs485_error_count", dict(
        address=0x090C, param="09-13", min=1, max=10, default=None)),
    ("001-1.1-rs232_timeout", "rs232_timeout", dict(
        address=0x090D, param="09-14", unit="ms", min=0, max=10000, default=0)),
    ("001-1.1-rs485_comm_settings", "rs485_comm_settings", dict(
        address=0x090F, param="09-16", default=0,
        bits=[{"name": "PARITY", "offset": 0, "width": 2}, {"name": "STOP_BITS", "offset": 2, "width": 1},
              {"name": "DATA_BITS", "offset": 3, "width": 1}])),
    ("001-4.2-alarm_reset", "alarm_reset", dict(address=0x0A00, access="rw")),
    ("001-4.2-alarm_history_clear", "alarm_history_clear", dict(address=0x0A22, access="rw")),
    ("001-4.2-comm_error_history_clear", "comm_error_history_clear", dict(address=0x0A26, access="rw")),
    ("001-4.2-configuration", "configuration", dict(address=0x0A27, access="rw")),
    ("001-4.3-motor_state", "motor_state", dict(
        address=0x0000, access="r", page=None,
        enum={"STOP": 0, "RUN": 2, "EBRAKE": 3, "FREE": 4, "FAULT": 5, "WAIT_INHIBIT": 6,
              "MOVING_SERVO_ON": 7, "SLIGHT_POS_KEEPING": 8})),
    ("001-4.3-motor_speed", "motor_speed", dict(
        address=0x0002, access="r", unit="r/min", scale=1, min=0, max=65535)),
    ("001-4.3-alarm_no", "alarm_no", dict(address=0x0003, access="r", min=0, max=21)),
    ("001-4.3-motor_direction", "motor_direction", dict(
        address=0x0004, access="r", enum={"CW": 0, "CCW": 1})),
    ("001-4.3-command_speed", "command_speed", dict(address=0x0005, access="r", unit="r/min")),
    ("001-4.3-bus_voltage", "bus_voltage", dict(
        address=0x0009, access="r", scale=0.01, unit="V", page=PAGE0)),
    ("001-4.3-output_percent", "output_percent", dict(
        address=0x000B, access="r", scale=0.1, unit="%", max=100, page=PAGE0)),
    ("001-4.3-output_current", "output_current", dict(
        address=0x000C, access="r", scale=0.01, unit="A", page=PAGE0)),
    ("001-4.3-accel_time_monitor", "accel_time_monitor", dict(
        address=0x0009, access="r", scale=0.1, unit="s", page=PAGE1)),
    ("001-4.3-decel_time_monitor", "decel_time_monitor", dict(
        address=0x000A, scale=0.1, unit="s", page=PAGE1)),
    ("001-4.3-int_vr_voltage", "int_vr_voltage", dict(address=0x000B, scale=0.01, unit="V", max=10, page=PAGE1)),
    ("001-4.3-xh_duty", "xh_duty", dict(address=0x000E, scale=0.1, unit="%", max=100, page=PAGE1)),
    ("001-4.3-xh_frequency", "xh_frequency", dict(address=0x000F, scale=1, unit="Hz", max=10000, page=PAGE1)),
    ("001-4.4-alarm_history[0]", "alarm_history[0]", dict(address=0x3300, access="r", max=22)),
    ("001-4.4-alarm_history[9]", "alarm_history[9]", dict(address=0x3309, access="r")),
    ("001-4.5-comm_error_history[0]", "comm_error_history[0]", dict(
        address=0x4800, access="r", storage="volatile",
        enum={"FRAME_FORMAT_OR_LRC_ERROR": 0x84, "COMMUNICATION_TIMEOUT": 0x85, "INVALID_COMMAND": 0x88,
              "OUT_OF_SETTING_RANGE": 0x8C, "CANNOT_EXECUTE": 0x8D})),
    ("001-4.5-comm_error_history[9]", "comm_error_history[9]", dict(address=0x4809)),
    ("001-4.6-digital_speed[0]", "digital_speed[0]", dict(
        address=0x0308, param="03-09", access="rw", type="u16", scale=1, unit="r/min", min=60, max=10000,
        default=3000, reflect="immediate", storage="eeprom")),
    ("001-4.6-digital_speed[7]", "digital_speed[7]", dict(address=0x030F, param="03-16", default=3000)),
    ("001-4.6-digital_accel_time[0]", "digital_accel_time[0]", dict(
        address=0x0400, param="04-01", scale=0.1, unit="s", min=0.1, max=10, default=1, storage="eeprom")),
    ("001-4.6-digital_decel_time[7]", "digital_decel_time[7]", dict(
        address=0x040F, param="04-16", scale=0.1, unit="s", default=1)),
    ("001-4.6-digital_torque_limit[0]", "digital_torque_limit[0]", dict(
        address=0x0700, param="07-01", scale=0.1, unit="%", min=0, max=200, default=200)),
    ("001-4.6-digital_duty[0]", "digital_duty[0]", dict(
        address=0x0708, param="07-09", scale=0.1, unit="%", max=100, default=10)),
    ("001-4.6-digital_duty[6]", "digital_duty[6]", dict(address=0x070E, param="07-15", default=80)),
    ("001-4.6-digital_duty[7]", "digital_duty[7]", dict(address=0x070F, param="07-16", default=100)),
    ("001-4.6-digital_speed_ram[0]", "digital_speed_ram[0]", dict(
        address=0x3F08, access="rw", unit="r/min", min=60, max=10000, storage="ram", reflect="immediate")),
    ("001-4.6-digital_speed_ram[3]", "digital_speed_ram[3]", dict(address=0x3F0B, storage="ram")),
    ("001-4.6-digital_accel_time_ram[0]", "digital_accel_time_ram[0]", dict(address=0x4000, scale=0.1, storage="ram")),
    ("001-4.6-digital_decel_time_ram[0]", "digital_decel_time_ram[0]", dict(address=0x4008, scale=0.1, storage="ram")),
    ("001-4.6-digital_torque_limit_ram[7]", "digital_torque_limit_ram[7]", dict(address=0x4307, storage="ram")),
    ("001-4.6-digital_duty_ram[7]", "digital_duty_ram[7]", dict(address=0x430F, storage="ram")),
    ("001-AppI-operation_data_source", "operation_data_source", dict(address=0x0202, param="02-03")),
    ("001-AppI-always_on_input_1", "always_on_input_1", dict(address=0x0606, param="06-07")),
    ("001-4.3-servo_on_mode", "servo_on_mode", dict(address=0x020D, param="02-14")),
    ("001-4.3-param_08_01", "param_08_01", dict(address=0x0800, param="08-01")),
    ("001-4.3-stop_holding_force", "stop_holding_force", dict(
        address=0x080A, param="08-11", enum={"FREE": 0, "SHORT_BRAKE": 1, "SLIGHT_POSITION_KEEPING": 2})),
]


@pytest.mark.parametrize("name,expected", [(c[1], c[2]) for c in CASES], ids=[c[0] for c in CASES])
def test_register(regs: dict, name: str, expected: dict) -> None:
    assert name in regs, f"register {name} missing"
    reg = regs[name]
    for key, want in expected.items():
        got = reg[key]
        if isinstance(want, float) and got is not None:
            assert got == pytest.approx(want), f"{name}.{key}"
        else:
            assert got == want, f"{name}.{key}: {got!r} != {want!r}"


@pytest.mark.parametrize(
    "name,count,first,last",
    [
        ("net_x_input_function", 8, 0x0900, 0x0907),
        ("alarm_history", 10, 0x3300, 0x3309),
        ("comm_error_history", 10, 0x4800, 0x4809),
        ("digital_speed", 8, 0x0308, 0x030F),
        ("digital_accel_time", 8, 0x0400, 0x0407),
        ("digital_decel_time", 8, 0x0408, 0x040F),
        ("digital_torque_limit", 8, 0x0700, 0x0707),
        ("digital_duty", 8, 0x0708, 0x070F),
        ("digital_speed_ram", 8, 0x3F08, 0x3F0F),
        ("digital_accel_time_ram", 8, 0x4000, 0x4007),
        ("digital_decel_time_ram", 8, 0x4008, 0x400F),
        ("digital_torque_limit_ram", 8, 0x4300, 0x4307),
        ("digital_duty_ram", 8, 0x4308, 0x430F),
    ],
    ids=lambda v: v if isinstance(v, str) else None,
)
def test_arrays(regs: dict, name: str, count: int, first: int, last: int) -> None:
    """001 §1.1/§4.4/§4.5/§4.6 address tables: every element, contiguous."""
    addresses = [regs[f"{name}[{i}]"]["address"] for i in range(count)]
    assert addresses == list(range(first, last + 1))
    assert f"{name}[{count}]" not in regs


def test_net_x_defaults(regs: dict) -> None:
    """001 §1.1 / §4.1: initial values of 09-01..09-08 are 1, 2, 8, 6, 10, 11, 0, 0."""
    assert [regs[f"net_x_input_function[{i}]"]["default"] for i in range(8)] == [1, 2, 8, 6, 10, 11, 0, 0]


def test_duty_defaults(regs: dict) -> None:
    """001 §4.6: duty initial values 100..1000 (1=0.1 %)."""
    assert [regs[f"digital_duty[{i}]"]["default"] for i in range(8)] == [10, 20, 30, 40, 50, 60, 80, 100]


def test_eeprom_ram_twins(regs: dict) -> None:
    """001 §4.6: every EEPROM operation-data register has a RAM twin with the same scale and range."""
    for base in ("digital_speed", "digital_accel_time", "digital_decel_time", "digital_torque_limit", "digital_duty"):
        for i in range(8):
            eep, ram = regs[f"{base}[{i}]"], regs[f"{base}_ram[{i}]"]
            assert eep["storage"] == "eeprom" and ram["storage"] == "ram"
            for key in ("scale", "unit", "min", "max", "reflect"):
                assert eep[key] == ram[key], f"{base}[{i}].{key}"


def test_monitor_pages_share_addresses(regs: dict) -> None:
    """001 §4.3: 0008h-000Fh change meaning with 09-11; 0000h-0007h do not."""
    page0 = {r["address"] for r in regs.values() if r["page"] == PAGE0}
    page1 = {r["address"] for r in regs.values() if r["page"] == PAGE1}
    assert page1 == set(range(0x0008, 0x0010))
    assert page0 == {0x0008, 0x0009, 0x000B, 0x000C}
    assert all(r["page"] is None for r in regs.values() if r["address"] < 0x0008)


def test_protocol(ev: dict) -> None:
    """001 §1, §1.3, §2.1, §2.2, §4.5: the protocol facts."""
    p = ev["protocol"]
    # function codes: 03h (max 16, no broadcast), 06h, 10h (max 16, broadcast)
    fcs = {fc["code"]: fc for fc in p["function_codes"]}
    assert set(fcs) == {0x03, 0x06, 0x10}
    assert fcs[0x03]["max_quantity"] == 16 and fcs[0x03]["broadcast"] is False
    assert fcs[0x06]["broadcast"] is True
    assert fcs[0x10]["max_quantity"] == 16 and fcs[0x10]["broadcast"] is True
    assert p["broadcast_address"] == 0
    ports = {port["name"]: port for port in p["ports"]}
    assert ports["rs485"]["baudrates"] == [9600, 19200, 38400, 57600, 115200]
    assert ports["rs232"]["baudrates"] == [115200] and ports["rs232"]["fixed_unit"] == 17
    assert ports["rs232"]["modes"] == ["ascii"]
    assert {e["code"] for e in p["exceptions"]} == {1, 2, 3, 4}
    assert {c["code"] for c in p["comm_errors"]} == {0x84, 0x85, 0x88, 0x8C, 0x8D}
    assert p["configuration"] == {"register": "configuration", "value": 1}
    assert p["comm_error_history"] == "comm_error_history"
    policy = p["exception_policy"]
    if isinstance(policy, list):
        policy = {item["case"]: item for item in policy}
    assert {case: policy[case]["code"] for case in ("illegal_function", "illegal_address", "illegal_quantity",
                                                    "out_of_range", "busy")} == {
        "illegal_function": 1, "illegal_address": 2, "illegal_quantity": 3, "out_of_range": 4, "busy": 4}
    assert policy["read_only"]["source"] == "map choice"


def test_examples_verified(ev: dict) -> None:
    """001 §2.2, §3.1-§3.3, Appendix I: ten RTU examples, every printed CRC correct."""
    names = {ex["name"]: ex for ex in ev["examples"]}
    assert len(names) == 10
    assert all(ex["status"] == "verified" for ex in names.values())
    assert names["broadcast_net_in_directions"]["response"] is None
    assert names["broadcast_write_speeds_ram"]["response"] is None


def test_appendix_ii_ascii_address_17_recorded(ev: dict) -> None:
    """001 Appendix II l.1828 'address fixed at 17' vs §1 RS-485 ASCII with SW1 ids 1-15: both accepted."""
    issue = next(k for k in ev["known_issues"] if "fixed at 17" in k["title"])
    assert issue["source"] == "001 Appendix II" and "單台通訊從站位址固定為 17" in issue["printed"]
    proto = ev["protocol"]
    ports = {p["name"]: p for p in proto["ports"]}
    assert ports["rs232"]["fixed_unit"] == 17 and ports["rs485"]["fixed_unit"] is None
    assert "ascii" in ports["rs485"]["modes"] and (proto["unit_min"], proto["unit_max"]) == (1, 15)


def test_unlisted_addresses_are_not_called_reserved(ev: dict) -> None:
    """001 §4.3 prints 保留 for monitor rows; 21 addresses (02-02, 02-04..02-13, 08-02..08-10, 09-09) are
    not listed in this document at all."""
    kinds: dict[str, int] = {}
    for item in ev["reserved"]:
        kinds[item["kind"]] = kinds.get(item["kind"], 0) + item["end"] - item["start"] + 1
    assert kinds["not_listed"] == 21
    assert {(r["start"], r["end"]) for r in ev["reserved"] if r["kind"] == "reserved"} == {
        (0x0001, 0x0001), (0x0006, 0x0007), (0x000A, 0x000A), (0x000D, 0x000F)}
