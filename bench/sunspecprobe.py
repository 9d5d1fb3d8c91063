"""SunSpec probe recovery: `drivemap probe --sunspec` against the Fronius simulator, compared with the
proven map maps/fronius_symo_hybrid.yaml.

The generated Fronius simulator is served on 127.0.0.1 (an ephemeral port) in this process. The shipped
map gives no values for the SunSpec marker, the model IDs and the model lengths (it reads 0 there), so
they are preset to the values the map's labels name ("SunS"; models 1, 103, 120, 121, 122, 123, 160, 124,
each L up to the next model's ID; the end model 0xFFFF, L 0). Then the verb runs in a subprocess
(`python -m drivemap probe --tcp HOST:PORT --sunspec -o FILE`) and the map it writes is compiled and
compared with the proven map, element address by element address:

* **cells recovered**: a proven register element the probe's map has at the same holding address with the
  same type, width (words) and scale-factor register (address of its `scale_register`);
* **registers recovered**: a proven register whose every element is recovered;
* the other fields (access, unit, not-available values, static scale) are compared cell by cell and every
  difference is listed with both values: the probe's map takes them from the SunSpec models, the proven
  map from Fronius' documents.

    python bench/sunspecprobe.py
"""

from __future__ import annotations

import importlib
import importlib.util
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import ROOT, Row, Section, print_section  # noqa: E402

TITLE = "SunSpec probe recovery"
MODEL = "fronius_symo_hybrid"
# model ID of each SunSpec block of the map (named by its registers' labels: "A well-known value 120" ...)
SUNSPEC_IDS = {"common": 1, "inverter": 103, "nameplate": 120, "settings": 121, "status": 122, "controls": 123,
               "mppt": 160, "storage": 124}
KEY = ("type", "words", "scale register")
OTHER = ("access", "unit", "not available", "scale")


def chain_values(registers: Any) -> dict[str, int]:
    """The SunSpec marker, each model's ID and L (to the next model's ID) and the end model."""
    address = {r.name: r.address for r in registers}
    order = sorted(SUNSPEC_IDS, key=lambda g: address[f"{g}_model_id"])
    values = {"sunspec_id": 0x53756E53, "end_block_id": 0xFFFF, "end_block_length": 0}
    for i, group in enumerate(order):
        after = address[f"{order[i + 1]}_model_id"] if i + 1 < len(order) else address["end_block_id"]
        values[f"{group}_model_id"] = SUNSPEC_IDS[group]
        values[f"{group}_model_length"] = after - address[f"{group}_model_id"] - 2
    return values


def facts(model: Any) -> dict[tuple[str, int], dict[str, Any]]:
    """(table, element address) -> the facts compared, for every register element of ``model``."""
    out = {}
    for reg in model.registers:
        scale_at = model.register(reg.scale_register).address if reg.scale_register else None
        for i in range(reg.count):
            out[(reg.table, reg.element_address(i))] = {
                "name": reg.element_name(i) if reg.count > 1 else reg.name, "register": reg.name, "type": reg.type,
                "words": reg.words, "scale register": scale_at, "access": reg.access, "unit": reg.unit,
                "not available": tuple(reg.not_available), "scale": float(reg.scale)}
    return out


def probe(out: Path) -> tuple[subprocess.CompletedProcess[str], float, Counter[int]]:
    """The Fronius simulator on 127.0.0.1 and the probe verb against it: (process, seconds, function codes)."""
    from drivemap.runtime.sim.serve import ThreadedSimServer

    sim = importlib.import_module(f"drivemap_models.{MODEL}.simulator").Simulator(units=[1])
    for name, raw in chain_values(sim.spec.registers).items():
        sim.set_raw(name, raw)
    codes: Counter[int] = Counter()
    handle = sim.handle

    def recording(unit: int, pdu: bytes, **kw: Any) -> Any:
        codes[pdu[0]] += 1
        return handle(unit, pdu, **kw)

    sim.handle = recording
    with ThreadedSimServer(sim, tcp=("127.0.0.1", 0)) as server:
        assert server.address is not None
        host, port = server.address
        started = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "drivemap", "probe", "--tcp", f"{host}:{port}", "--sunspec",
                               "--rate", "100000", "-o", str(out)], capture_output=True, text=True, timeout=300, cwd=ROOT)
        seconds = time.perf_counter() - started
    return proc, seconds, codes


def _pairs(diffs: list[tuple[str, Any, Any]], limit: int = 6) -> str:
    """Differences grouped by (probed, proven) value, with a few names each."""
    groups: dict[tuple[str, str], list[str]] = {}
    for name, mine, theirs in diffs:
        groups.setdefault((repr(mine), repr(theirs)), []).append(name)
    parts = []
    for (mine, theirs), names in sorted(groups.items(), key=lambda kv: -len(kv[1])):
        more = f", … {len(names) - limit} more" if len(names) > limit else ""
        parts.append(f"probed {mine}, proven {theirs}: {len(names)} ({', '.join(names[:limit])}{more})")
    return "; ".join(parts)


def compare(proven: dict[tuple[str, int], dict[str, Any]], probed: dict[tuple[str, int], dict[str, Any]],
            base: int) -> dict[str, Any]:
    """Cells and registers recovered, what is missed (and where), the other fields' differences."""
    sunspec = {k: v for k, v in proven.items() if k[0] == "holding" and k[1] >= base}
    same = {k for k in sunspec if k in probed and all(probed[k][f] == sunspec[k][f] for f in KEY)}
    by_register: dict[str, list[tuple[str, int]]] = {}
    for k, v in proven.items():
        by_register.setdefault(v["register"], []).append(k)
    other: dict[str, list[tuple[str, Any, Any]]] = {f: [] for f in (*KEY, *OTHER)}
    for k, v in sunspec.items():
        if k in probed:
            for f in other:
                if probed[k][f] != v[f]:
                    other[f].append((v["name"], probed[k][f], v[f]))
    return {
        "proven": len(proven), "sunspec": len(sunspec), "same": len(same),
        "registers": len(by_register), "registers_same": sum(all(k in same for k in ks) for ks in by_register.values()),
        "outside": sorted(v["name"] for k, v in proven.items() if k not in sunspec),
        "absent": sorted(sunspec[k]["name"] for k in sunspec if k not in probed),
        "extra": sorted(probed[k]["name"] for k in probed if k not in proven), "differ": other,
    }


def _rows(section: Section, r: dict[str, Any], seconds: float, codes: Counter[int]) -> None:
    section.rows.append(Row(TITLE, "SunSpec cells recovered (address, type, width, scale register)",
                            r["same"] / r["sunspec"], "—", None,
                            f"{r['same']}/{r['sunspec']} cells at and above the SunSpec base; {len(r['extra'])} extra"))
    section.rows.append(Row(TITLE, "proven map: registers recovered", r["registers_same"] / r["registers"], "—", None,
                            f"{r['registers_same']}/{r['registers']}; {len(r['outside'])} of the proven cells lie outside "
                            "the SunSpec models (the walk reads the model chain only)"))
    reads = sum(codes.values())
    section.rows.append(Row(TITLE, "reads only (function code 03h)", None, "0 other codes", set(codes) <= {3},
                            f"{reads} reads in {seconds:.2f} s (probe verb, subprocess); codes "
                            f"{', '.join(f'{c:02X}h x{n}' for c, n in sorted(codes.items()))}"))


def _detail(r: dict[str, Any], proc: subprocess.CompletedProcess[str], written: Path) -> list[str]:
    out = ["The probe's own summary (its output file shown as FILE):", "", "```",
           proc.stdout.strip().replace(str(written), "FILE"), "```", "",
           "| measure | count | of | what |", "|---|---:|---:|---|",
           f"| SunSpec cells recovered | {r['same']} | {r['sunspec']} | address, type, width and scale register as proven |",
           f"| proven registers recovered | {r['registers_same']} | {r['registers']} | every element recovered |",
           f"| proven cells outside the walk | {len(r['outside'])} | {r['proven']} | "
           f"{', '.join(r['outside']) or '-'} (below the SunSpec base: not in a SunSpec model) |",
           f"| SunSpec cells not in the probe's map | {len(r['absent'])} | {r['sunspec']} | {', '.join(r['absent']) or '-'} |",
           f"| probed cells the proven map does not have | {len(r['extra'])} | - | {', '.join(r['extra']) or '-'} |"]
    out += ["", "Fields that differ on the cells both maps have (the probe's map takes them from the SunSpec "
            "models, the proven map from Fronius' documents):", ""]
    out += [f"* **{f}** ({len(d)}): {_pairs(d)}" if d else f"* **{f}**: none" for f, d in r["differ"].items()]
    return out


def run(quick: bool = False) -> Section:
    from drivemap.compiler import compile_map

    section = Section(TITLE)
    with tempfile.TemporaryDirectory(prefix="drivemap-sunspec-") as tmp:
        out = Path(tmp) / f"{MODEL}_probed.yaml"
        proc, seconds, codes = probe(out)
        if proc.returncode != 0 or not out.is_file():
            section.error = f"drivemap probe --sunspec exited {proc.returncode}: {proc.stderr.strip() or proc.stdout.strip()}"
            return section
        probed = facts(compile_map(out))
    proven = facts(compile_map(ROOT / "maps" / f"{MODEL}.yaml"))
    base = min(a for t, a in probed)
    r = compare(proven, probed, base)
    _rows(section, r, seconds, codes)
    section.detail = _detail(r, proc, out)
    if importlib.util.find_spec("sunspec2") is None:
        section.detail.append("\npysunspec2 is not installed (`pip install 'drivemap[sunspec]'`): the probe wrote each "
                              "model as its ID, L and raw words, so names, types and scale registers are not recovered.")
    return section


def main() -> int:
    return print_section(run())


if __name__ == "__main__":
    sys.exit(main())
