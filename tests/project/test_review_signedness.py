"""``review: [signedness]``: an integer register whose width the source states but not whether it is signed.

The map's type is the unsigned reading. A write whose raw value means the same signed and unsigned
(0 to 2**(bits-1) - 1) goes out; one that would mean something else either way is refused before anything
is sent (``OpenForReview`` naming signedness and the raw value); the gateway's number entity offers only
the values that read the same both ways.
"""

from __future__ import annotations

import pytest

from drivemap.compiler import compile_map
from drivemap.model.spec import spec_from_model
from drivemap.runtime.errors import OpenForReview
from drivemap.runtime.package import load_package
from drivemap.runtime.sim.simulator import Simulator
from drivemap.testing.loopback import loopback_bus
from tests.badmaps import ROOT


def _edx() -> tuple[object, object]:
    model = compile_map(ROOT / "maps" / "edx.yaml")
    return model, load_package(spec_from_model(model))


def test_the_shipped_edx_map_leaves_signedness_open_where_its_manual_does() -> None:
    model, _ = _edx()
    reg = model.register("frequency_command")
    assert reg.review == ("signedness",) and reg.open_for_writes == ()
    assert reg.sign_ambiguous(32768) and reg.sign_ambiguous(65535) and not reg.sign_ambiguous(32767)
    assert not reg.sign_ambiguous(0)


def test_a_sign_neutral_write_goes_out_and_an_ambiguous_one_is_refused() -> None:
    model, pkg = _edx()
    sim = Simulator(spec_from_model(model), [1])
    reg = model.register("frequency_command")  # scale 0.01 Hz
    with loopback_bus(sim) as bus:
        drive = pkg.Client(bus, unit=1)
        accessor = getattr(drive, reg.name)
        accessor.write(12.34)
        assert sim.unit(1).raw(reg.name) == 1234
        sent = bus.stats.transactions
        with pytest.raises(OpenForReview, match=r"raw value 40000 reads differently signed and unsigned") as caught:
            accessor.write(400.0)
        assert caught.value.fields == ("signedness",)
        assert bus.stats.transactions == sent  # nothing sent
        assert sim.unit(1).raw(reg.name) == 1234
        accessor.write_raw(40000)  # raw words given as such (a printed frame's): the caller chose them
        assert sim.unit(1).raw(reg.name) == 40000


def test_the_gateway_offers_only_sign_neutral_values() -> None:
    from drivemap.gateway.discovery import number_bounds

    model, _ = _edx()
    reg = model.register("frequency_command")
    assert number_bounds(reg) == (0, 327.67)  # raw 0..32767 at 0.01 Hz: what reads the same both ways
