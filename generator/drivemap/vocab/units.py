"""Units and device classes as Home Assistant and ESPHome name them, and how many decimals a scaled
value shows: the exporters (homeassistant, esphome) and the gateway's MQTT discovery share them."""

from __future__ import annotations

from decimal import Decimal

__all__ = ["DEVICE_CLASSES", "DEVICE_CLASS_SINCE", "UNIT_SPELLING", "decimals", "device_class_known", "unit_for"]

#: Device classes and the first Home Assistant release that has them (older ones reject the entity).
DEVICE_CLASS_SINCE: dict[str, tuple[int, int]] = {"reactive_energy": (2025, 6)}


def device_class_known(device_class: str, version: tuple[int, int] | None) -> bool:
    """Whether Home Assistant ``version`` (None: the current release) has ``device_class``."""
    return version is None or version >= DEVICE_CLASS_SINCE.get(device_class, (0, 0))


#: unit -> (device_class, state_class) where the unit says it (Home Assistant and ESPHome share the names).
DEVICE_CLASSES: dict[str, tuple[str | None, str | None]] = {
    "V": ("voltage", "measurement"),
    "mV": ("voltage", "measurement"),
    "A": ("current", "measurement"),
    "mA": ("current", "measurement"),
    "W": ("power", "measurement"),
    "kW": ("power", "measurement"),
    "VA": ("apparent_power", "measurement"),
    "kVA": ("apparent_power", "measurement"),
    "var": ("reactive_power", "measurement"),
    "kvar": ("reactive_power", "measurement"),
    "varh": ("reactive_energy", "total_increasing"),
    "kvarh": ("reactive_energy", "total_increasing"),
    "VAh": (None, "total_increasing"),  # no apparent-energy device class (Home Assistant, ESPHome)
    "kVAh": (None, "total_increasing"),
    "rpm": (None, "measurement"),
    "Wh": ("energy", "total_increasing"),
    "kWh": ("energy", "total_increasing"),
    "Hz": ("frequency", "measurement"),
    "°C": ("temperature", "measurement"),
    "%": (None, "measurement"),
    "s": ("duration", "measurement"),
    "ms": ("duration", "measurement"),
    "min": ("duration", "measurement"),
    "h": ("duration", "measurement"),
}

#: A map's unit -> the spelling Home Assistant and ESPHome use (their device classes accept only it).
UNIT_SPELLING: dict[str, str] = {"r/min": "rpm", "RPM": "rpm", "VAr": "var", "kVAr": "kvar", "VAr h": "varh",
                                 "VArh": "varh", "kVArh": "kvarh", "℃": "°C", "degC": "°C"}


def unit_for(unit: str) -> str:
    """The unit as Home Assistant and ESPHome spell it (``r/min`` -> ``rpm``, ``VAr`` -> ``var``)."""
    return UNIT_SPELLING.get(unit, unit)


def decimals(*numbers: float) -> int:
    """Decimal places needed to show values of ``raw * scale + offset`` (0.01 -> 2)."""
    places = 0
    for n in numbers:
        exponent = Decimal(repr(float(n))).normalize().as_tuple().exponent
        if isinstance(exponent, int) and exponent < 0:
            places = max(places, -exponent)
    return places
