"""Heavy-duty diesel engines: the fuel equation's constants for medium- and heavy-duty diesel rows.

The fuel equation is the one of :mod:`fleetrun.simulation.engine` (a Willans line with
Chen-Flynn friction). What differs for trucks is where its constants come from
(``models/heavy_duty/engines.toml``):

- friction, full-load efficiency fall-off, accessory load: heavy-diesel literature values;
- the Willans slope ``eta_indicated``: anchored on EPA's engine CO2 standards. An engine of the
  row's service class (heavy >= 10 L, else medium) and model year that just meets its
  standard emits, over the steady-state SET modes (40 CFR 1036.510), exactly the standard in
  g CO2/hp-hr (40 CFR 1036.108). The fuel equation is linear in 1 / eta_indicated, so the
  slope that does so is found in closed form (:func:`willans_slope_for_standard`).

This is the role of GEM's default engine fuel maps (the maps EPA ran its Phase 2 reference
vehicles with, one per service class and standard year): a map of a compliant engine. Here
the map is the fuel equation; :func:`bsfc_map_g_per_kWh` tabulates it.
"""
from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

import numpy as np

from fleetrun.physics.fuels import fuel_properties
from fleetrun.resources import model_file
from fleetrun.simulation.engine import (fuel_coefficients, fuel_power_terms_W, fuel_rate_g_per_s,
                                        full_load_torque_Nm, stroke_m)
from fleetrun.simulation.records import HeavyDutyFuelConstants, ReferenceEngine
from fleetrun.units import LITERS_PER_GALLON, RAD_S_PER_RPM

ENGINES_FILE = "heavy_duty/engines.toml"
HP_W = 745.699872                 # mechanical horsepower [W] (NIST SP 811)
SET_SPEED_FRACTIONS = {"A": 0.25, "B": 0.50, "C": 0.75}
HEAVY_DUTIES = ("MD", "HD")


def set_speeds_rpm(speed_rpm, power_W) -> dict[str, float]:
    """SET speeds A, B, C [rpm] from a full-load power curve (40 CFR 1065.610).

    n_lo = the lowest speed at which power reaches 50 % of its maximum, n_hi = the highest at
    which it is still 70 %; A, B, C = n_lo + 25 / 50 / 75 % of (n_hi - n_lo).

    Parameters
    ----------
    speed_rpm : array, increasing engine speeds of the full-load curve [rpm]
    power_W : array, full-load power at those speeds [W]

    Returns
    -------
    dict, ``A``, ``B``, ``C`` -> speed [rpm].

    >>> n = np.linspace(600.0, 2000.0, 15)
    >>> {k: float(v) for k, v in set_speeds_rpm(n, np.minimum(100.0 * n, 150000.0)).items()}
    {'A': 1100.0, 'B': 1400.0, 'C': 1700.0}
    """
    n, p = np.asarray(speed_rpm, float), np.asarray(power_W, float)
    p_max = p.max()
    lo = n[np.argmax(p >= 0.5 * p_max)]
    hi = n[len(p) - 1 - np.argmax(p[::-1] >= 0.7 * p_max)]
    return {k: lo + f * (hi - lo) for k, f in SET_SPEED_FRACTIONS.items()}


def _full_load(engine: ReferenceEngine, speed_rpm):
    return full_load_torque_Nm(speed_rpm, engine.peak_torque_Nm, engine.rated_power_kW, engine.rated_speed_rpm,
                               engine.idle_speed_rpm, engine.peak_torque_speed_fraction * engine.rated_speed_rpm,
                               engine.idle_torque_fraction)


def _set_modes() -> tuple[list, np.ndarray, np.ndarray]:
    """The SET modes of engines.toml: speed labels, load fractions, weights."""
    modes = model_file(ENGINES_FILE)["set_modes"]
    return ([m["speed"] for m in modes], np.array([m["load_pct"] for m in modes]) / 100.0,
            np.array([m["weight"] for m in modes]))


def set_points(engine: ReferenceEngine) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Speed [rpm], torque [N m] and weight of each SET mode (engines.toml) for ``engine``.

    Parameters
    ----------
    engine : ReferenceEngine, size and full-load shape

    Returns
    -------
    (speed [rpm], torque [N m], weight [-]), arrays, one entry per SET mode.
    """
    labels, loads, weights = _set_modes()
    n = np.linspace(engine.idle_speed_rpm, 1.1 * engine.rated_speed_rpm, 881)
    speeds = set_speeds_rpm(n, _full_load(engine, n) * n * RAD_S_PER_RPM)
    speeds["idle"] = engine.idle_speed_rpm
    speed = np.array([speeds[label] for label in labels])
    return speed, _full_load(engine, speed) * loads, weights


def co2_g_per_g_fuel(fuel: str = "diesel") -> float:
    """Tailpipe CO2 per gram of fuel, from models/fuels.toml's CO2 per gallon and density.

    Parameters
    ----------
    fuel : str, a fuel of models/fuels.toml

    Returns
    -------
    CO2 per fuel [g/g].

    >>> round(co2_g_per_g_fuel("diesel"), 4)
    3.2015
    """
    props = fuel_properties(fuel)
    return props.co2_g_per_gal / (props.density_kg_per_L * LITERS_PER_GALLON * 1e3)


def _engine_fuel_g_per_s(engine: ReferenceEngine, constants: HeavyDutyFuelConstants, speed_rpm, torque_Nm):
    """Fuel rate [g/s] of ``engine`` on the dynamometer (no accessory load) at speed x torque."""
    disp = engine.displacement_L
    terms = fuel_power_terms_W(torque_Nm, speed_rpm, _full_load(engine, speed_rpm), disp,
                               stroke_m(disp, engine.cylinders), engine.peak_torque_Nm, False)
    coeffs = fuel_coefficients(constants.eta_indicated, constants.high_load_factor, constants.fmep_0_kPa,
                               constants.fmep_piston_speed_kPa_s_per_m, constants.fmep_peak_fraction,
                               constants.pmep_throttle_kPa, 0.0, constants.transient_factor)
    return fuel_rate_g_per_s(terms, coeffs, True, fuel_properties("diesel").lhv_MJ_per_kg)


def set_co2_g_per_hp_hr(constants: HeavyDutyFuelConstants, engine: ReferenceEngine) -> float:
    """Cycle-weighted brake-specific CO2 [g/hp-hr] of ``engine`` over the SET modes:
    sum(w CO2 rate) / sum(w brake power) (40 CFR 1036.510 weighting), no accessory load
    (an engine on the dynamometer drives none).

    Parameters
    ----------
    constants : HeavyDutyFuelConstants, the fuel equation's constants
    engine : ReferenceEngine

    Returns
    -------
    brake-specific CO2 [g/hp-hr].
    """
    speed, torque, weight = set_points(engine)
    fuel = _engine_fuel_g_per_s(engine, constants, speed, torque)
    work_hp_h = float(np.sum(weight * torque * speed * RAD_S_PER_RPM)) / HP_W
    return float(np.sum(weight * fuel)) * 3600.0 * co2_g_per_g_fuel() / work_hp_h


def set_ramped_schedule(engine: ReferenceEngine, step_s: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Speed [rpm] and torque [N m] of ``engine`` over the ramped-modal SET, every ``step_s``:
    the modes of engines.toml in order, each held for its ``set_ramped`` seconds, the final
    idle, and linear ramps of speed and of percent torque (of the full load at the ramp's
    speed) between consecutive modes (40 CFR 1036.510(a); times: 1036.505 Table 1, 2016 text).

    Parameters
    ----------
    engine : ReferenceEngine
    step_s : float, sampling interval [s]

    Returns
    -------
    (speed [rpm], torque [N m]), arrays of one sample per ``step_s`` (sample midpoints).
    """
    labels, loads, _ = _set_modes()
    ramped = model_file(ENGINES_FILE)["set_ramped"]
    speed, _, _ = set_points(engine)
    speeds, fractions = list(speed) + [speed[0]], list(loads) + [loads[0]]
    held = list(ramped["mode_seconds"]) + [ramped["final_idle_seconds"]]
    n_parts, f_parts = [], []
    for k, seconds in enumerate(held):
        t = np.arange(0.5 * step_s, seconds, step_s)
        n_parts.append(np.full(t.size, speeds[k]))
        f_parts.append(np.full(t.size, fractions[k]))
        if k + 1 < len(held):
            s = np.arange(0.5 * step_s, ramped["ramp_seconds"], step_s) / ramped["ramp_seconds"]
            n_parts.append(speeds[k] + s * (speeds[k + 1] - speeds[k]))
            f_parts.append(fractions[k] + s * (fractions[k + 1] - fractions[k]))
    n, f = np.concatenate(n_parts), np.concatenate(f_parts)
    return n, f * _full_load(engine, n)


def set_ramped_co2_g_per_hp_hr(constants: HeavyDutyFuelConstants, engine: ReferenceEngine) -> float:
    """Brake-specific CO2 [g/hp-hr] of ``engine`` over the ramped-modal SET as the test
    computes it: total CO2 mass over total positive work of the interval (40 CFR 1036.510(g),
    1065.650), ramps included, no accessory load. The check of :func:`set_co2_g_per_hp_hr`'s
    modal weighting, which the Willans slope is anchored on.

    Parameters
    ----------
    constants : HeavyDutyFuelConstants
    engine : ReferenceEngine

    Returns
    -------
    brake-specific CO2 [g/hp-hr].
    """
    speed, torque = set_ramped_schedule(engine)
    fuel_g = float(np.sum(_engine_fuel_g_per_s(engine, constants, speed, torque)))
    work_hp_h = float(np.sum(np.maximum(torque, 0.0) * speed * RAD_S_PER_RPM)) / HP_W / 3600.0
    return fuel_g * co2_g_per_g_fuel() / work_hp_h


def willans_slope_for_standard(standard_g_per_hp_hr: float, constants: HeavyDutyFuelConstants,
                               engine: ReferenceEngine) -> float:
    """The eta_indicated at which ``engine`` meets the SET standard exactly. Every term of the
    fuel equation is divided by eta_indicated, so SET CO2 x eta is a constant.

    Parameters
    ----------
    standard_g_per_hp_hr : float, the SET CO2 standard [g/hp-hr]
    constants : HeavyDutyFuelConstants, the other constants (eta_indicated is replaced)
    engine : ReferenceEngine

    Returns
    -------
    eta_indicated [-].
    """
    return set_co2_g_per_hp_hr(replace(constants, eta_indicated=1.0), engine) / standard_g_per_hp_hr


def service_class(displacement_L: float) -> str:
    """``heavy`` (>= heavy_min_displacement_L) or ``medium``.

    Parameters
    ----------
    displacement_L : float, [L]

    Returns
    -------
    str, ``heavy`` or ``medium``.

    >>> service_class(12.0), service_class(7.0)
    ('heavy', 'medium')
    """
    return "heavy" if displacement_L >= model_file(ENGINES_FILE)["heavy_min_displacement_L"] else "medium"


def standard_for(service: str, model_year: int) -> float:
    """The SET CO2 standard [g/hp-hr] in force for ``model_year`` (the latest step at or
    before it; before the first step, the first).

    Parameters
    ----------
    service : str, ``heavy`` or ``medium``
    model_year : int

    Returns
    -------
    standard [g CO2/hp-hr].
    """
    steps = sorted((int(y), s) for y, s in model_file(ENGINES_FILE)["set_standard_g_per_hp_hr"][service].items())
    in_force = [s for y, s in steps if y <= model_year]
    return in_force[-1] if in_force else steps[0][1]


def reference_engine(service: str, idle_speed_rpm: float, peak_torque_speed_fraction: float,
                     idle_torque_fraction: float) -> ReferenceEngine:
    """The reference engine of ``service`` (engines.toml) with the full-load shape given (the
    engines.toml set of the row's duty class).

    Parameters
    ----------
    service : str, ``heavy`` or ``medium``
    idle_speed_rpm : float, [rpm]
    peak_torque_speed_fraction : float, peak-torque speed / rated speed [-]
    idle_torque_fraction : float, full-load torque at idle / peak torque [-]

    Returns
    -------
    ReferenceEngine (units in its field names).
    """
    size = model_file(ENGINES_FILE)["reference_engine"][service]
    return ReferenceEngine(displacement_L=size["displacement_L"], peak_torque_Nm=size["peak_torque_Nm"],
                           rated_power_kW=size["rated_power_kW"], rated_speed_rpm=size["rated_speed_rpm"],
                           cylinders=int(size["cylinders"]), idle_speed_rpm=idle_speed_rpm,
                           peak_torque_speed_fraction=peak_torque_speed_fraction,
                           idle_torque_fraction=idle_torque_fraction)


@lru_cache(maxsize=None)
def heavy_duty_constants(service: str, model_year: int, idle_speed_rpm: float, peak_torque_speed_fraction: float,
                         idle_torque_fraction: float) -> HeavyDutyFuelConstants:
    """The fuel-equation constants of a ``service``-class diesel of ``model_year``: the
    literature constants of engines.toml and the Willans slope that meets the SET standard.

    Parameters
    ----------
    service : str, ``heavy`` or ``medium``
    model_year : int, the engine's model year (its standard)
    idle_speed_rpm : float, [rpm]
    peak_torque_speed_fraction, idle_torque_fraction : float, the full-load shape [-]

    Returns
    -------
    HeavyDutyFuelConstants (the eight constants of engine.py's fuel equation).
    """
    literature = HeavyDutyFuelConstants(eta_indicated=1.0, **model_file(ENGINES_FILE)["constants"])
    engine = reference_engine(service, idle_speed_rpm, peak_torque_speed_fraction, idle_torque_fraction)
    eta = willans_slope_for_standard(standard_for(service, model_year), literature, engine)
    return replace(literature, eta_indicated=eta)


def engine_model_year(vehicle) -> int:
    """The model year whose engine standard applies to ``vehicle`` (VehicleSpec): its
    ``engine_model_year`` column, else ``model_year``, else ``default_model_year``.

    Parameters
    ----------
    vehicle : VehicleSpec

    Returns
    -------
    int, the model year.
    """
    for year in ((vehicle.extra or {}).get("engine_model_year"), vehicle.model_year):
        if year not in (None, "") and year == year:   # year == year: not NaN
            return int(year)
    return int(model_file(ENGINES_FILE)["default_model_year"])


def heavy_duty_fuel_constants(vehicle, displacement_L: float, idle_speed_rpm: float,
                              peak_torque_speed_fraction: float,
                              idle_torque_fraction: float) -> HeavyDutyFuelConstants | None:
    """The fuel constants of a medium- or heavy-duty diesel ``vehicle`` (VehicleSpec) of
    ``displacement_L`` whose engine set (params.engine_defaults) has the given full-load
    shape; None for any other vehicle (it keeps its set's constants).

    Parameters
    ----------
    vehicle : VehicleSpec
    displacement_L : float, [L]
    idle_speed_rpm : float, [rpm]
    peak_torque_speed_fraction, idle_torque_fraction : float, the full-load shape [-]

    Returns
    -------
    HeavyDutyFuelConstants or None.
    """
    if vehicle.fuel != "diesel" or vehicle.duty_class not in HEAVY_DUTIES:
        return None
    return heavy_duty_constants(service_class(displacement_L), engine_model_year(vehicle), idle_speed_rpm,
                                peak_torque_speed_fraction, idle_torque_fraction)


def bsfc_map_g_per_kWh(engine: ReferenceEngine, constants: HeavyDutyFuelConstants, speed_rpm, load_fraction):
    """Brake-specific fuel consumption [g/kWh] of ``engine`` on a grid of speeds [rpm] x load
    fractions of full-load torque (the fuel map the docs quote), accessories excluded.

    Parameters
    ----------
    engine : ReferenceEngine
    constants : HeavyDutyFuelConstants
    speed_rpm : array (S,), [rpm]
    load_fraction : array (L,), of full-load torque [-]

    Returns
    -------
    BSFC [g/kWh], array (S, L) (inf or NaN at zero torque).
    """
    n = np.asarray(speed_rpm, float)[:, None]
    torque = _full_load(engine, n) * np.asarray(load_fraction, float)[None, :]
    fuel = _engine_fuel_g_per_s(engine, constants, n, torque)
    with np.errstate(divide="ignore", invalid="ignore"):
        return fuel * 3.6e6 / (torque * n * RAD_S_PER_RPM)
