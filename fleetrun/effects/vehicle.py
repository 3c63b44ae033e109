"""Vehicle-level physics a drive-cycle simulation leaves out, as extra fuel rate [g/s].

Channels: ``time_s`` (since the start), ``vehicle_speed_mps``, ``engine_on`` (1 while the
engine turns), scalars ``vehicle_mass_kg`` and ``marginal_fuel_g_per_J`` (fuel per unit of
extra engine work: the Willans-line slope, see :func:`marginal_fuel_g_per_J`).
"""
from __future__ import annotations

import numpy as np

from fleetrun.effects.base import Effect, Parameter
from fleetrun.physics.fuels import fuel_properties
from fleetrun.units import STANDARD_GRAVITY_M_S2



def marginal_fuel_g_per_J(fuel: str, eta_indicated: float, drivetrain_efficiency: float = 1.0) -> float:
    """Fuel [g] per J of extra work at the wheels (or at the crank with efficiency 1).

    Extra load on a running engine costs fuel at the slope of the Willans line (fuel power
    against brake power), not at the engine's (much lower) average efficiency.

    Parameters
    ----------
    fuel : str, ``gasoline`` or ``diesel`` (its lower heating value: models/fuels.toml).
    eta_indicated : float, the engine's Willans-line slope [-], brake power per fuel power at the
        margin: the vehicle's ``eta_indicated`` as the simulation's fuel equation uses it
        (models/engines.toml, fitted in models/engine_calibration.toml, per-vehicle override;
        resolved by ``fleetrun.simulation.params``). This module keeps no value of its own.
    drivetrain_efficiency : float, wheel work per crank work [-] (1: work at the crank).

    Returns
    -------
    marginal fuel [g/J], ``1 / (eta_indicated * LHV * drivetrain_efficiency)``.
    """
    lhv_J_per_g = fuel_properties(fuel.lower()).lhv_MJ_per_kg * 1e3
    return 1.0 / (float(eta_indicated) * lhv_J_per_g * drivetrain_efficiency)


def cold_start_extra_fuel(time_s, tau_s, engine_on=1.0):
    """Cold-start enrichment and friction: per g/s at the start, decaying as exp(-t/tau).

    An empirical diagnosis signature for a recording simulated warm; the physics of a cold
    engine in the simulation is ``fleetrun.simulation.thermal`` (docs/effects.md).

    Cold oil (thesis Sec. 3.1.2, 9.8: viscosity by Walther's equation, much higher when cold)
    and cold-start enrichment both fade with the engine's first-order warm-up; the Argonne
    cold/hot UDDS pairs (inputs/dyno) show the difference concentrated in the first phase.

    Parameters
    ----------
    time_s : float or array, time since the start [s]; negative times count as 0
    tau_s : float, decay time constant [s]
    engine_on : float or array, 1 while the engine turns, else 0 [-]

    Returns
    -------
    extra fuel rate per g/s of extra rate at the start [(g/s) / (g/s)], ``exp(-t/tau) * engine_on``.
    """
    t = np.maximum(np.asarray(time_s, dtype=float), 0.0)
    return np.exp(-t / tau_s) * np.asarray(engine_on, dtype=float)


def grade_extra_fuel(vehicle_speed_mps, vehicle_mass_kg, marginal_g_per_J):
    """Extra fuel per percent of grade: ``m g v (grade/100) * fuel per J`` (thesis Eq. 3.5 road load
    on a level road; seed 004 Eq. 35 adds the grade force to the longitudinal balance).

    Downhill the engine cannot give fuel back below zero fuelling; the rate is not floored
    here because the baseline already floors the total.

    Parameters
    ----------
    vehicle_speed_mps : float or array, vehicle speed v [m/s]
    vehicle_mass_kg : float, vehicle mass m [kg]
    marginal_g_per_J : float, marginal fuel per J of work [g/J] (:func:`marginal_fuel_g_per_J`)

    Returns
    -------
    extra fuel rate per percent of grade [g/s per %].
    """
    v = np.asarray(vehicle_speed_mps, dtype=float)
    return vehicle_mass_kg * STANDARD_GRAVITY_M_S2 * v / 100.0 * marginal_g_per_J


def route_grade_shape(distance_m, direction):
    """Grade along a route per unit of amplitude: ``sum_k u_k cos(k pi s / L)``, k = 1..K.

    A real road's grade is a function of distance (the slope of its elevation profile, seed
    004 Eq. 35 adds ``m g sin(theta)`` to the longitudinal balance wherever the vehicle is on
    the slope). Described by the first K modes of an elevation ``z(s) = sum_k u_k L / (k pi)
    sin(k pi s / L)`` that ends where it starts, so the shape carries no net climb (a net
    climb is the constant grade of :func:`grade_extra_fuel`).

    Parameters
    ----------
    distance_m : array, distance travelled since the route's start s [m], non-decreasing
    direction : array of K floats, the modes' weights u [-] (a unit vector)

    Returns
    -------
    grade per unit of amplitude at each sample [-] (multiply by the amplitude in %).
    """
    s = np.asarray(distance_m, dtype=float)
    length = float(s[-1] - s[0]) if s.size else 0.0
    if length <= 0:
        return np.zeros_like(s)
    x = (s - s[0]) / length
    u = np.asarray(direction, dtype=float)
    return sum(w * np.cos((k + 1) * np.pi * x) for k, w in enumerate(u))


def aero_drag_extra_fuel(vehicle_speed_mps, marginal_g_per_J):
    """Extra fuel per N s^2/m^2 of extra quadratic road load: ``v^2 * v * fuel per J``.

    The road load's quadratic coefficient (EPA coastdown C, thesis Eq. 3.5) is aerodynamic,
    ``C = rho Cd A / 2``; a roof box, an open window or a trailer raises it. Only while the
    wheels are driven (``vehicle_speed_mps`` is zero elsewhere in the channels).

    Parameters
    ----------
    vehicle_speed_mps : float or array, vehicle speed v [m/s]
    marginal_g_per_J : float, marginal fuel per J of work [g/J] (:func:`marginal_fuel_g_per_J`)

    Returns
    -------
    extra fuel rate per N s^2/m^2 of extra quadratic road-load coefficient [(g/s) / (N s^2/m^2)].
    """
    v = np.asarray(vehicle_speed_mps, dtype=float)
    return v * v * v * marginal_g_per_J


def accessory_extra_fuel(engine_on, marginal_g_per_J):
    """Extra fuel per kW of constant accessory power while the engine runs.

    Parameters
    ----------
    engine_on : float or array, 1 while the engine runs, else 0 [-]
    marginal_g_per_J : float, marginal fuel per J of crank work [g/J] (:func:`marginal_fuel_g_per_J`)

    Returns
    -------
    extra fuel rate per kW of accessory power [(g/s) / kW].
    """
    return 1000.0 * marginal_g_per_J * np.asarray(engine_on, dtype=float)


def _basis_warmup(ch, tau_s):
    return cold_start_extra_fuel(ch["time_s"], tau_s, ch.get("engine_on", 1.0))


def _basis_grade(ch):
    return grade_extra_fuel(ch["vehicle_speed_mps"], ch["vehicle_mass_kg"], ch["marginal_fuel_g_per_J"])


def _basis_aero(ch):
    return aero_drag_extra_fuel(ch["vehicle_speed_mps"], ch["marginal_fuel_g_per_J"])


def _basis_accessory(ch):
    return accessory_extra_fuel(ch.get("engine_on", np.ones_like(ch["time_s"])), ch["marginal_fuel_g_per_J"])


VEHICLE_EFFECTS = (
    Effect(
        id="warmup", level="vehicle", title="cold-start fuel penalty",
        parameters=(Parameter("extra_fuel_g_per_s", 0.3, 0.0, 20.0, "g/s",
                              "extra fuel rate at the start"),
                    Parameter("tau_s", 200.0, 20.0, 3000.0, "s",
                              "time constant of the decay exp(-t/tau)",
                              grid=tuple(float(v) for v in np.geomspace(30.0, 2000.0, 16)))),
        linear="extra_fuel_g_per_s", channels=(),
        signature="measured fuel above the simulation right after a cold start, fading within "
                  "minutes; follows time since start",
        seed="thesis Sec. 3.1.2 and 9.8 (temperatures fixed at operating values; Walther B.7)",
        steady_state="zero in a warm steady state", basis=_basis_warmup,
        separating_test="compare with a hot start of the same vehicle (--calibrate-on): a warm-up "
                        "is absent there, a constant load is not",
        per_recording=True),
    Effect(
        id="road_grade", level="vehicle", title="road grade missing from the drive profile",
        parameters=(Parameter("grade_pct", 1.0, -15.0, 15.0, "%",
                              "constant grade not in the profile (positive uphill)"),),
        linear="grade_pct", channels=(),
        signature="fuel shortfall proportional to speed (m g v sin theta), also while cruising",
        seed="thesis Sec. 3.1.6 (straight, level road); seed 004 Eqs 34-38 (longitudinal balance)",
        steady_state="adds m g v grade/100 of tractive power", basis=_basis_grade,
        separating_test="record grade_pct, or drive the route in both directions"),
    Effect(
        id="aero_drag", level="vehicle", title="extra aerodynamic drag",
        parameters=(Parameter("extra_C_N_s2_per_m2", 0.1, 0.0, 2.0, "N s^2/m^2",
                              "extra quadratic road-load coefficient (coastdown C in SI units)"),),
        linear="extra_C_N_s2_per_m2", channels=(),
        signature="fuel shortfall growing as the cube of speed while the wheels are driven: "
                  "small in town, large on the highway",
        seed="thesis Eq. 3.5 (road load A + B v + C v^2 from the EPA coastdown coefficients)",
        steady_state="adds extra_C v^3 of tractive power", basis=_basis_aero,
        separating_test="a coastdown of the vehicle as driven (roof box, windows, trailer)"),
    Effect(
        id="accessory_load", level="vehicle", title="constant accessory power",
        parameters=(Parameter("power_kW", 1.0, 0.0, 30.0, "kW",
                              "accessory power drawn from the engine while it runs"),),
        linear="power_kW", channels=(),
        signature="a constant extra fuel rate whenever the engine runs, including idle",
        seed="thesis Ch. 3.2 energy balance (only road load drives the engine)",
        steady_state="adds power_kW at the crank", basis=_basis_accessory,
        separating_test="record an idle stretch with the accessories off and on"),
)
