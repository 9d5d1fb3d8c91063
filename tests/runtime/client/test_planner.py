"""The read planner is optimal: read_all() uses exactly the lower-bound number of requests.

The lower bound is computed here independently of drivemap.runtime.client.protocol.planner: an exhaustive search
(memoised on the set of covered targets) that always branches on the leftmost uncovered target and
tries every window, in every page context, that can cover it. It shares only the *rules* with the
planner (max quantity, never span an address that is not a readable register or a readable
reserved word, a 32-bit register is never split, a paged register is read only in its page's
context), not the algorithm.
"""

from __future__ import annotations

import functools
from typing import Any

import pytest

from tests.helpers_client import MODELS, TIMEOUT, package, tcp_server

Item = tuple[int, int, object, object]  # (address, words, page, key)


def _max_read(spec) -> int:  # noqa: ANN001
    fc = spec.protocol.function(0x03) or spec.protocol.function(0x04)
    limit = fc.max_quantity or 125
    if spec.protocol.max_frame_bytes:
        limit = min(limit, (spec.protocol.max_frame_bytes - 5) // 2)
    return limit


def _items(spec) -> list[Item]:  # noqa: ANN001
    items: list[Item] = []
    for reg in spec.registers:
        if "r" in reg.access:
            words = 2 if reg.type in ("u32", "s32") else 1
            for i in range(reg.count):
                items.append((reg.address + i * reg.stride, words, reg.page, (reg.name, i)))
    for res in spec.reserved:
        if res.readable is True:
            items.extend((a, 1, res.page, None) for a in range(res.start, res.end + 1))
    return sorted(items, key=lambda it: (it[0], -1 if it[2] is None else it[2].value))


def lower_bound(spec) -> tuple[int, int]:  # noqa: ANN001
    """(minimum number of read requests, naive one-request-per-register count)."""
    limit = _max_read(spec)
    items = _items(spec)
    targets = [it for it in items if it[3] is not None]
    contexts = [None] + sorted({it[2] for it in items if it[2] is not None}, key=lambda p: (p.selector, p.value))

    def line(ctx: object) -> list[Item]:
        return [it for it in items if it[2] is None or it[2] == ctx]

    lines = {id(c): line(c) for c in contexts}

    def window(ctx: object, start: int) -> frozenset[object]:
        ln = lines[id(ctx)]
        first = ln[start]
        covered = {first[3]}
        end = first[0] + first[1]
        for it in ln[start + 1:]:
            if it[0] != end or it[0] + it[1] - first[0] > limit:
                break
            covered.add(it[3])
            end = it[0] + it[1]
        covered.discard(None)
        return frozenset(covered)

    windows = [window(c, s) for c in contexts for s in range(len(lines[id(c)]))]
    order = [t[3] for t in targets]
    by_target: dict[object, list[frozenset[object]]] = {k: [] for k in order}
    for w in windows:
        for k in w:
            by_target[k].append(w)

    @functools.cache
    def best(covered: frozenset[object]) -> int:
        left = next((k for k in order if k not in covered), None)
        if left is None:
            return 0
        return 1 + min(best(covered | w) for w in set(by_target[left]))

    import sys

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10000))
    naive = sum(reg.count for reg in spec.registers if "r" in reg.access)
    return best(frozenset()), naive


@pytest.mark.parametrize("model", MODELS)
def test_plan_matches_lower_bound(model: str) -> None:
    pkg = package(model)
    bound, naive = lower_bound(pkg.SPEC)
    plan = pkg.Client.plan()
    print(f"{model}: read_all plan {len(plan)} requests, lower bound {bound}, naive {naive}")
    assert len(plan) == bound
    assert pkg.Client.plan() is plan  # computed once, cached per client class


@pytest.mark.parametrize("model", MODELS)
def test_plan_respects_rules(model: str) -> None:
    pkg = package(model)
    spec = pkg.SPEC
    limit = _max_read(spec)
    items = _items(spec)
    for req in pkg.Client.plan():
        assert 1 <= req.count <= limit
        spanned = [it for it in items if req.address <= it[0] < req.address + req.count
                   and (it[2] is None or it[2] == req.page)]
        words = set()
        for it in spanned:
            assert it[0] + it[1] <= req.address + req.count, "a 32-bit register is split"
            words.update(range(it[0], it[0] + it[1]))
        assert words == set(range(req.address, req.address + req.count)), "spans an unreadable address"
        for (name, _), _off in req.cells:
            reg = spec.register(name)
            assert reg.page is None or reg.page == req.page


@pytest.mark.parametrize("model", MODELS)
def test_read_all_uses_lower_bound_on_the_wire(model: str) -> None:
    pkg = package(model)
    bound, naive = lower_bound(pkg.SPEC)
    with tcp_server(model) as (_sim, host, port):
        with pkg.Client.tcp(host, port, unit=1, timeout=TIMEOUT, page_policy="switch") as drive:
            snap = drive.read_all()
            reads = drive.stats.by_function.get(0x03, 0) + drive.stats.by_function.get(0x04, 0)
            switches = drive.stats.by_function.get(0x06, 0) + drive.stats.by_function.get(0x10, 0)
    print(f"{model}: read_all sent {reads} read requests (lower bound {bound}, naive {naive}), {switches} page switches")
    assert reads == bound
    for reg in pkg.SPEC.registers:
        if "r" in reg.access:
            assert getattr(snap, reg.name) is not None


def test_subset_plan_is_cached_and_minimal() -> None:
    pkg = package("v2")
    keys = [("status", 0), ("output_current", 0), ("pid_feedback", 0)]
    plan = pkg.Client.plan(keys)
    assert pkg.Client.plan(list(reversed(keys))) is plan
    assert len(plan) == 2  # 0120h alone; 0127h..012Ah in one request


def _spec(registers: list[Any], reserved: tuple[Any, ...] = (), max_quantity: int = 16) -> Any:
    from drivemap.runtime.spec import DeviceSpec, FunctionSpec, ProductSpec, ProtocolSpec, SerialSpec, TimingSpec

    protocol = ProtocolSpec(modes=("rtu",), unit_min=1, unit_max=247, broadcast_address=None, serial=SerialSpec(),
                            function_codes=(FunctionSpec(3, max_quantity, None),), exceptions=(), timing=TimingSpec())
    return DeviceSpec(device=ProductSpec("synthetic", "synthetic"), protocol=protocol, registers=tuple(registers),
                      reserved=reserved)


def test_pages_share_unpaged_neighbours() -> None:
    """Greedy per page would need 3 requests; the exact plan needs 2 (+ the selector)."""
    from drivemap.runtime.client.protocol.planner import plan_reads
    from drivemap.runtime.spec import PageSpec, RegisterSpec

    regs = [RegisterSpec("sel", 100, access="rw"),
            RegisterSpec("common", 0, access="r", count=8),
            RegisterSpec("p0", 8, access="r", count=8, page=PageSpec("sel", 0)),
            RegisterSpec("p1", 8, access="r", count=8, page=PageSpec("sel", 1))]
    spec = _spec(regs)
    keys = [(r.name, i) for r in regs for i in range(r.count)]
    plan = plan_reads(spec, keys)
    assert len(plan) == lower_bound(spec)[0] == 3
    assert {(r.address, r.count, r.page.value if r.page else None) for r in plan if r.page} in (
        {(0, 16, 0), (8, 8, 1)}, {(0, 16, 1), (8, 8, 0)})


#: Random maps the default tier checks; the slow tier checks :data:`ALL_RANDOM_MAPS` (the same first ones).
RANDOM_MAPS = 10
ALL_RANDOM_MAPS = 60


def test_random_maps_match_lower_bound() -> None:
    _random_maps_match_lower_bound(RANDOM_MAPS)


@pytest.mark.slow
def test_all_random_maps_match_lower_bound() -> None:
    _random_maps_match_lower_bound(ALL_RANDOM_MAPS)


def _random_maps_match_lower_bound(trials: int) -> None:
    import random

    from drivemap.runtime.client.protocol.planner import plan_reads
    from drivemap.runtime.spec import PageSpec, RegisterSpec, ReservedSpec

    rng = random.Random(1234)
    for trial in range(trials):
        regs: list[Any] = [RegisterSpec("sel", 500, access="rw")]
        address = 0
        n = 0
        while address < 60:
            kind = rng.random()
            if kind < 0.15:
                address += rng.randint(1, 3)  # a gap
                continue
            words_type = "u32" if rng.random() < 0.2 else "u16"
            access = rng.choice(["r", "r", "rw", "w"])
            if rng.random() < 0.25:
                span = rng.randint(1, 4)
                for page in range(rng.randint(2, 3)):
                    regs.append(RegisterSpec(f"p{n}_{page}", address, type="u16", access=access, count=span,
                                             page=PageSpec("sel", page)))
                address += span
            else:
                regs.append(RegisterSpec(f"r{n}", address, type=words_type, word_order="high_first", access=access))
                address += 2 if words_type == "u32" else 1
            n += 1
        reserved = (ReservedSpec(address + 1, address + 3, True),) if trial % 3 == 0 else ()
        if reserved:
            regs.append(RegisterSpec("tail", address + 4, access="r"))
        spec = _spec(regs, reserved, max_quantity=rng.choice([2, 3, 4, 8, 16]))
        readable = [(r.name, i) for r in regs if "r" in r.access for i in range(r.count)]
        plan = plan_reads(spec, readable)
        covered = sorted(k for req in plan for k, _ in req.cells)
        assert covered == sorted(readable), trial
        assert len(plan) == lower_bound(spec)[0], trial
