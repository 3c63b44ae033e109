"""Differential efficiency: the thesis model and other baselines behind one entry point.

``efficiency(configuration, torque_fraction, speed_rpm, gear_ratio, ...)`` evaluates a
configuration with a physics baseline chosen by name (``thesis`` = Appendix B as printed,
``vecto-generic`` = VECTO's generic axle loss map). Arrays broadcast; ``gear_ratio`` may be
an array too (evaluated per distinct value).
"""
from __future__ import annotations

import numpy as np

from fleetrun.differential import baselines as _baselines  # noqa: F401  (registers baselines)
from fleetrun.differential.configurations import (AXLE_GEARS, canonical_configuration,
                                                  configuration_ids, configuration_lubricant, dual_configuration_ids,
                                                  reference_capacity_Nm, uses_two_speed_box)
from fleetrun.errors import InputError
from fleetrun.registry import PHYSICS

__all__ = ["efficiency", "canonical_configuration", "configuration_ids", "dual_configuration_ids", "uses_two_speed_box",
           "configuration_lubricant", "reference_capacity_Nm", "kim_torque_scale_Nm", "physics_names",
           "check_inputs"]


def kim_torque_scale_Nm(peak_engine_torque_Nm, torque_converter_ratio, max_transmission_gear_ratio):
    """Kim's torque scale (thesis Sec. 5.2.1.A): the largest torque the transmission can hand
    to the differential, peak engine torque x converter ratio (3.0 automatic, 1.0 manual) x
    the largest (first) gear ratio. Input torque / this scale is the torque fraction that the
    model maps back onto its reference differential's capacity.

    Parameters
    ----------
    peak_engine_torque_Nm : float or array [N m]
    torque_converter_ratio : float or array, stall torque ratio [-] (3.0 automatic, 1.0 manual)
    max_transmission_gear_ratio : float or array, first-gear ratio [-]

    Returns
    -------
    Kim torque scale [N m]

    >>> float(kim_torque_scale_Nm(250.0, 3.0, 4.7))
    3525.0
    """
    if all(type(x) in (int, float) for x in (peak_engine_torque_Nm, torque_converter_ratio,
                                              max_transmission_gear_ratio)):
        peak = float(peak_engine_torque_Nm)   # one vehicle (a row of the fleet): no array to build
    else:
        peak = np.asarray(peak_engine_torque_Nm, dtype=float)
    return peak * torque_converter_ratio * max_transmission_gear_ratio


def physics_names() -> list[str]:
    """The registered differential baselines (``--physics``).

    Returns
    -------
    list of str, the baseline names.
    """
    return PHYSICS.names()


def check_inputs(configuration, torque_fraction, speed_rpm, gear_ratio, low_gear_ratio=None, axle_gear="high"):
    """Validate the arguments of :func:`efficiency`; returns the canonical configuration id.

    Parameters
    ----------
    configuration : str, a configuration id (any case, ``-`` or ``_``)
    torque_fraction : float or array, input torque / Kim torque scale [-], >= 0
    speed_rpm : float or array, differential input speed [rpm], >= 0
    gear_ratio : float or array, final-drive ratio [-], > 0
    low_gear_ratio : float or None, two-speed axle low ratio [-] (dual configurations)
    axle_gear : str, ``high`` or ``low``

    Returns
    -------
    str, the canonical configuration id; invalid arguments raise :class:`InputError`.
    """
    config = canonical_configuration(configuration)
    g = np.asarray(gear_ratio, dtype=float)
    if not np.all(np.isfinite(g)) or np.any(g <= 0):
        raise InputError(f"gear ratio must be a positive number, got {_show(g)}",
                         hint="Give the differential (final drive) ratio, e.g. --gear-ratio 3.73")
    n = np.asarray(speed_rpm, dtype=float)
    if np.any(np.isnan(n)) or np.any(n < 0):
        raise InputError(f"speed must be >= 0 rpm, got {_show(n[~(n >= 0)])}",
                         hint="Give the differential input speed in rpm, e.g. --speeds-rpm 0,1000,2000")
    tf = np.asarray(torque_fraction, dtype=float)
    if np.any(np.isnan(tf)) or np.any(tf < 0):
        raise InputError(f"torque fraction must be >= 0, got {_show(tf[~(tf >= 0)])}",
                         hint="The thesis model covers drive torque: input torque / Kim torque scale, e.g. 0,0.25,0.5")
    if uses_two_speed_box(config):
        if low_gear_ratio is None:
            raise InputError(f"{config} has a two-speed axle and needs its low gear ratio",
                             hint="Add --low-gear-ratio, e.g. 4.900735 for the measured Eaton box (43/34 x 62/16)")
        lo = float(low_gear_ratio)
        if not np.isfinite(lo) or lo <= 0:
            raise InputError(f"low gear ratio must be a positive number, got {low_gear_ratio}")
        if axle_gear not in AXLE_GEARS:
            raise InputError(f"axle gear must be 'low' or 'high', got '{axle_gear}'")
    return config


def _show(values):
    flat = np.atleast_1d(values).ravel()
    return str(flat[0]) if flat.size == 1 else str(flat[:3].tolist())


def efficiency(configuration, torque_fraction, speed_rpm, gear_ratio, *, low_gear_ratio=None,
               axle_gear="high", physics="thesis", oil_temp_C=None, kim_torque_scale_Nm=None):
    """Differential efficiency of ``configuration`` (ids: docs/interface.md).

    The thesis model (Ch. 5, Appendix B) or another registered baseline: output power / input
    power at a steady operating point.

    Parameters
    ----------
    configuration : str, a configuration id (``LD_RWD``, ``HD_DUAL``, ...; any case, - or _)
    torque_fraction : float or array, input torque / Kim torque scale [-] (thesis Sec. 5.2.1.A)
    speed_rpm : float or array, differential input (transmission output) speed [rpm]
    gear_ratio : float or array, final-drive ratio [-]
    low_gear_ratio : float or array or None, two-speed axle low ratio [-] (dual configurations)
    axle_gear : ``"high"`` or ``"low"``, the two-speed axle's engaged range
    physics : str, the baseline (``thesis``: Appendix B as printed; ``vecto-generic``)
    oil_temp_C : float or None, lubricant temperature [C] (None: the baseline's own, 70 C for
        thesis)
    kim_torque_scale_Nm : float or None, the vehicle's Kim scale [N m], for baselines that need
        absolute torque (vecto-generic; None: the reference differential's capacity); the
        thesis model maps fractions onto its reference differential and ignores it

    Returns
    -------
    efficiency [-], an array of the broadcast shape; 0 where a stage's losses exceed its input
    (thesis B.6).

    >>> round(float(efficiency("LD_RWD", 0.5, 2000.0, 3.55)), 4)
    0.9816
    """
    config = check_inputs(configuration, torque_fraction, speed_rpm, gear_ratio,
                          None if low_gear_ratio is None else np.min(low_gear_ratio), axle_gear)
    model = PHYSICS.get(physics)
    low = np.nan if low_gear_ratio is None else low_gear_ratio
    tf, n, g, lo = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in
                                         (torque_fraction, speed_rpm, gear_ratio, low)))
    kwargs = dict(axle_gear=axle_gear, oil_temp_C=oil_temp_C, kim_torque_scale_Nm=kim_torque_scale_Nm)

    def one(g_value, lo_value, sel=None):
        pick = (lambda a: a) if sel is None else (lambda a: a[sel])
        return model.efficiency(config, pick(tf), pick(n), float(g_value),
                                low_gear_ratio=None if np.isnan(lo_value) else float(lo_value), **kwargs)

    if g.size == 0:
        return np.zeros(g.shape)
    if np.ndim(gear_ratio) == 0 and np.ndim(low) == 0:  # the common case: one vehicle, one axle
        return one(float(gear_ratio), float(low))
    # evaluate once per distinct (gear ratio, low gear ratio); NaN (no low gear) as -1
    pairs = np.nan_to_num(np.stack([g.ravel(), lo.ravel()], axis=1), nan=-1.0)
    if np.all(pairs == pairs[0]):
        return np.broadcast_to(one(g.flat[0], lo.flat[0]), g.shape).astype(float)
    out = np.empty(g.shape)
    keys, inverse = np.unique(pairs, axis=0, return_inverse=True)
    inverse = inverse.reshape(g.shape)
    for k, (g_value, lo_value) in enumerate(keys):
        sel = inverse == k
        out[sel] = one(g_value, np.nan if lo_value == -1.0 else lo_value, sel)
    return out
