"""Effects (``--with``, docs/effects.md) inside the drive-cycle simulation.

**Differential level.** An effect is an extra pinion torque loss ``dT`` taken before the
thesis chain, ``T_out = G_tot eta(T_in - dT) (T_in - dT)`` (as
:func:`fleetrun.effects.efficiency_with_effects`). The backward simulation already finds the
thesis chain's input ``T_base`` for the demanded output (any mode: direct or the maps, which
are built without effects), so the pinion torque is the solution of

    T_in = T_base + dT(T_in; channels)

``dT`` of ``bearing_preload``, ``bearing_drag``, ``inertia`` and ``oil_warmup`` does not depend
on T_in (one evaluation); ``mixed_lubrication`` and ``cornering`` grow with |T_in| at a slope
below 1, so fixed-point iteration converges geometrically. Channels per step: pinion speed and
acceleration (``G_tot x`` the wheel's, so a two-speed range change is not an acceleration),
time since the start of the cycle at the step's middle, the scenario's ambient temperature,
the configuration's lubricant, and wheel-speed difference 0 (the cycles are straight).

**Vehicle level.** An effect is an extra fuel rate
(:func:`fleetrun.effects.vehicle_extra_fuel_g_per_s`) added to the step's fuel rate while the
engine burns fuel (not during deceleration fuel cut-off), the total floored at 0.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from fleetrun import effects as effect_catalog
from fleetrun.differential import canonical_configuration, configuration_lubricant
from fleetrun.effects import as_effect_list
from fleetrun.effects.base import AppliedEffect
from fleetrun.errors import DomainError
from fleetrun.simulation.params import willans_slope
from fleetrun.units import RAD_S_PER_RPM

FIXED_POINT_TOL = 1e-10   # of the Kim scale: the direct inversion's tolerance
FIXED_POINT_MAX_ITER = 200


@dataclass(frozen=True)
class CycleEffects:
    """The effects of one ``simulate`` call, split by level: tuples of (Effect, params)."""
    differential: tuple = ()
    vehicle: tuple = ()

    def __bool__(self) -> bool:
        return bool(self.differential or self.vehicle)


def cycle_effects(effects) -> CycleEffects:
    """Split ``effects`` (a ``--with`` string, ids, or (effect, params) pairs) by level.

    Parameters
    ----------
    effects : str, sequence or CycleEffects, a ``--with`` string (docs/effects.md), effect ids,
        or (effect, params) pairs; empty or None for none

    Returns
    -------
    CycleEffects, the differential-level and vehicle-level (effect, params) pairs.
    """
    if not effects:
        return CycleEffects()
    if isinstance(effects, CycleEffects):
        return effects

    pairs = as_effect_list(effects)
    return CycleEffects(differential=tuple(p for p in pairs if p[0].level == "differential"),
                        vehicle=tuple(p for p in pairs if p[0].level == "vehicle"))


def describe_effects(effects) -> list[AppliedEffect]:
    """The record of ``effects``: each one's id, level and parameters.

    Parameters
    ----------
    effects : str, sequence, CycleEffects or None, as for :func:`cycle_effects`

    Returns
    -------
    list of AppliedEffect, one per effect (parameters in the units of the effect's catalogue entry).
    """
    if isinstance(effects, CycleEffects):
        effects = effects.differential + effects.vehicle
    return [AppliedEffect(e.id, e.level, {k: float(v) for k, v in params.items()})
            for e, params in as_effect_list(effects or [])]


def step_time_since_start_s(time_s) -> np.ndarray:
    """Time since the start of the cycle at the middle of each step (step 0: 0).

    Parameters
    ----------
    time_s : array, the cycle's time stamps [s], shape (N,)

    Returns
    -------
    time since the start at each step's middle [s], shape (N,).
    """
    t = np.asarray(time_s, float)
    previous = np.concatenate([t[:1], t[:-1]])
    return 0.5 * (t + previous) - t[0]


@lru_cache(maxsize=None)
def _lubricant(configuration: str) -> str:
    return configuration_lubricant(canonical_configuration(configuration))


def differential_extra_torque_Nm(effects: CycleEffects, configurations, base_input_torque_Nm, input_speed_rpm,
                                 input_accel_rad_s2, time_since_start_s, ambient_temp_C, overall_ratio,
                                 kim_torque_scale_Nm) -> np.ndarray:
    """Extra pinion torque ``T_in - T_base`` [N m] of the differential-level effects, (V, N).

    Arrays are (V, N) (``time_since_start_s`` (N,) or (V, N), ``kim_torque_scale_Nm`` (V, 1)); row v
    belongs to ``configurations[v]``, whose lubricant the oil effects use. Solves
    ``T_in = T_base + dT(T_in)`` by fixed-point iteration to 1e-10 of the Kim scale.

    Parameters
    ----------
    effects : CycleEffects, the effects of the call (:func:`cycle_effects`)
    configurations : sequence of str, the differential configuration of each vehicle row
    base_input_torque_Nm : array, thesis-chain pinion torque T_base [N m], (V, N)
    input_speed_rpm : float or array, pinion speed [rpm], (V, N)
    input_accel_rad_s2 : float or array, pinion angular acceleration [rad/s^2], (V, N)
    time_since_start_s : float or array, time since the cycle's start [s], (N,) or (V, N)
    ambient_temp_C : float, the scenario's ambient temperature [C]
    overall_ratio : float or array, overall pinion-to-carrier ratio G_tot [-]
    kim_torque_scale_Nm : float or array, the configuration's Kim torque scale [N m], (V, 1)

    Returns
    -------
    extra pinion torque ``T_in - T_base`` [N m], (V, N); zeros without differential effects.
    """
    extra = effect_catalog.differential_extra_torque_Nm
    base = np.asarray(base_input_torque_Nm, float)
    shape = base.shape
    out = np.zeros(shape)
    if not effects.differential or base.size == 0:
        return out
    speed = np.broadcast_to(np.asarray(input_speed_rpm, float) * RAD_S_PER_RPM, shape)
    accel = np.broadcast_to(np.asarray(input_accel_rad_s2, float), shape)
    time = np.broadcast_to(np.asarray(time_since_start_s, float), shape)
    ratio = np.broadcast_to(np.asarray(overall_ratio, float), shape)
    tol = np.broadcast_to(FIXED_POINT_TOL * np.asarray(kim_torque_scale_Nm, float), shape)
    lubricants = np.array([_lubricant(c) for c in configurations], dtype=object)
    for lubricant in dict.fromkeys(lubricants):
        rows = np.flatnonzero(lubricants == lubricant)

        def d_torque(t_in, rows=rows, lubricant=lubricant):
            channels = {"input_torque_Nm": t_in, "input_speed_rad_s": speed[rows],
                        "input_accel_rad_s2": accel[rows], "wheel_speed_difference_rad_s": 0.0,
                        "time_s": time[rows], "ambient_temp_C": float(ambient_temp_C),
                        "gear_ratio": ratio[rows], "lubricant": lubricant}
            return np.broadcast_to(extra(effects.differential, channels), t_in.shape)

        t_base = base[rows]
        t_in = t_base + d_torque(t_base)
        for _ in range(FIXED_POINT_MAX_ITER):
            following = t_base + d_torque(t_in)
            converged = np.abs(following - t_in) <= tol[rows]
            t_in = following
            if converged.all():
                break
        else:
            ids = ", ".join(e.id for e, _ in effects.differential)
            raise DomainError(f"the differential effects ({ids}) take more than the input torque: "
                              "no pinion torque delivers the demanded output",
                              hint="Lower the effect parameters given with --with")
        out[rows] = t_in - t_base
    return out


def vehicle_extra_fuel_g_per_s(effects: CycleEffects, va, time_since_start_s, vehicle_speed_mps,
                               wheel_power_W, engine_on) -> np.ndarray:
    """Extra fuel rate [g/s] of the vehicle-level effects, (V, N); row v is vehicle v of the
    arrays ``va`` (params.VehicleArrays): its fuel, test weight and Willans slope
    ``eta_indicated``, the one the fuel equation uses, so extra work costs what it costs there.

    Parameters
    ----------
    effects : CycleEffects, the effects of the call (:func:`cycle_effects`)
    va : VehicleArrays, the vehicles' parameters (``fleetrun.simulation.params``)
    time_since_start_s : float or array, time since the cycle's start [s], (N,) or (V, N)
    vehicle_speed_mps : array, vehicle speed [m/s], (V, N)
    wheel_power_W : float or array, tractive power at the wheels [W], (V, N)
    engine_on : float or array, 1 where the engine burns fuel, else 0 [-], (V, N)

    Returns
    -------
    extra fuel rate [g/s], (V, N); zeros without vehicle effects.
    """
    extra = effect_catalog.vehicle_extra_fuel_g_per_s

    fuels, masses_kg, willans = va.fuel, va.mass_kg, willans_slope(va)
    speed = np.asarray(vehicle_speed_mps, float)
    out = np.zeros(speed.shape)
    if not effects.vehicle:
        return out
    time = np.broadcast_to(np.asarray(time_since_start_s, float), speed.shape)
    power = np.broadcast_to(np.asarray(wheel_power_W, float), speed.shape)
    on = np.broadcast_to(np.asarray(engine_on, float), speed.shape)
    for v in range(speed.shape[0]):
        out[v] = extra(effects.vehicle, time_s=time[v], vehicle_speed_mps=speed[v],
                       vehicle_mass_kg=float(masses_kg[v]), fuel=str(fuels[v]), eta_indicated=float(willans[v]),
                       engine_on=on[v], wheel_power_W=power[v])
    return out
