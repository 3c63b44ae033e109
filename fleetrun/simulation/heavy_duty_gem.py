"""GEM's composite of heavy-duty cycles: weights per vehicle type and g CO2/ton-mile.

EPA's GEM (40 CFR 1037.510(c), 1037.705(b)) rates a truck by the weighted average of its CO2
per mile over a transient and two cruise cycles, divided by the regulatory payload of its
class. The weights and payloads are data (``models/heavy_duty/gem_cycles.toml``); the same
weights, read as shares of miles, are a ``cycle_mix`` (:func:`gem_cycle_mix`).
"""
from __future__ import annotations

from fleetrun.errors import unknown_name_error
from fleetrun.physics.fuels import fuel_properties
from fleetrun.resources import model_file

GEM_FILE = "heavy_duty/gem_cycles.toml"
PARTS = ("transient", "cruise_55", "cruise_65")


def gem_cycle_mix(vehicle_type: str) -> dict[str, float]:
    """{cycle name: share} of GEM's weighting for ``vehicle_type`` (a key of the file's
    ``weights``, e.g. ``sleeper_cab``); cycles of zero weight left out."""
    data = model_file(GEM_FILE)
    if vehicle_type not in data["weights"]:
        raise unknown_name_error("GEM vehicle type", vehicle_type, tuple(data["weights"]))
    weights = data["weights"][vehicle_type]
    return {data[part]: float(weights[part]) for part in PARTS if weights[part] > 0}


def payload_short_tons(regulatory_class: str) -> float:
    """The regulatory payload [short tons] of ``regulatory_class`` (40 CFR 1037.705(b))."""
    payloads = model_file(GEM_FILE)["payload_short_tons"]
    if regulatory_class not in payloads:
        raise unknown_name_error("regulatory class", regulatory_class, tuple(payloads))
    return float(payloads[regulatory_class])


def composite_g_co2_per_ton_mile(gallons_per_mile: dict[str, float], mix: dict[str, float], payload_tons: float,
                                 fuel: str = "diesel") -> float:
    """sum(w_c x gal/mi_c) x CO2 per gallon / payload [g CO2/ton-mile] (40 CFR 1037.510(c)).

    Parameters
    ----------
    gallons_per_mile : fuel per mile [gal/mi] of each cycle of ``mix``.
    mix : {cycle: weight} (:func:`gem_cycle_mix`).
    payload_tons : regulatory payload [short tons].
    """
    per_mile = sum(w * gallons_per_mile[c] for c, w in mix.items())
    return per_mile * fuel_properties(fuel).co2_g_per_gal / payload_tons
