"""Physics the thesis model leaves out: a registry used by ``diagnose`` and ``--with``.

>>> from fleetrun.effects import get_effect, parse_with
>>> [(e.id, p) for e, p in parse_with("inertia,cornering:k_c=0.1")]
[('inertia', {'J_kg_m2': 0.05}), ('cornering', {'k_c': 0.1})]

Differential-level effects are extra pinion torque losses (see
:mod:`fleetrun.effects.differential`); vehicle-level effects are extra fuel rates (see
:mod:`fleetrun.effects.vehicle`). docs/effects.md describes each one.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from fleetrun.differential import canonical_configuration, configuration_lubricant, efficiency
from fleetrun.effects.base import Effect, Parameter
from fleetrun.effects.differential import DIFFERENTIAL_EFFECTS
from fleetrun.effects.vehicle import VEHICLE_EFFECTS, marginal_fuel_g_per_J
from fleetrun.errors import InputError, unknown_name_error
from fleetrun.registry import EFFECTS
from fleetrun.units import RAD_S_PER_RPM

for _effect in DIFFERENTIAL_EFFECTS + VEHICLE_EFFECTS:
    EFFECTS.register(_effect.id, _effect)

__all__ = ["EFFECTS", "Effect", "Parameter", "get_effect", "effects_for_level", "parse_with",
           "differential_extra_torque_Nm", "efficiency_with_effects", "steady_channels",
           "vehicle_extra_fuel_g_per_s", "overall_ratio", "as_effect_list"]


def get_effect(name: str) -> Effect:
    """The effect called ``name`` (case-insensitive, ``-`` for ``_``).

    Parameters
    ----------
    name : str, an effect id of docs/effects.md

    Returns
    -------
    Effect, the registered effect; an unknown name raises the registry's unknown-name error
    listing the valid ids.
    """
    return EFFECTS.get(name)


def effects_for_level(level: str) -> list[Effect]:
    """The registered effects of ``level`` (``differential`` or ``vehicle``).

    Parameters
    ----------
    level : str, ``differential`` or ``vehicle``

    Returns
    -------
    list of Effect, in registration order.
    """
    return [e for e in EFFECTS.values() if e.level == level]


def parse_with(text: str | None) -> list[tuple[Effect, dict[str, float]]]:
    """Parse ``--with EFFECT[,EFFECT...]``; each may carry ``:param=value[:param=value]``.

    Unset parameters take the effect's defaults; values outside the declared bounds are
    refused with the bounds in the message.

    Parameters
    ----------
    text : str or None, the ``--with`` value (None or blank: no effects)

    Returns
    -------
    list of (Effect, dict of float), each effect with its full parameters in the units of its
    catalogue entry.
    """
    if text is None or not str(text).strip():
        return []
    out = []
    for item in str(text).split(","):
        item = item.strip()
        if not item:
            continue
        name, *assignments = item.split(":")
        effect = get_effect(name)
        params = effect.defaults()
        for assignment in assignments:
            if "=" not in assignment:
                raise InputError(f"--with {item}: expected name=value after ':', got '{assignment}'",
                                 hint=f"Parameters of {effect.id}: "
                                      + ", ".join(p.name for p in effect.parameters))
            pname, value = (s.strip() for s in assignment.split("=", 1))
            try:
                param = effect.parameter(pname)
            except KeyError:
                raise unknown_name_error(f"parameter of {effect.id}", pname,
                                         [p.name for p in effect.parameters]) from None
            try:
                val = float(value)
            except ValueError:
                raise InputError(f"--with {item}: {pname} must be a number, got '{value}'") from None
            if not (param.lower <= val <= param.upper):
                raise InputError(f"--with {item}: {pname}={val:g} is outside "
                                 f"[{param.lower:g}, {param.upper:g}] {param.unit}")
            params[pname] = val
        out.append((effect, params))
    return out


def as_effect_list(effects) -> list[tuple[Effect, dict[str, float]]]:
    """``effects`` in any form the functions here accept (a ``--with`` string, ids, Effect
    objects, (effect or id, params) pairs) as (Effect, full parameters) pairs.

    Parameters
    ----------
    effects : str, sequence or None, any of the forms above

    Returns
    -------
    list of (Effect, dict of float), each effect with its full parameters.
    """
    return _as_effect_list(effects)


def _as_effect_list(effects) -> list[tuple[Effect, dict]]:
    if effects is None:
        return []
    if isinstance(effects, str):
        return parse_with(effects)
    out = []
    for item in effects:
        if isinstance(item, str):
            out.extend(parse_with(item))
        elif isinstance(item, Effect):
            out.append((item, item.defaults()))
        else:
            effect, params = item
            if isinstance(effect, str):
                effect = get_effect(effect)
            full = effect.defaults()
            full.update(params or {})
            out.append((effect, full))
    return out


def steady_channels(input_torque_Nm, input_speed_rpm, gear_ratio, *, lubricant="75W90",
                    channels: Mapping | None = None) -> dict:
    """Channels for a steady-state operating point (a map cell or a simulation step).

    Steady state means: no acceleration, straight driving (equal wheel speeds) and oil at its
    operating temperature (``time_s`` = infinity), unless ``channels`` overrides any of them
    (e.g. ``{"oil_temp_C": 10.0, "ambient_temp_C": 10.0}`` or
    ``{"wheel_speed_difference_rad_s": 2.0}``).

    Parameters
    ----------
    input_torque_Nm : float or array, pinion torque [N m]
    input_speed_rpm : float or array, pinion speed [rpm]
    gear_ratio : float, overall pinion-to-carrier ratio [-]
    lubricant : str, a name of ``models/lubricants.toml``
    channels : mapping or None, channels that override the steady-state ones

    Returns
    -------
    dict, the channels of :mod:`fleetrun.effects.differential` (speed in [rad/s]).
    """
    t = np.asarray(input_torque_Nm, dtype=float)
    w = np.asarray(input_speed_rpm, dtype=float) * RAD_S_PER_RPM
    ch = {"input_torque_Nm": t, "input_speed_rad_s": w, "input_accel_rad_s2": 0.0,
          "wheel_speed_difference_rad_s": 0.0, "time_s": np.inf, "ambient_temp_C": 20.0,
          "gear_ratio": float(gear_ratio), "lubricant": lubricant}
    if channels:
        ch.update(channels)
    return ch


def differential_extra_torque_Nm(effects, channels: Mapping) -> np.ndarray:
    """Sum of the extra pinion torque losses of differential-level ``effects``.

    Parameters
    ----------
    effects : str, sequence or None, as for :func:`as_effect_list`; vehicle-level ones are skipped
    channels : mapping, the channels of :mod:`fleetrun.effects.differential`
        (e.g. :func:`steady_channels`)

    Returns
    -------
    extra pinion torque [N m], an array of the channels' shape (0 without differential effects).
    """
    total = 0.0
    for effect, params in _as_effect_list(effects):
        if effect.level != "differential":
            continue
        total = total + effect.evaluate(channels, params)
    return np.asarray(total, dtype=float)


def _default_lubricant(configuration: str) -> str:
    """The lubricant of the configuration's driving axle (ATF in a transaxle, else gear oil)."""
    return configuration_lubricant(canonical_configuration(configuration))


def overall_ratio(gear_ratio, low_gear_ratio=None, axle_gear="high") -> float:
    """Pinion-to-carrier ratio: ``gear_ratio``, times ``low_gear_ratio`` in a dual's low gear.

    Parameters
    ----------
    gear_ratio : float, final-drive ratio [-]
    low_gear_ratio : float or None, two-speed axle low ratio [-]
    axle_gear : str, ``high`` or ``low``, the engaged range

    Returns
    -------
    float, overall pinion-to-carrier ratio [-].
    """
    if str(axle_gear).lower() == "low" and low_gear_ratio:
        return float(gear_ratio) * float(low_gear_ratio)
    return float(gear_ratio)


def efficiency_with_effects(configuration, torque_fraction, speed_rpm, gear_ratio, effects, *,
                            kim_torque_scale_Nm, channels=None, lubricant=None, **model_kwargs):
    """Differential efficiency with extra physics at steady state.

    The effects' extra pinion torque ``dT`` is taken before the thesis chain:
    ``T_out = G * eta(T_in - dT) * (T_in - dT)``, so the returned efficiency is
    ``eta(T_in - dT) * (T_in - dT) / T_in`` (0 where ``dT >= T_in``, as the B.6 floor).
    At steady state inertia and cornering contribute nothing and the oil is warm, unless
    ``channels`` says otherwise (see :func:`steady_channels`). ``kim_torque_scale_Nm``: the
    vehicle's Kim scale, turning fractions into the effects' absolute torque (and passed on to
    baselines in absolute torque).

    Parameters
    ----------
    configuration : str, a configuration id (docs/interface.md)
    torque_fraction : float or array, input torque / Kim torque scale [-]
    speed_rpm : float or array, differential input speed [rpm]
    gear_ratio : float, final-drive ratio [-]
    effects : str, sequence or None, as for :func:`as_effect_list`
    kim_torque_scale_Nm : float, the vehicle's Kim scale [N m]
    channels : mapping or None, channels overriding the steady state (:func:`steady_channels`)
    lubricant : str or None, lubricant name (None: the configuration's driving axle's)
    **model_kwargs : passed on to :func:`fleetrun.differential.efficiency` (``low_gear_ratio``,
        ``axle_gear``, ``physics``, ``oil_temp_C``)

    Returns
    -------
    efficiency [-], an array of the broadcast shape of ``torque_fraction`` and ``speed_rpm``.
    """
    model_kwargs["kim_torque_scale_Nm"] = kim_torque_scale_Nm
    tf = np.asarray(torque_fraction, dtype=float)
    n = np.asarray(speed_rpm, dtype=float)
    tf, n = np.broadcast_arrays(tf, n)
    t_in = tf * kim_torque_scale_Nm
    effect_list = _as_effect_list(effects)
    if not effect_list:
        return efficiency(configuration, tf, n, gear_ratio, **model_kwargs)
    lub = lubricant or _default_lubricant(str(configuration))
    ratio = overall_ratio(gear_ratio, model_kwargs.get("low_gear_ratio"),
                          model_kwargs.get("axle_gear", "high"))
    ch = steady_channels(t_in, n, ratio, lubricant=lub, channels=channels)
    dt = np.broadcast_to(differential_extra_torque_Nm(effect_list, ch), t_in.shape)
    t_eff = t_in - dt
    eta_b = np.asarray(efficiency(configuration, np.maximum(t_eff, 0.0) / kim_torque_scale_Nm, n,
                                  gear_ratio, **model_kwargs), dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        eta = np.where((t_in > 0) & (t_eff > 0), eta_b * t_eff / np.where(t_in > 0, t_in, 1.0), 0.0)
    return eta


def vehicle_extra_fuel_g_per_s(effects, *, time_s, vehicle_speed_mps, vehicle_mass_kg, fuel,
                               eta_indicated, engine_on=1.0, wheel_power_W=None) -> np.ndarray:
    """Extra fuel rate [g/s] of the vehicle-level ``effects`` for a simulation to add.

    ``time_s`` is the time since the (cold) start; ``wheel_power_W`` (when given) limits the
    grade's extra work to steps that drive the wheels; ``engine_on`` is 0 where the engine is
    off. Extra work costs fuel at the engine's Willans-line slope ``eta_indicated`` (see
    :func:`fleetrun.effects.vehicle.marginal_fuel_g_per_J`).

    Parameters
    ----------
    effects : str, sequence or None, as for :func:`as_effect_list`; differential-level ones are skipped
    time_s : float or array, time since the (cold) start [s]
    vehicle_speed_mps : float or array, vehicle speed [m/s]
    vehicle_mass_kg : float, vehicle mass [kg]
    fuel : str, ``gasoline`` or ``diesel``
    eta_indicated : float, the engine's Willans-line slope [-]
    engine_on : float or array, 1 while the engine runs, else 0 [-]
    wheel_power_W : float or array or None, tractive power at the wheels [W]

    Returns
    -------
    extra fuel rate [g/s], an array of the broadcast shape of ``time_s`` and ``vehicle_speed_mps``.
    """
    t = np.asarray(time_s, dtype=float)
    v = np.asarray(vehicle_speed_mps, dtype=float)
    if wheel_power_W is not None:
        v = v * (np.asarray(wheel_power_W, dtype=float) > 0)
    on = np.broadcast_to(np.asarray(engine_on, dtype=float), t.shape)
    ch = {"time_s": t, "vehicle_speed_mps": v, "engine_on": on,
          "vehicle_mass_kg": float(vehicle_mass_kg), "marginal_fuel_g_per_J": marginal_fuel_g_per_J(fuel, eta_indicated)}
    total = np.zeros(np.broadcast_shapes(t.shape, v.shape))
    for effect, params in _as_effect_list(effects):
        if effect.level == "vehicle":
            total = total + effect.evaluate(ch, params)
    return total
