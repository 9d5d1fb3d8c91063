"""The v2 map against values read in the manual (shared/manuals/003_81ad9a58587804cf.txt).

Each case id names the manual section it was read from ("003-<section>-<register>").
The map is read through the export contract: ``drivemap.backends.export.export_model("v2")``.
"""

from __future__ import annotations

import pytest

from drivemap.build import export_model

MODEL = "v2"


@pytest.fixture(scope="module")
def exported() -> dict:
    return export_model(MODEL)


@pytest.fixture(scope="module")
def registers(exported: dict) -> dict:
    return {reg["name"]: reg for reg in exported["registers"]}


# name, expected fields (engineering units; scale 1 when unscaled), as read in the manual.
REGISTER_CASES = [
    # 003 §DATA 一览表 (指令 DATA): 0101H bit field, read and write.
    pytest.param("run_command", dict(address=0x0101, type="u16", scale=1, unit=None, access="rw",
                                     default=None, enum=None, param="P_257"),
                 id="003-DATA一览表-指令DATA-run_command"),
    # 0102H 频率指令; scale from the 06H example: 1770h = 60.0 Hz -> 0.01 Hz.
    pytest.param("frequency_command", dict(address=0x0102, type="u16", scale=0.01, unit="Hz", access="rw",
                                           default=None, min=None, max=None, enum=None, param="P_258"),
                 id="003-保持暂存器的写入06H-frequency_command"),
    # 0103H 转矩指令 *1: no scale or unit printed.
    pytest.param("torque_command", dict(address=0x0103, type="u16", scale=1, unit=None, access="rw",
                                        default=None, enum=None, bits=None),
                 id="003-DATA一览表-指令DATA-torque_command"),
    # 003 §DATA 一览表 (监视数据): read only.
    pytest.param("status", dict(address=0x0120, type="u16", scale=1, access="r", enum=None, param="P_288"),
                 id="003-DATA一览表-监视数据-status"),
    # 0123H: revealed by the 03H example (reads 频率指令 at 0123H, gets 1770h).
    pytest.param("frequency_command_monitor", dict(address=0x0123, type="u16", scale=0.01, unit="Hz", access="r",
                                                   enum=None, bits=None),
                 id="003-保持暂存器内容读出03H-frequency_command_monitor"),
    # 0127H 输出电流 (10/1A).
    pytest.param("output_current", dict(address=0x0127, type="u16", scale=0.1, unit="A", access="r",
                                        default=None, enum=None, bits=None, param="P_295"),
                 id="003-DATA一览表-监视数据-output_current"),
    pytest.param("torque_command_monitor", dict(address=0x0128, scale=1, unit=None, access="r"),
                 id="003-DATA一览表-监视数据-torque_command_monitor"),
    pytest.param("output_torque", dict(address=0x0129, scale=1, unit=None, access="r"),
                 id="003-DATA一览表-监视数据-output_torque"),
    # 012AH PID 回授量 (10/1%), unsigned; 012BH PID 输入量 (10/1% 附符号), signed.
    pytest.param("pid_feedback", dict(address=0x012A, type="u16", scale=0.1, unit="%", access="r"),
                 id="003-DATA一览表-监视数据-pid_feedback"),
    pytest.param("pid_input", dict(address=0x012B, type="s16", scale=0.1, unit="%", access="r"),
                 id="003-DATA一览表-监视数据-pid_input"),
    # 012CH/012DH TM2 AIN / AV2 (1024 / 10V).
    pytest.param("ain_input", dict(address=0x012C, type="u16", scale=10 / 1024, unit="V", access="r"),
                 id="003-DATA一览表-监视数据-ain_input"),
    pytest.param("av2_input", dict(address=0x012D, type="u16", scale=10 / 1024, unit="V", access="r"),
                 id="003-DATA一览表-监视数据-av2_input"),
    # 003 §参数与暂存器编号对照表: P_n at register n; meaning/range/default not in this document.
    pytest.param("parameters[0]", dict(address=0x0000, type="u16", scale=1, unit=None, access="rw",
                                       default=None, min=None, max=None, enum=None),
                 id="003-参数与暂存器编号对照表-parameters[0]"),
    pytest.param("parameters[52]", dict(address=0x0034, access="rw", default=None),
                 id="003-参数与暂存器编号对照表-parameters[52]"),
    pytest.param("parameters[75]", dict(address=0x004B, access="rw", default=None),
                 id="003-参数与暂存器编号对照表-parameters[75]"),
    pytest.param("parameters[174]", dict(address=0x00AE, access="rw"),
                 id="003-参数与暂存器编号对照表-parameters[174]"),
    pytest.param("parameters[255]", dict(address=0x00FF, access="rw", default=None),
                 id="003-参数与暂存器编号对照表-parameters[255]"),
]


@pytest.mark.parametrize("name, expected", REGISTER_CASES)
def test_register(registers: dict, name: str, expected: dict) -> None:
    assert name in registers, f"{name} missing from the export"
    reg = registers[name]
    for key, want in expected.items():
        got = reg[key]
        if isinstance(want, float):
            assert got == pytest.approx(want), f"{name}.{key}"
        else:
            assert got == want, f"{name}.{key}: {got!r} != {want!r}"


def _bits(reg: dict) -> dict:
    return {b["name"]: (b["offset"], b.get("width", 1)) for b in reg["bits"]}


def test_run_command_bits(registers: dict) -> None:
    """003 §DATA 一览表 (指令 DATA), 0101H: bits 0-D as printed, B and E-F unused."""
    assert _bits(registers["run_command"]) == {
        "RUN": (0, 1), "REVERSE": (1, 1), "EXTERNAL_FAULT": (2, 1), "FAULT_RESET": (3, 1), "JOG": (4, 1),
        "MULTI_INPUT_1": (5, 1), "MULTI_INPUT_2": (6, 1), "MULTI_INPUT_3": (7, 1),
        "MULTI_INPUT_FWD": (8, 1), "MULTI_INPUT_REV": (9, 1), "MULTI_INPUT_RES": (10, 1),
        "MULTI_OUTPUT_1": (12, 1), "MULTI_OUTPUT_2": (13, 1),
    }


def test_status_bits(registers: dict) -> None:
    """003 §DATA 一览表 (监视数据), 0120H: bits 0-4, 5-F unused."""
    assert _bits(registers["status"]) == {
        "RUNNING": (0, 1), "REVERSE": (1, 1), "READY": (2, 1), "FAULT": (3, 1), "DATA_ERROR": (4, 1),
    }


@pytest.mark.parametrize("address", [0x0100, 0x0104, 0x011F, 0x0121, 0x0122, 0x0124, 0x0126, 0x012E, 0x012F],
                         ids=lambda a: f"003-DATA一览表-reserved-{a:04X}H")
def test_reserved_addresses_have_no_register(registers: dict, address: int) -> None:
    assert all(reg["address"] != address for reg in registers.values())


def test_parameter_array_stops_at_p255(registers: dict) -> None:
    """003 §参数与暂存器编号对照表: P_256.. fall on the command/monitor block, not modelled as parameters."""
    assert "parameters[256]" not in registers
    assert sum(1 for name in registers if name.startswith("parameters[")) == 256


def test_protocol_facts(exported: dict) -> None:
    """003 §2 通信格式 and 003 §错误代码一览表."""
    proto = exported["protocol"]
    assert proto["modes"] == ["rtu"]
    assert (proto["unit_min"], proto["unit_max"]) == (1, 254)
    assert proto["broadcast_address"] == 0
    fcs = {fc["code"]: fc for fc in proto["function_codes"]}
    assert sorted(fcs) == [0x03, 0x06, 0x08, 0x10]
    assert fcs[0x03]["max_quantity"] == 16
    assert fcs[0x06]["max_quantity"] == 1
    assert fcs[0x10]["max_quantity"] == 11  # 31-byte request = 9 + 2N
    # 003 §2 通信格式: "0 表一齐发送指令" names the broadcast address only: writes unknown (null, with the
    # reason), reads and loopback false (map choice: they need a reply); the same rule as edx and vfd1000.
    assert {code: fc["broadcast"] for code, fc in fcs.items()} == {3: False, 6: None, 8: False, 16: None}
    assert all(fc["broadcast_reason"] for fc in fcs.values())
    assert "0 表一齐发送指令" in fcs[6]["broadcast_reason"] and fcs[3]["broadcast_reason"].startswith("map choice")
    policy = {entry["case"]: entry["code"] for entry in proto["exception_policy"]}
    assert policy["illegal_function"] == 0x51
    assert policy["illegal_address"] == 0x52
    assert policy["illegal_quantity"] == 0x53
    assert policy["out_of_range"] == 0x54
    assert policy["read_only"] == 0x55
    assert policy["busy"] == 0x55
    assert proto["timing"]["inter_frame_gap_ms"] == 10


def _hex(frame: str | None) -> str | None:
    return None if frame is None else frame.replace(" ", "").upper()


def test_examples_transcribed(exported: dict) -> None:
    """Every printed frame pair (4 function codes x normal/abnormal reply), as printed; two errata."""
    examples = {ex["name"]: ex for ex in exported["examples"]}
    assert len(examples) == 8
    # 003 §保持暂存器内容读出 [03H]: printed CRC AF 82 (correct: B6 50).
    assert _hex(examples["read_frequency_command"]["response"]) == "0103021770AF82"
    assert examples["read_frequency_command"]["status"] == "erratum"
    # 003 §保持暂存器内容读出 [03H]: fault reply printed with unit 02 (CRC C0 CD is right for unit 01).
    assert _hex(examples["read_frequency_command_fault"]["response"]) == "028352C0CD"
    assert examples["read_frequency_command_fault"]["status"] == "erratum"
    # 003 §LOOP BACK 测试 [08H]: fault code 20H (not in the error table), CRC correct.
    assert _hex(examples["loopback_fault"]["response"]) == "01882047D8"
    # 003 §复数保持暂存器的写入 [10H].
    assert _hex(examples["write_run_forward_60hz"]["request"]) == "01100101000204000117706027"
    verified = {name for name, ex in examples.items() if ex["status"] == "verified"}
    assert verified == set(examples) - {"read_frequency_command", "read_frequency_command_fault"}


def test_every_parameter_element_exports_its_id(registers: dict) -> None:
    """003 §参数与暂存器编号对照表: P_n is at register n, so parameters[n] is P_n for n = 0..255."""
    for n in range(256):
        reg = registers[f"parameters[{n}]"]
        assert (reg["address"], reg["param"]) == (n, f"P_{n}")
    # P_256.. are the command/monitor registers at the same addresses
    assert registers["run_command"]["param"] == "P_257" and registers["status"]["param"] == "P_288"


def test_unlisted_addresses_are_not_called_reserved(exported: dict) -> None:
    """003 §DATA 一览表 (监视数据): 0121H-0122H and 0124H-0126H are not listed (5 addresses), unlike the
    预备 (reserved) rows 0100H, 0104H-011FH, 012EH-012FH."""
    kinds: dict[str, int] = {}
    for item in exported["reserved"]:
        kinds[item["kind"]] = kinds.get(item["kind"], 0) + item["end"] - item["start"] + 1
    assert kinds == {"reserved": 1 + 28 + 2, "not_listed": 5}
