"""maps/vfd1000.yaml against values read in manual 002 (002_65caa110b92ac236.txt).

The manual's sections have no numbers; case ids name the table or example instead:
"CmdTable" = communication control command table (1000H-3016H), "FaultTable" = 5000H table,
"Ex03H" / "Ex06H" = the worked examples.
"""

from __future__ import annotations

import json

import pytest

from drivemap.build import export_model

MODEL = "vfd1000"


@pytest.fixture(scope="module")
def exported() -> dict:
    return export_model(MODEL)


@pytest.fixture(scope="module")
def registers(exported: dict) -> dict:
    return {r["name"]: r for r in exported["registers"]}


def _crc16_modbus(data: bytes) -> bytes:
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return bytes([crc & 0xFF, crc >> 8])


# (name, expected fields) -- every value read in manual 002; None = the manual does not give it.
CASES = [
    pytest.param("control_command", dict(address=0x1000, type="u16", access="w", scale=1, unit=None, default=None,
                 enum={"FORWARD_RUNNING": 1, "REVERSE_RUNNING": 2, "FORWARD_JOGGING": 3, "JOGGING_0004": 4,
                       "STOP": 5, "FREE_STOP": 6, "FAULT_RESET": 7, "JOG_STOP": 8}),
                 id="002-CmdTable-1000H-control_command"),
    pytest.param("inverter_state", dict(address=0x1001, type="u16", access="r", scale=1, default=None,
                 enum={"FORWARD_RUNNING": 1, "REVERSE_RUNNING": 2, "STANDBY": 3, "FAULT": 4, "POFF": 5}),
                 id="002-CmdTable-1001H-inverter_state"),
    pytest.param("communication_setting", dict(address=0x2000, type="s16", access="rw", scale=0.01, unit="%",
                 min=-100.0, max=100.0, default=None, enum=None),
                 id="002-CmdTable-2000H-communication_setting"),
    pytest.param("pid_setting", dict(address=0x2001, type="u16", access="rw", scale=0.1, unit="%",
                 min=0, max=100.0, default=None),
                 id="002-CmdTable-2001H-pid_setting"),
    pytest.param("pid_feedback", dict(address=0x2002, type="u16", access="rw", scale=0.1, unit="%",
                 min=0, max=100.0, default=None),
                 id="002-CmdTable-2002H-pid_feedback"),
    pytest.param("torque_setting_value", dict(address=0x2003, type="u16", access="rw", scale=0.1, unit="%",
                 min=0, max=100.0, default=None),
                 id="002-CmdTable-2003H-torque_setting_value"),
    pytest.param("upper_limit_frequency_setting", dict(address=0x2004, access="rw", scale=1, unit=None,
                 min=0, max=None, default=None),
                 id="002-CmdTable-2004H-upper_limit_frequency_setting"),
    pytest.param("operating_frequency", dict(address=0x3000, access="r", scale=1, unit=None, default=None),
                 id="002-CmdTable-3000H-operating_frequency"),
    pytest.param("set_frequency", dict(address=0x3001, access="r", scale=1, unit=None),
                 id="002-CmdTable-3001H-set_frequency"),
    pytest.param("dc_bus_voltage", dict(address=0x3002, access="r", scale=1, unit=None),
                 id="002-CmdTable-3002H-dc_bus_voltage"),
    pytest.param("output_current", dict(address=0x3004, access="r", scale=1, unit=None),
                 id="002-CmdTable-3004H-output_current"),
    pytest.param("pid_feedback_value", dict(address=0x3009, access="r", scale=1, unit=None),
                 id="002-CmdTable-3009H-pid_feedback_value"),
    pytest.param("terminal_input_status", dict(address=0x300A, access="r", bits=None),
                 id="002-CmdTable-300AH-terminal_input_status"),
    pytest.param("analog_input_ai1", dict(address=0x300C, access="r", scale=1, unit=None),
                 id="002-CmdTable-300CH-analog_input_ai1"),
    pytest.param("analog_input_ai2", dict(address=0x300D, access="r", scale=1, unit=None),
                 id="002-CmdTable-300DH-analog_input_ai2"),
    pytest.param("high_speed_pulse_frequency", dict(address=0x3010, access="r"),
                 id="002-CmdTable-3010H-high_speed_pulse_frequency"),
    pytest.param("plc_current_step", dict(address=0x3012, access="r"),
                 id="002-CmdTable-3012H-plc_current_step"),
    pytest.param("external_counter_input", dict(address=0x3014, access="r"),
                 id="002-CmdTable-3014H-external_counter_input"),
    pytest.param("torque_setting", dict(address=0x3015, access="r", scale=1, unit=None),
                 id="002-CmdTable-3015H-torque_setting"),
    pytest.param("device_code", dict(address=0x3016, access="r"),
                 id="002-CmdTable-3016H-device_code"),
    pytest.param("fault_code", dict(address=0x5000, type="u16", access="r", scale=1, unit=None,
                 enum={"NO_FAULT": 0, "OUT1": 1, "OUT2": 2, "OUT3": 3, "OC1": 4, "OC2": 5, "OC3": 6,
                       "OV1": 7, "OV2": 8, "OV3": 9, "UV": 10, "OL1": 11, "OL2": 12, "SPI": 13, "SPO": 14,
                       "OH1": 15, "OH2": 16, "EF": 17, "CE": 18, "ITE": 19, "TE": 20, "EEP": 21,
                       "PIDE": 22, "BCE": 23, "END": 24, "OL3": 25}),
                 id="002-FaultTable-5000H-fault_code"),
    pytest.param("parameter_0004", dict(address=0x0004, type="u16", access="r", scale=1, unit=None, default=None,
                 param=None),
                 id="002-Ex03H-parameter_0004"),
    pytest.param("parameter_0005", dict(address=0x0005, type="u16", access="r", scale=1, unit=None, default=None),
                 id="002-Ex03H-parameter_0005"),
    pytest.param("parameter_0008", dict(address=0x0008, type="u16", access="rw", scale=1, unit=None, default=None),
                 id="002-Ex06H-parameter_0008"),
]


@pytest.mark.parametrize(("name", "expected"), CASES)
def test_register(registers: dict, name: str, expected: dict) -> None:
    assert name in registers, f"{name} missing from the map"
    reg = registers[name]
    for key, value in expected.items():
        if isinstance(value, float):
            assert reg[key] == pytest.approx(value), f"{name}.{key}"
        else:
            assert reg[key] == value, f"{name}.{key}"


def test_no_invented_registers_for_pc_parameters(registers: dict) -> None:
    """002 §PC.00-PC.02: the PC.xx register addresses are not printed, so none is a register."""
    assert not [r for r in registers.values() if (r["param"] or "").startswith("PC.")]


def test_reserved_monitor_addresses_not_registers(registers: dict) -> None:
    """002 §CmdTable: 300EH, 300FH, 3011H, 3013H are 'Reserved'."""
    addresses = {r["address"] for r in registers.values()}
    assert not addresses & {0x300E, 0x300F, 0x3011, 0x3013}


def test_protocol_unit_ids_and_serial(exported: dict) -> None:
    """002 §PC.00 (1~247), §RTU frame format (0 = broadcast), §PC.01, §PC.02."""
    p = exported["protocol"]
    # the export contract fixes only the top-level keys; accept both spellings of the unit range
    units = p.get("unit_ids") or {"min": p.get("unit_min"), "max": p.get("unit_max")}
    assert units["min"] == 1 and units["max"] == 247
    assert p["broadcast_address"] == 0
    # 002 §RTU frame format only names 0 as the broadcast address: 06H unknown (null, with the reason),
    # 03H false (map choice: a read needs a reply); the same rule as edx 004 §1.3 and v2 003 §2.
    fcs = {fc["code"]: fc for fc in p["function_codes"]}
    assert {code: fc["broadcast"] for code, fc in fcs.items()} == {3: False, 6: None}
    assert "broadcast address" in fcs[6]["broadcast_reason"] and fcs[3]["broadcast_reason"].startswith("map choice")
    port = p["ports"][0]
    assert port["baudrates"] == [1200, 2400, 4800, 9600, 19200, 38400]
    assert set(port["parity"]) == {"none", "even", "odd"}
    assert port["data_bits"] == [8]
    assert set(port["stop_bits"]) == {1, 2}
    assert port["default_baudrate"] is None and port["default_parity"] is None


@pytest.mark.parametrize(
    "frame",
    [
        pytest.param("01 03 00 04 00 02 85 CA", id="002-Ex03H-request"),
        pytest.param("01 03 00 04 00 00 00 00 43 07", id="002-Ex03H-response-as-printed"),
        pytest.param("01 03 04 00 00 00 00 FA 33", id="002-Ex03H-response-standard"),
        pytest.param("02 06 00 08 13 88 05 6D", id="002-Ex06H-request-and-response"),
    ],
)
def test_example_crc(frame: str) -> None:
    raw = bytes.fromhex(frame)
    assert _crc16_modbus(raw[:-2]) == raw[-2:]


def test_examples_present(exported: dict) -> None:
    """002 §Example read 03H / §Example write 06H."""
    ex = {e["name"]: e for e in exported["examples"]}
    assert set(ex) == {"read_0004_two_registers", "write_0008_5000"}
    assert ex["read_0004_two_registers"]["request"].replace(" ", "").upper() == "01030004000285CA"
    assert ex["read_0004_two_registers"]["response"].replace(" ", "").upper() == "01030004000000004307"
    assert ex["read_0004_two_registers"]["erratum"]
    assert ex["write_0008_5000"]["request"] == ex["write_0008_5000"]["response"]
    assert not ex["write_0008_5000"]["erratum"]


def test_exception_codes_are_marked_assumed(exported: dict) -> None:
    """002 §Response action: the exception table is missing; 01/02/03/06 are the map's assumption."""
    excs = {e["code"]: e for e in exported["protocol"]["exceptions"]}
    assert sorted(excs) == [0x01, 0x02, 0x03, 0x06]
    for exc in excs.values():
        assert exc["documented"] is False and exc["source"] == "map choice"
    for case in exported["protocol"]["exception_policy"]:
        assert case["source"] == "map choice"


def test_only_pc00_to_pc02_are_described(exported: dict) -> None:
    """002 §PC.00-§PC.02: the text names no PC.03-PC.05 (they came from a reading aid, not the manual)."""
    text = json.dumps([exported["title"], exported["protocol"], exported["registers"]], ensure_ascii=False)
    for name in ("PC.03", "PC.04", "PC.05"):
        assert name not in text
    whats = [s["what"] for s in exported["protocol"]["ports"][0]["settings"]]
    assert whats == ["unit id (local communication address)", "baud rate", "data format (parity and stop bits)"]


@pytest.mark.parametrize("model", ["edx", "ev", "v2"])
def test_other_maps_list_documented_codes_only(model: str) -> None:
    for exc in export_model(model)["protocol"]["exceptions"]:
        assert exc["documented"] is True and exc["source"] != "map choice", (model, exc["code"])


def test_reserved_rows_are_printed_reserved(exported: dict) -> None:
    """002 §Communication control command table: 300EH-300FH, 3011H, 3013H are printed "Reserved"."""
    assert {(r["start"], r["end"], r["kind"]) for r in exported["reserved"]} == {
        (0x300E, 0x300F, "reserved"), (0x3011, 0x3011, "reserved"), (0x3013, 0x3013, "reserved")}
