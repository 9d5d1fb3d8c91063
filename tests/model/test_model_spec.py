"""One hierarchy: the model's nodes extend the runtime's spec classes with compile-time facts only,
and :func:`spec_from_model` is their projection onto those classes (no copy field by field)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest

from drivemap.compiler import compile_map
from drivemap.model.family import IdentityCheck
from drivemap.model.nodes import (
    Alignment,
    Bit,
    CommError,
    Device,
    Enum,
    EnumValue,
    ExceptionCode,
    FunctionCode,
    Model,
    Page,
    PolicyCase,
    Protocol,
    Register,
    ReplyQuirk,
    Reserved,
    RunningState,
    Timing,
)
from drivemap.model.rules import AllowedValue
from drivemap.model.spec import project, spec_from_model
from drivemap.runtime import spec as runtime
from drivemap.runtime.spec import RegisterSpec

ROOT = Path(__file__).resolve().parents[2]
MAPS = sorted((ROOT / "maps").glob("*.yaml"))

#: Each model node, its runtime class, and the runtime fields it declares again: narrower types
#: (Literal, the model's own node classes) or fields derived from the map's richer form.
NODES: list[tuple[type, type, set[str]]] = [
    (Register, runtime.RegisterSpec,
     {"type", "access", "table", "bits", "values", "running_advice", "bits_class"}),
    (Bit, runtime.BitSpec, set()),
    (Enum, runtime.EnumSpec, {"members"}),
    (EnumValue, runtime.EnumMemberSpec, set()),
    (Reserved, runtime.ReservedSpec, {"table"}),
    (Timing, runtime.TimingSpec, set()),
    (Alignment, runtime.AlignmentSpec, {"table"}),
    (IdentityCheck, runtime.IdentitySpec, set()),
    (FunctionCode, runtime.FunctionSpec, set()),
    (ExceptionCode, runtime.ExceptionSpec, set()),
    (CommError, runtime.CommErrorSpec, set()),
    (PolicyCase, runtime.PolicySpec, set()),
    (Model, runtime.DeviceSpec, {"device", "protocol", "registers", "reserved", "identity", "enums"}),
    (Device, runtime.ProductSpec, set()),
    (Protocol, runtime.ProtocolSpec,
     {"function_codes", "exceptions", "comm_errors", "exception_policy", "comm_error_policy", "timing",
      "running_state", "reply_quirks", "alignment"}),
    (RunningState, runtime.RunningStateSpec, set()),
    (ReplyQuirk, runtime.ReplyQuirkSpec, set()),
]


@pytest.mark.parametrize(("node", "base", "again"), NODES, ids=lambda x: getattr(x, "__name__", ""))
def test_model_node_extends_its_runtime_class_and_declares_no_runtime_fact_again(
        node: type, base: type, again: set[str]) -> None:
    assert issubclass(node, base)
    runtime_fields = {f.name for f in dataclasses.fields(base)}
    assert set(node.__dict__.get("__annotations__", {})) & runtime_fields == again


def test_page_is_the_runtime_class() -> None:
    assert Page is runtime.PageSpec


def _nodes(value: Any) -> list[Any]:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return [value, *(n for f in dataclasses.fields(value) for n in _nodes(getattr(value, f.name)))]
    if isinstance(value, tuple):
        return [n for v in value for n in _nodes(v)]
    return []


@pytest.mark.parametrize("path", MAPS, ids=lambda p: p.stem)
def test_spec_from_model_holds_only_runtime_classes(path: Path) -> None:
    """The projection drops the model's classes: the spec prints and compares as the runtime's."""
    spec = spec_from_model(compile_map(path))
    nodes = _nodes(spec)
    assert len(nodes) > 10
    assert {type(n).__module__ for n in nodes} == {runtime.__name__}


def test_a_register_is_its_spec_and_its_projection_drops_only_compile_time_facts() -> None:
    model = compile_map(ROOT / "maps" / "ev.yaml")
    spec = spec_from_model(model)
    for reg in model.registers:
        plain = project(reg, RegisterSpec)
        assert type(plain) is RegisterSpec and plain == spec.register(reg.name)
        assert plain != reg  # a model Register carries more (and is another class)
        assert (plain.words, plain.signed) == (reg.words, reg.signed)


def test_runtime_fields_are_derived_from_the_maps_richer_forms() -> None:
    ev = compile_map(ROOT / "maps" / "ev.yaml")
    advised = next(r for r in ev.registers if r.advice is not None)
    assert advised.advice is not None and advised.running_advice == advised.advice.text()
    flagged = next(r for r in ev.registers if r.bits)
    assert flagged.bits_class and all(isinstance(b, Bit) for b in flagged.bits)
    sdm = compile_map(ROOT / "maps" / "sdm630.yaml")
    reg = sdm.register("system_type")
    assert reg.values == tuple((v.value, v.label) for v in reg.value_set) and reg.values
    changed = dataclasses.replace(reg, value_set=(AllowedValue(7, "seven", "a note"),), flags_name="Other")
    assert changed.values == ((7, "seven"),) and changed.bits_class is None  # recomputed; no bits, no class
    with pytest.raises(ValueError, match="init=False"):
        dataclasses.replace(reg, values=((1, None),))


def test_model_numbers_are_the_runtimes() -> None:
    """Whole numbers are ints in the model as in the spec (``max: 100.0`` reads 100)."""
    model = compile_map(ROOT / "maps" / "vfd1000.yaml")
    spec = spec_from_model(model)
    for reg in model.registers:
        for name in ("scale", "offset", "min", "max", "write_delay_ms"):
            value = getattr(reg, name)
            assert value is None or isinstance(value, float) != float(value).is_integer()
            assert repr(value) == repr(getattr(spec.register(reg.name), name))


def test_the_device_record_is_one_shape() -> None:
    """The model is the runtime's DeviceSpec: what the runtime reads of the protocol is the model's
    own protocol fields (serial defaults and fixed unit ids taken from the ports when the model is built)."""
    model = compile_map(ROOT / "maps" / "ev.yaml")
    spec = spec_from_model(model)
    assert isinstance(model, runtime.DeviceSpec) and type(spec) is runtime.DeviceSpec
    assert spec.device == runtime.ProductSpec("ev", model.device.title) and spec.name == model.name == "ev"
    assert type(spec.protocol) is runtime.ProtocolSpec
    assert spec.protocol == project(model.protocol, runtime.ProtocolSpec)
    assert model.protocol.fixed_units == spec.protocol.fixed_units == (17,)  # the RS-232 port's fixed id
    assert model.protocol.serial == spec.protocol.serial and spec.protocol.serial.parity == "none"
    assert spec.protocol.configuration == runtime.CommandSpec("configuration", 1)
    assert spec.protocol.running_state == runtime.RunningStateSpec("motor_state", (2,))
    assert model.protocol.valid_unit(17) and not model.protocol.valid_unit(0)  # the runtime's rule, on the model


def test_the_flat_names_of_earlier_releases_warn_and_still_answer() -> None:
    """Users' code that read ``SPEC.timing`` or ``SPEC.model`` keeps working, with a DeprecationWarning."""
    import copy
    import pickle

    spec = spec_from_model(compile_map(ROOT / "maps" / "vfd1000.yaml"))
    with pytest.warns(DeprecationWarning, match=r"DeviceSpec\.timing is now DeviceSpec\.protocol\.timing"):
        assert spec.timing is spec.protocol.timing  # type: ignore[attr-defined]
    with pytest.warns(DeprecationWarning, match="device"):
        assert spec.model == "vfd1000"  # type: ignore[attr-defined]
    with pytest.warns(DeprecationWarning):
        assert spec.policy("illegal_address") == spec.protocol.policy("illegal_address")  # type: ignore[attr-defined]
    with pytest.raises(AttributeError, match="no_such_field"):
        spec.no_such_field  # type: ignore[attr-defined]  # noqa: B018
    assert pickle.loads(pickle.dumps(spec)) == spec == copy.deepcopy(spec)


@pytest.mark.parametrize("model", ["ev", "vfd1000"])
def test_a_spec_py_written_by_an_earlier_release_still_imports_and_equals_todays(model: str) -> None:
    """Users commit generated packages: a ``spec.py`` printed in the flat form (kept as written by the
    release before the split, tests/fixtures/spec_v1) builds the same DeviceSpec, with a DeprecationWarning."""
    import importlib.util

    path = ROOT / "tests" / "fixtures" / "spec_v1" / f"{model}_spec.py"
    assert "    unit_min=" in path.read_text(encoding="utf-8")  # the flat form
    loader = importlib.util.spec_from_file_location(f"_old_spec_{model}", path)
    assert loader is not None and loader.loader is not None
    module = importlib.util.module_from_spec(loader)
    with pytest.warns(DeprecationWarning, match="earlier release"):
        loader.loader.exec_module(module)
    today = spec_from_model(compile_map(ROOT / "maps" / f"{model}.yaml"))
    # review: (what the map's source leaves open) came later: the earlier release printed none
    today = dataclasses.replace(today, registers=tuple(dataclasses.replace(r, review=()) for r in today.registers))
    assert module.SPEC == today


def test_the_json_export_says_what_the_map_says_of_the_protocol_not_the_runtimes_derived_facts() -> None:
    """The model's protocol also holds the runtime's serial defaults and fixed unit ids (derived from the
    ports); the export contract is the map's protocol (its unit_ids as unit_min/unit_max/unit_source)."""
    import json

    from drivemap.backends.export import export

    schema = json.loads((ROOT / "schemas" / "drivemap.schema.json").read_text(encoding="utf-8"))
    map_keys = set(schema["properties"]["protocol"]["properties"]) - {"unit_ids"}
    for path in MAPS:
        keys = list(export(compile_map(path))["protocol"])
        assert set(keys) == map_keys | {"unit_min", "unit_max", "unit_source"}, path.stem
        assert keys[:3] == ["modes", "unit_min", "unit_max"]


def test_a_replaced_model_looks_up_its_own_registers() -> None:
    """The model's register index is the runtime's, built on first use: ``dataclasses.replace`` gives a
    model that finds its new registers and not the old ones."""
    model = compile_map(ROOT / "maps" / "ev.yaml")
    first = next(r for r in model.registers if not r.is_array)
    assert model.register(first.name) is first
    renamed = dataclasses.replace(first, name="renamed_register")
    other = dataclasses.replace(model, registers=tuple(renamed if r is first else r for r in model.registers))
    assert other.register("renamed_register") is renamed and other.cell("renamed_register").register is renamed
    with pytest.raises(KeyError):
        other.register(first.name)
