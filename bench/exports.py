"""(6) Exports: entities and Modbus requests per poll cycle of each export, beside drivemap's plan.

Per map (default page, every group), counted from the exported files themselves:

* **targets** — the readable register elements the integration exports (the same set for both);
* **drivemap plan** — ``len(plan_reads(spec, targets))``: the reads drivemap's client sends;
* **Home Assistant** — entities (modbus sensors, virtual sensors of ``virtual_count``, switches,
  template sensors and binary sensors) and reads per poll cycle: every modbus sensor entry polls
  on its own (one read; a ``virtual_count`` array is one read), switches without ``verify`` and
  templates read nothing;
* **ESPHome** — entities (internal fillers not counted) and reads per full update: the ranges
  ESPHome's own range builder makes from the file (ported in ``tests/esphome_ranges.py``);
* **naive** — one read per element.
"""

from __future__ import annotations

from typing import Any

from common import ROOT, Row, Section

from drivemap.backends.exporters.base import Options
from drivemap.backends.exporters.esphome import REUSE_RANGES, EsphomeExporter, esphome_version
from drivemap.backends.exporters.homeassistant import HomeAssistantExporter
from drivemap.compiler import load_model
from drivemap.model.spec import spec_from_model
from drivemap.runtime.client.protocol.planner import plan_reads
from tests import esphome_ranges as esp
from tests.exporter_helpers import SERIAL  # what the maps leave open on their serial line


def _yaml(text: str) -> Any:
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    Loader.add_constructor("!secret", lambda loader, node: loader.construct_scalar(node))
    Loader.add_constructor("!literal", lambda loader, node: loader.construct_mapping(node)
                           if isinstance(node, yaml.MappingNode) else loader.construct_scalar(node))
    return yaml.load(text, Loader=Loader)  # noqa: S506 - a SafeLoader subclass


def homeassistant(model: Any) -> tuple[int, int]:
    text = next(iter(HomeAssistantExporter().render(model, Options(root=ROOT, values=SERIAL.get(model.name, {}))).values()))
    doc = _yaml(text)
    hub = doc["modbus"][0]
    sensors = hub.get("sensors", [])
    entities = sum(1 + s.get("virtual_count", 0) for s in sensors) + len(hub.get("switches", []))
    entities += sum(len(block.get("sensor", [])) + len(block.get("binary_sensor", [])) for block in doc.get("template", []))
    return entities, len(sensors)


def esphome(model: Any) -> tuple[int, int, int]:
    values = {k: v for k, v in SERIAL.get(model.name, {}).items() if k != "method"}
    text = next(iter(EsphomeExporter().render(model, Options(root=ROOT, values=values)).values()))
    doc = _yaml(text)
    entities = sum(1 for p in ("sensor", "binary_sensor", "text_sensor", "number", "select", "switch")
                   for e in doc.get(p) or () if not e.get("internal"))
    items = esp.items_of(doc)
    words = {i.word for i in items if not i.name.startswith("gap_")}
    # the export is written for the newest ESPHome (EsphomeExporter's default): its range builder counts
    return entities, len(esp.update_ranges(doc, reuse=esphome_version(None) >= REUSE_RANGES)), len(words)


def targets(model: Any) -> list[tuple[str, int]]:
    out = []
    for reg in model.registers:
        if not reg.readable or reg.command_value is not None:
            continue
        if reg.page is not None:
            selector = model.register(reg.page.selector)
            shown = sorted({r.page.value for r in model.registers if r.page and r.page.selector == reg.page.selector})
            default = selector.default_at(0)
            page = int(default) if default is not None and int(default) in shown else shown[0]
            if reg.page.value != page:
                continue
        out.extend((reg.name, i) for i in range(reg.count))
    return out


def run(quick: bool) -> Section:
    sec = Section("Exports (entities and reads per poll cycle)")
    sec.detail.append("| model | targets | drivemap plan | Home Assistant entities | Home Assistant reads "
                      "| ESPHome entities | ESPHome reads | naive | HA / drivemap | ESPHome / drivemap |")
    sec.detail.append("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name in sorted(p.stem for p in (ROOT / "maps").glob("*.yaml")):  # every map, the seeds and the new devices
        model = load_model(name)
        keys = targets(model)
        plan = len(plan_reads(spec_from_model(model), keys))
        ha_entities, ha_reads = homeassistant(model)
        esp_entities, esp_reads, _ = esphome(model)
        sec.detail.append(f"| {name} | {len(keys)} | {plan} | {ha_entities} | {ha_reads} | {esp_entities} | {esp_reads} "
                          f"| {len(keys)} | {ha_reads / plan:.2f}× | {esp_reads / plan:.2f}× |")
        sec.rows.append(Row("6 exports", f"{name}: ESPHome reads / drivemap plan", esp_reads / plan, "= 1.00",
                            esp_reads == plan, f"{esp_reads} vs {plan} reads per update ({esp_entities} entities)"))
        sec.rows.append(Row("6 exports", f"{name}: Home Assistant reads / drivemap plan", ha_reads / plan, "info", None,
                            f"{ha_reads} vs {plan} reads per poll cycle ({ha_entities} entities)"))
    return sec


if __name__ == "__main__":
    s = run(False)
    print("\n".join(s.detail))
    for r in s.rows:
        print(r)
