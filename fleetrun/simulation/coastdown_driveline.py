"""The coastdown's driveline part: spin losses that the EPA target road load already holds and
that the drivetrain model counts again (docs/validation-epa.md "Coastdown driveline removed").

EPA target coefficients come from a coastdown in neutral (SAE J2263; 40 CFR 1066.301-310):
besides tyres and air they hold the spin drag of everything the wheels turn, the axle and
differential and the transmission's output side (Moskalik 2020, SAE 2020-01-1064, EPA: the
transmission's neutral output drag, measured as F0 + F1 V + F2 V^2, "can be quite large" and
is part of the vehicle coefficients). fleetrun's drivetrain adds the differential's loss (thesis
chain) and the gearbox spin loss (transmission.py) on top of that road load, so the no-load part
of those losses is in the simulation twice.

``remove_driveline_spin`` takes, per vehicle, the drivetrain model's own loss at zero output
torque over the coastdown's speed range (the differential by its thesis chain itself, the
``direct`` model, not a map's interpolation at zero), as a force at the wheels, fits it as
a + b v and subtracts a from A and b from B (B may be negative, as in the coastdown's own
fit). Variants (``models/road_load.toml``):

- ``none``: the road load as given (the default);
- ``differential``: the differential's no-load loss by the thesis chain (run's physics, ambient);
- ``differential_gearbox``: plus the gearbox spin loss a + b n with the gearbox input turning
  at top gear (fleetrun's in-gear spin loss standing in for the neutral drag EPA measured).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from fleetrun.errors import unknown_name_error
from fleetrun.resources import model_file
from fleetrun.simulation.core import DifferentialSolver
from fleetrun.simulation.transmission import spin_loss_Nm
from fleetrun.units import RAD_S_PER_RPM

VARIANTS = ("none", "differential", "differential_gearbox")
# SAE J2263 coasts from 115 km/h down to 15 km/h: the speeds the target coefficients were fitted over
COASTDOWN_SPEEDS_MPS = np.linspace(15.0, 115.0, 11) / 3.6


def default_variant() -> str:
    """The variant of ``models/road_load.toml`` ``[coastdown] driveline_removed``."""
    return model_file("road_load.toml")["coastdown"]["driveline_removed"]


def check_variant(name: str) -> str:
    """``name`` if it is a variant, else an error listing the valid ones."""
    if name not in VARIANTS:
        raise unknown_name_error("coastdown driveline variant", str(name), VARIANTS)
    return name


def linear_fit(speed_mps, force_N):
    """Least-squares a + b v per row of ``force_N`` (V, S) over ``speed_mps`` (S,): (a [N], b [N s/m])."""
    X = np.stack([np.ones_like(speed_mps), speed_mps], axis=1)
    coef, *_ = np.linalg.lstsq(X, np.asarray(force_N, float).T, rcond=None)
    return coef[0], coef[1]


def gearbox_spin_force_N(speed_mps, radius_m, final_drive, top_ratio, spin_a_Nm, spin_b_Nm_per_krpm):
    """Gearbox spin loss (transmission.spin_loss_Nm) with its input at top gear, at the wheels [N].

    Parameters
    ----------
    speed_mps : array (S,), road speed v [m/s]
    radius_m, final_drive, top_ratio : arrays (V,), tyre radius [m], axle ratio [-], top gear ratio [-]
    spin_a_Nm, spin_b_Nm_per_krpm : arrays (V,), the spin loss a [N m] and b [N m per 1000 rpm]

    Returns
    -------
    force [N], (V, S).

    >>> # 20 m/s on 0.33 m tyres, 2.1 overall: input 1215 rpm, (2 + 1.215) N m x 2.1 / 0.33 m
    >>> round(float(gearbox_spin_force_N(np.array([20.0]), np.array([0.33]), np.array([3.0]),
    ...                                  np.array([0.7]), np.array([2.0]), np.array([1.0]))[0, 0]), 2)
    20.46
    """
    overall = (final_drive * top_ratio)[:, None]
    n_in = speed_mps[None, :] / radius_m[:, None] / RAD_S_PER_RPM * overall
    return spin_loss_Nm(n_in, spin_a_Nm[:, None], spin_b_Nm_per_krpm[:, None]) * overall / radius_m[:, None]


def driveline_spin_force_N(va, solver, variant: str, speed_mps=COASTDOWN_SPEEDS_MPS):
    """The drivetrain model's no-load loss as a force at the wheels [N], (V, S); the differential
    by the thesis chain (``direct``) in ``solver``'s physics and ambient."""
    if solver.mode != "direct":
        solver = DifferentialSolver(va, "direct", solver.physics, solver.ambient, None)
    r, G = va.radius_m[:, None], va.final_drive[:, None]
    diff_rpm = speed_mps[None, :] / r / RAD_S_PER_RPM * G
    zero = np.zeros(diff_rpm.shape)
    frac = solver.input_fraction_2d(zero, diff_rpm, zero.astype(bool), np.ones(diff_rpm.shape, bool))
    force = frac * va.kim_torque_scale_Nm[:, None] * G / r
    if variant == "differential_gearbox":
        ratios = np.where(va.combo_trans_ratio > 0, va.combo_trans_ratio, np.inf)
        force = force + gearbox_spin_force_N(speed_mps, va.radius_m, va.final_drive, ratios.min(axis=1),
                                             va.spin_loss[:, 0], va.spin_loss[:, 1])
    return force


def remove_driveline_spin(va, solver, variant: str):
    """``va`` with A and B less the fitted no-load driveline force (unchanged for ``none``)."""
    if check_variant(variant) == "none" or va.n == 0:
        return va
    a, b = linear_fit(COASTDOWN_SPEEDS_MPS, driveline_spin_force_N(va, solver, variant))
    return replace(va, A_N=va.A_N - a, B_N=va.B_N - b)
