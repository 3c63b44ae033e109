"""GEM's composite of heavy-duty cycles: weights per vehicle type and g CO2/ton-mile.

EPA's GEM (40 CFR 1037.510(c), 1037.705(b)) rates a truck by the weighted average of its CO2
per mile over a transient and two cruise cycles, divided by the regulatory payload of its
class. The weights and payloads are data (``models/heavy_duty/gem_cycles.toml``); the same
weights, read as shares of miles, are a ``cycle_mix`` (:func:`gem_cycle_mix`).

Phase 2 vocational vehicles also idle: GEM adds a drive-idle cycle (engine at idle speed in
gear, the vehicle held still: an automatic's torque converter loads the engine) and a
parked-idle cycle (neutral), weighted by shares of operating time (:func:`idle_shares`) and
turned into fuel per mile with the table's average speed of the non-idle cycles
(:func:`idle_gallons_per_mile`). The idle fuel rates come from the row's own engine
(:func:`idle_fuel_rates_g_per_s`).
"""
from __future__ import annotations

import numpy as np

from fleetrun.errors import unknown_name_error
from fleetrun.physics.fuels import fuel_properties
from fleetrun.resources import model_file
from fleetrun.simulation.core import engine_fuel_rate_g_per_s, idle_fuel_rate_g_per_s
from fleetrun.simulation.engine import full_load_torque_Nm
from fleetrun.simulation.params import VehicleArrays

GEM_FILE = "heavy_duty/gem_cycles.toml"
PARTS = ("transient", "cruise_55", "cruise_65")


def gem_cycle_mix(vehicle_type: str) -> dict[str, float]:
    """{cycle name: share} of GEM's weighting for ``vehicle_type`` (a key of the file's
    ``weights``, e.g. ``sleeper_cab``); cycles of zero weight left out.

    Parameters
    ----------
    vehicle_type : str, a key of ``weights`` in ``models/heavy_duty/gem_cycles.toml``

    Returns
    -------
    dict of float, {cycle name: weight [-]} (40 CFR 1037.510(c)); an unknown type raises the
    registry's unknown-name error.
    """
    data = model_file(GEM_FILE)
    if vehicle_type not in data["weights"]:
        raise unknown_name_error("GEM vehicle type", vehicle_type, tuple(data["weights"]))
    weights = data["weights"][vehicle_type]
    return {data[part]: float(weights[part]) for part in PARTS if weights[part] > 0}


def payload_short_tons(regulatory_class: str) -> float:
    """The regulatory payload [short tons] of ``regulatory_class`` (40 CFR 1037.705(b)).

    Parameters
    ----------
    regulatory_class : str, a key of ``payload_short_tons`` in ``models/heavy_duty/gem_cycles.toml``

    Returns
    -------
    float, regulatory payload [short tons].
    """
    payloads = model_file(GEM_FILE)["payload_short_tons"]
    if regulatory_class not in payloads:
        raise unknown_name_error("regulatory class", regulatory_class, tuple(payloads))
    return float(payloads[regulatory_class])


def composite_g_co2_per_ton_mile(gallons_per_mile: dict[str, float], mix: dict[str, float], payload_tons: float,
                                 fuel: str = "diesel", idle_gal_per_mile: float = 0.0) -> float:
    """(sum(w_c x gal/mi_c) + idle gal/mi) x CO2 per gallon / payload [g CO2/ton-mile]
    (40 CFR 1037.510(c)).

    Parameters
    ----------
    gallons_per_mile : dict of float, fuel per mile [gal/mi] of each cycle of ``mix``.
    mix : dict of float, {cycle: weight [-]} (:func:`gem_cycle_mix`).
    payload_tons : float, regulatory payload [short tons] (:func:`payload_short_tons`).
    fuel : str, ``diesel`` or ``gasoline``: its CO2 per gallon (models/fuels.toml).
    idle_gal_per_mile : float or array, the idle cycles' fuel per mile driven [gal/mi]
        (:func:`idle_gallons_per_mile`; 0 for tractors).

    Returns
    -------
    composite CO2 [g CO2/ton-mile] (an array if ``idle_gal_per_mile`` or the per-cycle values are).
    """
    per_mile = sum(w * gallons_per_mile[c] for c, w in mix.items()) + idle_gal_per_mile
    return per_mile * fuel_properties(fuel).co2_g_per_gal / payload_tons


def idle_shares(vehicle_type: str) -> tuple[float, float, float]:
    """(drive idle, parked idle, average non-idle speed [mph]) of ``vehicle_type``: shares of
    operating time of GEM's idle cycles (gem_cycles.toml ``idle``); (0, 0, nan) for a type
    without idle (tractors).

    Parameters
    ----------
    vehicle_type : str, a key of ``weights`` in ``models/heavy_duty/gem_cycles.toml``

    Returns
    -------
    (drive idle share [-], parked idle share [-], average non-idle speed [mph]).
    """
    idle = model_file(GEM_FILE).get("idle", {}).get(vehicle_type)
    if idle is None:
        gem_cycle_mix(vehicle_type)      # an unknown type is an error, not a type without idle
        return 0.0, 0.0, float("nan")
    return float(idle["drive_idle"]), float(idle["parked_idle"]), float(idle["nonidle_speed_mph"])


def idle_gallons_per_mile(drive_idle_gal_per_h, parked_idle_gal_per_h, drive_share: float, parked_share: float,
                          nonidle_speed_mph: float):
    """Idle fuel per mile driven [gal/mi]: the idle cycles' fuel per hour of operation,
    (s_d g_d + s_p g_p), over the miles of that hour, (1 - s_d - s_p) v (the shares s are of
    operating time, the rest of it is spent on the non-idle cycles at their average speed v).

    Parameters
    ----------
    drive_idle_gal_per_h, parked_idle_gal_per_h : float or array, idle fuel rates [gal/h].
    drive_share, parked_share : float, shares of operating time [-] (:func:`idle_shares`).
    nonidle_speed_mph : float, average speed of the non-idle cycles [mph].

    Returns
    -------
    idle fuel per mile driven [gal/mi], an array of the shape of the rates (zeros without idle).
    """
    if drive_share == 0.0 and parked_share == 0.0:
        return np.zeros_like(np.asarray(drive_idle_gal_per_h, float))
    per_hour = drive_share * np.asarray(drive_idle_gal_per_h, float) + parked_share * np.asarray(
        parked_idle_gal_per_h, float)
    return per_hour / ((1.0 - drive_share - parked_share) * nonidle_speed_mph)


def idle_fuel_rates_g_per_s(va: VehicleArrays) -> tuple[np.ndarray, np.ndarray]:
    """(drive idle, parked idle) fuel rates [g/s] of each vehicle: the fuel equation at idle
    speed with, in drive, the torque the stalled converter's pump absorbs, (n_idle / K)^2
    (transmission.py's converter; a clutch is open, so manual and automated-manual
    gearboxes idle in drive as in neutral), and, parked, the standstill idle of the
    simulation (no load beyond the accessories).

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters (``fleetrun.simulation.params``; engine
        speeds n_idle in [rpm], converter capacity factor K_tc in [rpm / (N m)^0.5])

    Returns
    -------
    (drive idle, parked idle) fuel rates [g/s], arrays of shape (V,).
    """
    parked = idle_fuel_rate_g_per_s(va)
    pump_Nm = np.where(va.automatic, (va.n_idle / va.K_tc) ** 2, 0.0)
    t_max = full_load_torque_Nm(va.n_idle, va.T_peak, va.P_rated_kW, va.n_rated, va.n_idle, va.n_peak_torque,
                                va.idle_T_frac)
    drive = np.where(va.automatic, engine_fuel_rate_g_per_s(va, pump_Nm, va.n_idle, t_max, True), parked)
    return drive, parked
