"""Engine temperature and the extra fuel of a cold engine: cold start, warm-up, soak.

One lumped thermal node per engine stands for its coolant, oil and the metal they wet, at one
temperature ``T`` [C] (oil temperature = node temperature). Constants: ``models/thermal.toml``
(literature defaults; global, never per vehicle).

- **Warm-up while running** (first law, losses to ambient neglected until the thermostat
  opens): ``C dT/dt = f m_dot LHV``, so ``T = min(T_start + f LHV M / C, T_open)`` with M the
  fuel burned since the start [g] and ``C = c_L V_d`` the node's heat capacity, scaled with
  displacement. Once at ``T_open`` the radiator holds T there while the engine runs.
- **Cooling while parked** (soak): Newton cooling toward ambient,
  ``T = T_amb + (T_end - T_amb) exp(-t / tau)``.
- **Extra fuel while cold** (only where the warm engine burns fuel; not in fuel cut-off):
  rubbing friction rises with the oil's viscosity, ``T_f,cold = s T_f (nu(T)/nu(T_open))^n``
  with ``T_f`` the warm engine's friction torque (its FMEP: ``engine.motoring_torque_Nm``
  without the closed-throttle pumping, which does not depend on the oil) and s the share of it
  in oil films; the extra torque costs fuel along the Willans slope,
  ``dm = dT_f omega / (eta_ind LHV)``. Gasoline engines are also enriched (and their spark
  retarded to light the catalyst): ``e(T) m_dot`` with e falling linearly from ``e_25`` at
  25 C to 0 at ``T_open``. The oil's viscosity is Walther's equation
  (:mod:`fleetrun.physics.lubricant`, thesis Eqs 5.13-5.14) through two points of an
  SAE 0W-20 (gasoline) or 5W-30 (diesel) oil.

The drive-cycle simulation (docs/simulation.md, "Cold start") runs the backward pass with a
warm engine, then one forward pass over time here: the temperature from the heat released so
far, then the cold-fuel correction, iterated because the extra fuel also heats the engine.
A plain cycle is driven warm (as EPA's HWFET and US06 after their preconditioning): T stays at
``T_open`` and nothing is added. A composed cycle (FTP) starts each phase after its soak.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from fleetrun.physics.lubricant import KELVIN, walther_coefficients, walther_kinematic_viscosity_m2_s
from fleetrun.resources import model_file
from fleetrun.simulation.core import engine_motoring_torque_Nm
from fleetrun.simulation.engine import fuel_rate_g_per_s
from fleetrun.units import RAD_S_PER_RPM

REFERENCE_COLD_C = 25.0      # engine temperature at which the enrichment share is e_25 [C]
FIXED_POINT_TOL_G = 1e-6     # fuel per step [g]: the forward pass' iteration tolerance
FIXED_POINT_MAX_ITER = 50


@dataclass(frozen=True)
class ThermalConstants:
    """The cold-start model's constants (``models/thermal.toml``)."""
    heat_fraction: float
    heat_capacity_J_per_K_per_L: float
    thermostat_temp_C: float
    soak_time_constant_s: float
    friction_share: float
    viscosity_exponent: float
    oil_walther: dict[str, tuple[float, float]]   # fuel -> (A, B) of Walther's equation
    enrichment_at_25C: dict[str, float]           # fuel -> e_25
    # what the node's heat capacity follows: "displacement" (c_L V_d) or "engine_mass"
    # (c_m x engine mass from rated power, :func:`engine_mass_kg`)
    heat_capacity_basis: str = "displacement"
    heat_capacity_J_per_K_per_kg: float = 0.0
    engine_base_mass_kg: float = 61.0
    engine_specific_power_kW_per_kg: float = 2.13


@lru_cache(maxsize=None)
def thermal_constants() -> ThermalConstants:
    """``models/thermal.toml`` as :class:`ThermalConstants`.

    Returns
    -------
    ThermalConstants (units in its field names; sources in models/thermal.toml).
    """
    data = model_file("thermal.toml")
    engine, friction = data["engine"], data["friction"]
    oils = {fuel: walther_coefficients(o["nu1_cSt"], o["T1_K"], o["nu2_cSt"], o["T2_K"])
            for fuel, o in data["oil"].items()}
    mass = data.get("engine_mass", {})
    return ThermalConstants(
        heat_fraction=float(engine["heat_fraction"]),
        heat_capacity_J_per_K_per_L=1e3 * float(engine["heat_capacity_kJ_per_K_per_L"]),
        thermostat_temp_C=float(engine["thermostat_temp_C"]),
        soak_time_constant_s=float(engine["soak_time_constant_s"]),
        friction_share=float(friction["share"]), viscosity_exponent=float(friction["viscosity_exponent"]),
        oil_walther=oils, enrichment_at_25C={k: float(v) for k, v in data["enrichment"].items()},
        heat_capacity_basis=str(engine.get("heat_capacity_basis", "displacement")),
        heat_capacity_J_per_K_per_kg=1e3 * float(engine.get("heat_capacity_kJ_per_K_per_kg", 0.0)),
        engine_base_mass_kg=float(mass.get("base_kg", 61.0)),
        engine_specific_power_kW_per_kg=float(mass.get("specific_power_kW_per_kg", 2.13)))


# ----------------------------------------------------------------------------- physics

def engine_heat_capacity_J_per_K(displacement_L, capacity_J_per_K_per_L):
    """Heat capacity of the lumped engine node [J/K]: ``c_L x V_d`` (scaled with engine size).

    Parameters
    ----------
    displacement_L : float or array, V_d [L]
    capacity_J_per_K_per_L : float, c_L [J/(K L)]

    Returns
    -------
    heat capacity [J/K].

    >>> float(engine_heat_capacity_J_per_K(2.0, 15000.0))
    30000.0
    """
    return np.asarray(displacement_L, float) * capacity_J_per_K_per_L


def engine_mass_kg(rated_power_kW, base_kg, specific_power_kW_per_kg):
    """Engine mass [kg] from its rated power: ``m_base + P_rated / p_spec``, FASTSim 2's
    fuel-converter mass (NREL FASTSim vehicle defaults fc_base_kg = 61 kg, fc_kw_per_kg = 2.13).

    Parameters
    ----------
    rated_power_kW : float or array, P_rated [kW]
    base_kg : float, m_base [kg]
    specific_power_kW_per_kg : float, p_spec [kW/kg]

    Returns
    -------
    mass [kg].

    >>> round(float(engine_mass_kg(150.0, 61.0, 2.13)), 1)
    131.4
    """
    return base_kg + np.asarray(rated_power_kW, float) / specific_power_kW_per_kg


def node_heat_capacity_J_per_K(va, k: ThermalConstants):
    """The vehicles' engine-node heat capacity [J/K] by ``k.heat_capacity_basis``: ``c_L V_d``
    (:func:`engine_heat_capacity_J_per_K`) or ``c_m`` x :func:`engine_mass_kg`.

    Parameters
    ----------
    va : VehicleArrays (displacement_L [L], P_rated_kW [kW])
    k : ThermalConstants

    Returns
    -------
    heat capacity [J/K], (V,).
    """
    if k.heat_capacity_basis == "engine_mass":
        return k.heat_capacity_J_per_K_per_kg * engine_mass_kg(va.P_rated_kW, k.engine_base_mass_kg,
                                                               k.engine_specific_power_kW_per_kg)
    return engine_heat_capacity_J_per_K(va.displacement_L, k.heat_capacity_J_per_K_per_L)


def warmed_temperature_C(start_temp_C, heat_J, heat_capacity_J_per_K, thermostat_temp_C):
    """Engine temperature [C] after ``heat_J`` [J] went into the node since ``start_temp_C``
    [C], held at ``thermostat_temp_C`` [C] once reached (radiator): ``min(T0 + Q / C, T_open)``.

    First law for one lumped node, losses to ambient neglected before the thermostat opens.
    An engine already above ``thermostat_temp_C`` stays where it is.

    Parameters
    ----------
    start_temp_C : float or array, T0 [C]
    heat_J : float or array, Q [J] into the node since the start
    heat_capacity_J_per_K : float or array, C [J/K]
    thermostat_temp_C : float, T_open [C]

    Returns
    -------
    temperature [C], the broadcast shape.

    >>> [round(float(warmed_temperature_C(20.0, q, 30000.0, 90.0)), 2) for q in (1.0e6, 3.0e6)]
    [53.33, 90.0]
    """
    start = np.asarray(start_temp_C, float)
    warmed = start + np.asarray(heat_J, float) / heat_capacity_J_per_K
    return np.where(start >= thermostat_temp_C, start, np.minimum(warmed, thermostat_temp_C))


def soaked_temperature_C(end_temp_C, ambient_temp_C, soak_s, time_constant_s):
    """Engine temperature [C] after ``soak_s`` [s] parked: Newton cooling toward ambient,
    ``T_amb + (T_end - T_amb) exp(-t / tau)``; ``soak_s = inf`` gives ambient (a cold start).

    Parameters
    ----------
    end_temp_C : float or array, temperature when the engine stopped [C]
    ambient_temp_C : float, [C]
    soak_s : float, time parked [s] (``inf``: cold)
    time_constant_s : float, tau [s]

    Returns
    -------
    temperature [C], the shape of ``end_temp_C``.

    >>> float(soaked_temperature_C(90.0, 20.0, float("inf"), 3600.0))
    20.0
    """
    decay = math.exp(-soak_s / time_constant_s) if math.isfinite(soak_s) else 0.0
    return ambient_temp_C + (np.asarray(end_temp_C, float) - ambient_temp_C) * decay


def oil_viscosity_ratio(temp_C, reference_temp_C, walther_A, walther_B):
    """Kinematic viscosity of the engine oil at ``temp_C`` over that at ``reference_temp_C``
    (both [C]), Walther's equation with coefficients A, B (thesis Eq. 5.14).

    Parameters
    ----------
    temp_C : float or array, oil temperature [C]
    reference_temp_C : float, [C]
    walther_A, walther_B : float, Walther's coefficients [-] (nu in cSt, T in K)

    Returns
    -------
    nu(T) / nu(T_ref) [-], the shape of ``temp_C``.
    """
    nu = walther_kinematic_viscosity_m2_s(np.asarray(temp_C, float) + KELVIN, walther_A, walther_B)
    return nu / walther_kinematic_viscosity_m2_s(reference_temp_C + KELVIN, walther_A, walther_B)


def cold_friction_torque_Nm(friction_torque_Nm, friction_share, viscosity_ratio, viscosity_exponent):
    """Extra friction torque of a cold engine [N m]: ``s T_f ((nu/nu_hot)^n - 1)``.

    Parameters
    ----------
    friction_torque_Nm : float or array, the warm friction torque T_f (FMEP) [N m]
    friction_share : float, s [-], its part in oil films
    viscosity_ratio : float or array, nu(T) / nu(T_open) [-]
    viscosity_exponent : float, n [-] (Burke et al. 2010: 0.52)

    Returns
    -------
    extra friction torque [N m], the broadcast shape.
    """
    return friction_share * friction_torque_Nm * (np.asarray(viscosity_ratio, float) ** viscosity_exponent - 1.0)


def enrichment_fraction(temp_C, thermostat_temp_C, fraction_at_25C):
    """Cold enrichment as a share of the warm fuel rate: ``e_25 (T_open - T) / (T_open - 25)``,
    0 at and above ``thermostat_temp_C`` [C], rising linearly as the engine gets colder
    (Taylor & Stewart 2001, SAE 2001-01-0221: the bag 1 penalty grows linearly as ambient
    falls).

    Parameters
    ----------
    temp_C : float or array, engine temperature [C]
    thermostat_temp_C : float, T_open [C]
    fraction_at_25C : float, e_25 [-]

    Returns
    -------
    enrichment [-] (share of the warm fuel rate), the shape of ``temp_C``.

    >>> [float(enrichment_fraction(t, 90.0, 0.3)) for t in (25.0, 57.5, 95.0)]
    [0.3, 0.15, 0.0]
    """
    cold = (thermostat_temp_C - np.asarray(temp_C, float)) / (thermostat_temp_C - REFERENCE_COLD_C)
    return fraction_at_25C * np.maximum(cold, 0.0)


# ----------------------------------------------------------------------------- forward pass

def start_temperature_C(first_soak_s, ambient_temp_C, constants: ThermalConstants | None = None):
    """Engine temperature [C] when a cycle starts: a warm engine (``T_open``) soaked for
    ``first_soak_s`` [s] (``inf`` = a cold start at ambient; 0 = warm).

    Parameters
    ----------
    first_soak_s : float, soak before the start [s] (``inf``: cold)
    ambient_temp_C : float, [C]
    constants : ThermalConstants or None (None: models/thermal.toml)

    Returns
    -------
    temperature [C].
    """
    k = constants or thermal_constants()
    return float(soaked_temperature_C(k.thermostat_temp_C, ambient_temp_C, first_soak_s, k.soak_time_constant_s))


def engine_temperature_C(fuel_g, heat_capacity_J_per_K, lhv_MJ_per_kg, start_temp_C, step_soak_s,
                         ambient_temp_C, constants: ThermalConstants | None = None):
    """Engine temperature [C] at the start of each step (V, N): the heat of the fuel burned so
    far (:func:`warmed_temperature_C`), Newton cooling in engine-off steps
    (:func:`soaked_temperature_C`; an engine-off step holds the temperature at its end).

    Parameters
    ----------
    fuel_g : array (V, N), fuel burned in each step [g]
    heat_capacity_J_per_K : array (V,), [J/K]
    lhv_MJ_per_kg : array (V,), [MJ/kg]
    start_temp_C : float or array (V,), [C]
    step_soak_s : array (N,), engine-off time of each step [s] (0 while running)
    ambient_temp_C : float, [C]
    constants : ThermalConstants or None (None: models/thermal.toml)

    Returns
    -------
    temperature [C], array (V, N).
    """
    k = constants or thermal_constants()
    V, N = fuel_g.shape
    heat_J = fuel_g * (k.heat_fraction * np.asarray(lhv_MJ_per_kg, float) * 1e3)[:, None]
    capacity = np.asarray(heat_capacity_J_per_K, float)[:, None]
    temps = np.empty((V, N))
    seg_start = np.broadcast_to(np.asarray(start_temp_C, float), (V,)).astype(float)[:, None]
    first = 0
    for off in list(np.flatnonzero(np.asarray(step_soak_s) > 0)) + [N]:
        if off > first:
            heat = np.cumsum(heat_J[:, first:off], axis=1)
            so_far = np.concatenate([np.zeros((V, 1)), heat[:, :-1]], axis=1)
            temps[:, first:off] = warmed_temperature_C(seg_start, so_far, capacity, k.thermostat_temp_C)
            seg_start = warmed_temperature_C(seg_start, heat[:, -1:], capacity, k.thermostat_temp_C)
        if off < N:
            seg_start = soaked_temperature_C(seg_start, ambient_temp_C, float(step_soak_s[off]),
                                             k.soak_time_constant_s)
            temps[:, off] = seg_start[:, 0]
        first = off + 1
    return temps


def cold_start_extra_fuel(va, fuel_rate, engine_speed_rpm, dt_s, step_soak_s, start_temp_C, ambient_temp_C,
                          constants: ThermalConstants | None = None):
    """Extra fuel rate of a cold engine [g/s] and the engine temperature [C], both (V, N).

    ``va``: the vehicles' simulation parameters (``fleetrun.simulation.params.VehicleArrays``:
    ``displacement_L``, the fuel constants, ``lhv``, ``fuel``); ``fuel_rate`` [g/s] and
    ``engine_speed_rpm`` (V, N): the warm engine's, every step (0 where the engine is off);
    ``dt_s`` (N,) step durations [s]; ``step_soak_s``, ``start_temp_C``, ``ambient_temp_C``
    as for :func:`engine_temperature_C`. Fixed-point iteration: the extra fuel also heats the
    engine, so the temperature is recomputed from warm + extra fuel until the extra fuel per
    step changes by less than 1e-6 g, each vehicle on its own, so that a vehicle's result does
    not depend on the others in the call (plain iteration; the change shrinks by a factor 3-5
    per pass: 7 passes at 25 C, 12 at -20 C for the test vehicles). Only the steps where some
    engine is below the thermostat on the warm fuel alone take part: more fuel only warms
    sooner, and once at ``T_open`` the rest of an engine run adds nothing and does not change
    the temperature (so the sub-problem on those steps is exact).

    Parameters
    ----------
    va : VehicleArrays, the vehicles' simulation parameters
    fuel_rate : array (V, N), the warm engine's fuel rate [g/s]
    engine_speed_rpm : array (V, N), [rpm]
    dt_s : array (N,), step durations [s]
    step_soak_s : array (N,), soak before each step [s]
    start_temp_C : float or array, engine temperature at the start [C]
    ambient_temp_C : float, [C]
    constants : ThermalConstants or None (None: models/thermal.toml)

    Returns
    -------
    (extra fuel rate [g/s], engine temperature [C]), arrays (V, N).
    """
    k = constants or thermal_constants()
    capacity = node_heat_capacity_J_per_K(va, k)
    dt = np.asarray(dt_s, float)[None, :]
    temp = engine_temperature_C(fuel_rate * dt, capacity, va.lhv, start_temp_C, step_soak_s, ambient_temp_C, k)
    extra = np.zeros_like(fuel_rate)
    cold = np.flatnonzero((temp < k.thermostat_temp_C).any(axis=0))
    if cold.size == 0:
        return extra, temp
    rate, rpm, dt, soak = fuel_rate[:, cold], engine_speed_rpm[:, cold], dt[:, cold], np.asarray(step_soak_s)[cold]
    cold_fuel = _cold_fuel_function(va, rate, rpm, k)
    part, part_temp = np.zeros_like(rate), temp[:, cold]   # the first pass: warm fuel only
    # Each vehicle stops iterating when its own change is below the tolerance, so its result
    # does not depend on which other vehicles share the call or the block.
    active = np.ones(rate.shape[0], bool)
    for _ in range(FIXED_POINT_MAX_ITER):
        new = cold_fuel(part_temp)
        change_g = np.max(np.abs(new - part) * dt, axis=1, initial=0.0)
        part[active] = new[active]
        active &= change_g > FIXED_POINT_TOL_G
        if not active.any():
            break
        again = engine_temperature_C((rate + part) * dt, capacity, va.lhv, start_temp_C, soak, ambient_temp_C, k)
        part_temp[active] = again[active]
    extra[:, cold], temp[:, cold] = part, part_temp
    return extra, temp


def _cold_fuel_function(va, fuel_rate, engine_speed_rpm, k: ThermalConstants):
    """The extra fuel rate [g/s] (V, n) as a function of the engine temperature (V, n), for the
    warm ``fuel_rate`` and ``engine_speed_rpm`` of those steps: cold friction along the
    Willans line plus enrichment, where the warm engine burns fuel.

    The same functions as above, arranged for the iteration: the friction fuel is linear in
    the factor ``(nu/nu_hot)^n - 1`` (>= 0 up to the thermostat), so it is the warm rubbing
    friction's fuel times that factor, tabulated against temperature per oil (0.05 K steps
    from -80 C to the thermostat, linear interpolation: error below 1e-4 of the factor).
    """
    col = lambda a: np.asarray(a, float)[:, None]  # noqa: E731
    fuels = np.array([str(f) if str(f) in k.oil_walther else "gasoline" for f in va.fuel])
    enrich = col([k.enrichment_at_25C.get(str(f), 0.0) for f in va.fuel]) * fuel_rate
    # fuel of the warm rubbing friction s T_f (where the engine burns fuel), along the Willans slope
    friction = engine_motoring_torque_Nm(va, engine_speed_rpm, col, throttled=False)   # FMEP: no pumping
    slope = 1.0 / col(va.fuel_constants[:, 0])   # 1 / eta_indicated (engine.fuel_coefficients)
    warm_friction_fuel = fuel_rate_g_per_s([k.friction_share * friction * engine_speed_rpm * RAD_S_PER_RPM], [slope],
                                           fuel_rate > 0, col(va.lhv))
    grid = np.linspace(-80.0, k.thermostat_temp_C, int(round((k.thermostat_temp_C + 80.0) / 0.05)) + 1)
    # the factor (nu/nu_hot)^n - 1: cold_friction_torque_Nm of a unit torque and share
    tables = {oil: cold_friction_torque_Nm(1.0, 1.0, oil_viscosity_ratio(grid, k.thermostat_temp_C, *k.oil_walther[oil]),
                                           k.viscosity_exponent) for oil in dict.fromkeys(fuels)}

    def extra(temp_C):
        factor = np.empty(temp_C.shape)
        for oil, table in tables.items():
            rows = fuels == oil
            factor[rows] = np.interp(temp_C[rows], grid, table)
        return warm_friction_fuel * factor + enrichment_fraction(temp_C, k.thermostat_temp_C, 1.0) * enrich

    return extra
