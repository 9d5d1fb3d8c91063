"""The edx map against values read in the manual (shared/manuals/004_698379178adcef99.txt).

Each case id names the manual section it was read from ("004-<section>-<register>").
The map is read through the export contract: ``drivemap.backends.export.export_model("edx")``.
"""

from __future__ import annotations

import pytest

from drivemap.build import export_model

MODEL = "edx"


@pytest.fixture(scope="module")
def exported() -> dict:
    return export_model(MODEL)


@pytest.fixture(scope="module")
def registers(exported: dict) -> dict:
    return {reg["name"]: reg for reg in exported["registers"]}


def _bits(reg: dict) -> dict:
    return {b["name"]: (b["offset"], b.get("width", 1)) for b in reg["bits"] or ()}


# name, expected fields (engineering units; scale 1 when unscaled), as read in the manual.
REGISTER_CASES = [
    # 004 §4.1 Command Data (Readable and Writable)
    pytest.param("operation_signal", dict(address=0x00E6, type="u16", scale=1, unit=None, access="rw",
                                          default=None, enum=None, param=None),
                 id="004-4.1-operation_signal"),
    # 00E7H Frequency Command; scale from the 06H/10H examples: 1770h = 60.0 Hz -> 0.01 Hz.
    pytest.param("frequency_command", dict(address=0x00E7, type="u16", scale=0.01, unit="Hz", access="rw",
                                           min=None, max=None, default=None, enum=None),
                 id="004-5.3-frequency_command"),
    pytest.param("remote_keypad_used", dict(address=0x00E8, type="u16", scale=1, access="rw", enum=None,
                                            bits=None, default=None),
                 id="004-4.1-remote_keypad_used"),
    # 004 §4.2 Monitor Data (Only for reading)
    pytest.param("status", dict(address=0x00EF, type="u16", scale=1, access="r", enum=None),
                 id="004-4.2-status"),
    pytest.param("fault_code", dict(address=0x00F0, type="u16", scale=1, access="r", bits=None),
                 id="004-4.2-fault_code"),
    pytest.param("io_status", dict(address=0x00F1, type="u16", access="r", enum=None),
                 id="004-4.2-io_status"),
    pytest.param("frequency_command_monitor", dict(address=0x00F2, access="r", scale=0.01, unit="Hz"),
                 id="004-5.1-frequency_command_monitor"),
    pytest.param("output_frequency", dict(address=0x00F3, access="r", scale=1, unit=None),
                 id="004-4.2-output_frequency"),
    # (1/1V)
    pytest.param("output_voltage_command", dict(address=0x00F4, type="u16", access="r", scale=1, unit="V"),
                 id="004-4.2-output_voltage_command"),
    pytest.param("dc_voltage_command", dict(address=0x00F5, type="u16", access="r", scale=1, unit="V"),
                 id="004-4.2-dc_voltage_command"),
    # (10/1A) -> 0.1 A
    pytest.param("output_current", dict(address=0x00F6, type="u16", access="r", scale=0.1, unit="A",
                                        default=None),
                 id="004-4.2-output_current"),
    # (10/1%) -> 0.1 %
    pytest.param("pid_feedback", dict(address=0x00F7, type="u16", access="r", scale=0.1, unit="%"),
                 id="004-4.2-pid_feedback"),
    # (10/1%, sign attached) -> s16
    pytest.param("pid_input", dict(address=0x00F8, type="s16", access="r", scale=0.1, unit="%"),
                 id="004-4.2-pid_input"),
    # (1024 / 10V) *1: footnote missing, kept raw
    pytest.param("tm2_ain_input", dict(address=0x00F9, access="r", scale=1, unit=None),
                 id="004-4.2-tm2_ain_input"),
    pytest.param("keypad_ain_input", dict(address=0x00FA, access="r", scale=1, unit=None),
                 id="004-4.2-keypad_ain_input"),
    pytest.param("remote_keypad_used_fb", dict(address=0x00FB, access="r"), id="004-4.2-remote_keypad_used_fb"),
    pytest.param("remote_keypad_used_fc", dict(address=0x00FC, access="r"), id="004-4.2-remote_keypad_used_fc"),
    # 004 §6 comparison list: one register per parameter, not linear.
    pytest.param("f00", dict(address=0x0000, param="F00", access="rw", scale=1, unit=None, default=None),
                 id="004-6-f00"),
    pytest.param("f07", dict(address=0x0008, param="F07", access="rw"), id="004-6-f07"),
    pytest.param("f11", dict(address=0x000E, param="F11", access="rw"), id="004-6-f11"),
    pytest.param("f16", dict(address=0x0092, param="F16", access="rw"), id="004-6-f16"),
    pytest.param("f24", dict(address=0x009F, param="F24", access="rw"), id="004-6-f24"),
    pytest.param("f25", dict(address=0x00A0, param="F25", access="rw"), id="004-6-f25"),
    pytest.param("f45", dict(address=0x0099, param="F45", access="rw"), id="004-6-f45"),
    pytest.param("f50", dict(address=0x00DF, param="F50", access="rw"), id="004-6-f50"),
    pytest.param("f54[0]", dict(address=0x002D, param="F54", access="rw"), id="004-6-f54[0]"),
    pytest.param("f54[1]", dict(address=0x002E, param="F54", access="rw"), id="004-6-f54[1]"),
    pytest.param("f54[2]", dict(address=0x002F, param="F54", access="rw"), id="004-6-f54[2]"),
    pytest.param("c00", dict(address=0x0064, param="C00", access="rw", default=None), id="004-6-c00"),
    pytest.param("c14", dict(address=0x009A, param="C14", access="rw"), id="004-6-c14"),
    pytest.param("c15", dict(address=0x0007, param="C15", access="rw"), id="004-6-c15"),
    pytest.param("c16", dict(address=0x009E, param="C16", access="rw"), id="004-6-c16"),
    pytest.param("c23", dict(address=0x000C, param="C23", access="rw"), id="004-6-c23"),
    pytest.param("c25", dict(address=0x0029, param="C25", access="rw"), id="004-6-c25"),
    pytest.param("c41", dict(address=0x009D, param="C41", access="rw"), id="004-6-c41"),
    pytest.param("c47", dict(address=0x0030, param="C47", access="rw"), id="004-6-c47"),
    pytest.param("c55", dict(address=0x009C, param="C55", access="rw"), id="004-6-c55"),
]


@pytest.mark.parametrize("name, expected", REGISTER_CASES)
def test_register(registers: dict, name: str, expected: dict) -> None:
    reg = registers[name]
    for key, value in expected.items():
        assert reg[key] == value, f"{name}.{key}: map has {reg[key]!r}, manual says {value!r}"


def test_operation_signal_bits(registers: dict) -> None:
    """004 §4.1: 00E6H bits 0-8, B, C as printed (9, A, D-F not used)."""
    assert _bits(registers["operation_signal"]) == {
        "RUN": (0, 1), "REVERSE": (1, 1), "EXTERNAL_FAULT": (2, 1), "FAULT_RESET": (3, 1), "JOG": (4, 1),
        "S1": (5, 1), "S2": (6, 1), "S3": (7, 1), "S4": (8, 1), "AIN": (11, 1), "RY1": (12, 1),
    }


def test_status_bits(registers: dict) -> None:
    """004 §4.2: 00EFH bits 0-4 (5-F unused)."""
    assert _bits(registers["status"]) == {
        "RUNNING": (0, 1), "REVERSE": (1, 1), "READY": (2, 1), "ABNORMAL": (3, 1), "DATA_SETTING_ERROR": (4, 1),
    }


def test_io_status_bits(registers: dict) -> None:
    """004 §4.2: 00F1H S1-S4 bits 0-3, AIN bit 6, RELAY1 bit 7."""
    assert _bits(registers["io_status"]) == {
        "S1": (0, 1), "S2": (1, 1), "S3": (2, 1), "S4": (3, 1), "AIN": (6, 1), "RELAY1": (7, 1),
    }


@pytest.mark.parametrize("member, value", [
    pytest.param("NORMAL", 0, id="004-4.2-fault_code-00"),
    pytest.param("OH", 1, id="004-4.2-fault_code-01"),
    pytest.param("OL1", 10, id="004-4.2-fault_code-10"),
    pytest.param("ES", 11, id="004-4.2-fault_code-11"),
    pytest.param("OCC", 13, id="004-4.2-fault_code-13"),
    pytest.param("ER6", 27, id="004-4.2-fault_code-27"),
    pytest.param("OCL", 35, id="004-4.2-fault_code-35"),
])
def test_fault_code_enum(registers: dict, member: str, value: int) -> None:
    assert registers["fault_code"]["enum"][member] == value


def test_fault_code_enum_complete(registers: dict) -> None:
    """004 §4.2: codes 00-35, 12 unused: 35 members."""
    values = sorted(registers["fault_code"]["enum"].values())
    assert values == [v for v in range(36) if v != 12]


def test_parameter_lists_complete(registers: dict) -> None:
    """004 §6: F00-F54 and C00-C55, each its own register."""
    params = {r["param"] for r in registers.values() if r["param"]}
    assert {f"F{i:02d}" for i in range(55)} <= params
    assert {f"C{i:02d}" for i in range(56)} <= params


def test_no_address_collision(registers: dict) -> None:
    addresses = [r["address"] for r in registers.values()]
    assert len(addresses) == len(set(addresses))


def test_protocol(exported: dict) -> None:
    proto = exported["protocol"]
    # 004 §1.3 unit ids 01H..FEH, 00H broadcast
    assert (proto["unit_min"], proto["unit_max"]) == (1, 254)
    assert proto["broadcast_address"] == 0
    # 004 §1: frame length maximum 80 bytes; RTU and ASCII
    assert proto["max_frame_bytes"] == 80
    assert set(proto["modes"]) == {"rtu", "ascii"}
    # 004 §2.3 time-out 400 ms, retry max 2; 004 §1.2.2 10 ms interval
    assert proto["timing"]["response_timeout_ms"] == 400
    assert proto["timing"]["retries"] == 2
    assert proto["timing"]["inter_frame_gap_ms"] == 10
    # 004 §1.4 function codes
    assert {fc["code"] for fc in proto["function_codes"]} == {0x03, 0x06, 0x08, 0x10}
    # 004 §1.3 only names 00H as the broadcast address: writes unknown (null, with the reason), reads and
    # loopback false (map choice: they need a reply); the same rule as v2 003 §2 and vfd1000 002.
    fcs = {fc["code"]: fc for fc in proto["function_codes"]}
    assert {code: fc["broadcast"] for code, fc in fcs.items()} == {3: False, 6: None, 8: False, 16: None}
    assert "00H : Broadcast to all the drivers" in fcs[6]["broadcast_reason"]
    assert fcs[16]["broadcast_reason"] == fcs[6]["broadcast_reason"]
    assert fcs[3]["broadcast_reason"].startswith("map choice") and fcs[8]["broadcast_reason"].startswith("map choice")
    assert not any(r["broadcast"] for r in exported["registers"])
    # 004 §3 error codes (hexadecimal bytes, see the examples) and §5.2's 20H
    assert {e["code"] for e in proto["exceptions"]} == {0x51, 0x52, 0x53, 0x54, 0x55, 0x20}


@pytest.mark.parametrize("case, code", [
    pytest.param("illegal_function", 0x51, id="004-3-illegal_function"),
    pytest.param("illegal_address", 0x52, id="004-3-illegal_address"),
    pytest.param("illegal_quantity", 0x53, id="004-3-illegal_quantity"),
    pytest.param("out_of_range", 0x54, id="004-3-out_of_range"),
])
def test_exception_policy(exported: dict, case: str, code: int) -> None:
    policy = exported["protocol"]["exception_policy"]
    if isinstance(policy, list):  # export form: [{case, code, source, reason}, ...]
        policy = {entry["case"]: entry for entry in policy}
    assert policy[case]["code"] == code


def test_examples_count(exported: dict) -> None:
    """004 §3 (2 replies) + §5.1-§5.4 x (ASCII, RTU) x (normal, fault) = 18 examples."""
    assert len(exported["examples"]) == 18


def _crc(frame: bytes) -> bytes:
    crc = 0xFFFF
    for byte in frame:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc.to_bytes(2, "little")


def _issue(exported: dict, affected: str, title: str) -> dict:
    found = [k for k in exported["known_issues"] if affected in k["affects"] and title in k["title"]]
    assert len(found) == 1, [k["title"] for k in found]
    return found[0]


def test_error_code_rtu_both_corrections_recorded(exported: dict) -> None:
    """004 §3 (l.147-151): 02 83 52 C0 CD; unit 01 (A) or CRC 30 CD (B) both fit; (A) is chosen."""
    issue = _issue(exported, "error_code_rtu", "two corrections fit")
    for frame in ("01 83 52 C0 CD", "02 83 52 30 CD"):  # both readings are valid frames
        raw = bytes.fromhex(frame)
        assert _crc(raw[:-2]) == raw[-2:]
        assert frame in issue["printed"]
    assert issue["corrected"] == "01 83 52 C0 CD" and issue["chosen"].startswith("(A)")
    assert "004 §5.1 RTU" in issue["reason"]
    example = {e["name"]: e for e in exported["examples"]}["error_code_rtu"]
    assert example["response"] == "028352C0CD" and example["status"] == "erratum"


def test_function_code_and_80h_recorded(exported: dict) -> None:
    """004 §3 l.153 prints 'Function Code AND 80H'; every printed fault reply sets bit 7 (OR 80H)."""
    issue = next(k for k in exported["known_issues"] if "AND 80H" in k["title"])
    assert issue["corrected"] == "Function Code OR 80H"
    faults = [e for e in exported["examples"] if e["name"].endswith("_fault") or e["name"].startswith("error_code")]
    assert len(faults) == 10 and set(issue["affects"]) == {e["name"] for e in faults}
    for ex in faults:
        frame = ex["response"]
        fc = int(frame[3:5], 16) if ex["mode"] == "ascii" else int(frame[2:4], 16)
        assert fc & 0x80 and fc & 0x7F in (0x03, 0x06, 0x08, 0x10), ex["name"]


def test_unlisted_addresses_are_not_called_reserved(exported: dict) -> None:
    """004 §6/§4: 35 addresses are never listed; 0039H-0063H and 00A1H-00C7H are listed without a name;
    only 00E9H-00EEH and 00FDH-00FFH are printed (Reserved)."""
    kinds: dict[str, int] = {}
    for item in exported["reserved"]:
        kinds[item["kind"]] = kinds.get(item["kind"], 0) + item["end"] - item["start"] + 1
    assert kinds == {"not_listed": 35, "unlabeled": 43 + 39, "reserved": 6 + 3}
