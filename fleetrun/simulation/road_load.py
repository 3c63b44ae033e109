"""Road load at the wheels (thesis Ch. 2 road-load forces, Sec. 7.2 coastdown coefficients).

EPA target coefficients give the road-load force of a vehicle coasting on a level road,
F = A + B v + C v^2 with F in lbf and v in mph (40 CFR 1066.301; Reineman & Nash 1995 as
used in thesis Table 7.1). They lump tyre rolling resistance, aerodynamic drag and the
spin losses of the coasting driveline. fleetrun adds inertia (test weight plus a
rotating-mass allowance) and grade.
"""
from __future__ import annotations

import numpy as np

from fleetrun.cycles import MPH_TO_MPS
from fleetrun.units import STANDARD_GRAVITY_M_S2

LBF_N = 4.4482216152605  # exact (avoirdupois pound x standard gravity)

# EPA's effective-mass allowance for rotating parts in coastdown analysis is 1.5 % of the
# test mass (40 CFR 1066.310(b)(7): M_e = M + 1.5 % for the rotating inertia of the wheels
# and driveline). Heavy vehicles carry more wheels per tonne; fleetrun uses 3 % for MD/HD.
ROTATING_MASS_FRACTION = {"LD": 0.015, "MD": 0.03, "HD": 0.03}


def coastdown_to_si(A_lbf, B_lbf_per_mph, C_lbf_per_mph2):
    """EPA coefficients (lbf, lbf/mph, lbf/mph^2) -> (N, N s/m, N s^2/m^2).

    Parameters
    ----------
    A_lbf, B_lbf_per_mph, C_lbf_per_mph2 : float or array, the EPA target coefficients [lbf, lbf/mph, lbf/mph^2]

    Returns
    -------
    (A [N], B [N s/m], C [N s^2/m^2]) as float arrays.

    >>> [round(float(x), 4) for x in coastdown_to_si(30.0, 0.2, 0.02)]
    [133.4466, 1.9901, 0.4452]
    """
    A = np.asarray(A_lbf, float) * LBF_N
    B = np.asarray(B_lbf_per_mph, float) * LBF_N / MPH_TO_MPS
    C = np.asarray(C_lbf_per_mph2, float) * LBF_N / MPH_TO_MPS**2
    return A, B, C


def coastdown_force_N(speed_mps, A_N, B_N_s_per_m, C_N_s2_per_m2):
    """The coastdown polynomial A + B v + C v^2 [N], evaluated as A + v (B + C v) at any speed
    (in place for arrays; Python floats work too, for the scalar re-drive loop).

    Parameters
    ----------
    speed_mps : float or array, v [m/s] (an array is overwritten only if it is the result's own)
    A_N, B_N_s_per_m, C_N_s2_per_m2 : float or array, the SI coefficients [N, N s/m, N s^2/m^2] (:func:`coastdown_to_si`)

    Returns
    -------
    force [N], the broadcast shape (a float for float arguments).

    >>> coastdown_force_N(10.0, 100.0, 2.0, 0.4)
    160.0
    """
    force = C_N_s2_per_m2 * speed_mps
    force += B_N_s_per_m
    force *= speed_mps
    force += A_N
    return force


def road_load_N(speed_mps, A_N, B_N_s_per_m, C_N_s2_per_m2):
    """Coastdown road-load force [N] at ``speed_mps`` (0 at standstill: nothing rolls).

    Parameters
    ----------
    speed_mps : float or array, v [m/s]
    A_N, B_N_s_per_m, C_N_s2_per_m2 : float or array, the SI coefficients [N, N s/m, N s^2/m^2]

    Returns
    -------
    force [N], the broadcast shape.

    >>> road_load_N([0.0, 10.0], 100.0, 2.0, 0.4).tolist()
    [0.0, 160.0]
    """
    v = np.asarray(speed_mps, float)
    force = coastdown_force_N(v, A_N, B_N_s_per_m, C_N_s2_per_m2)
    return force if (v > 0.0).all() else np.where(v > 0.0, force, 0.0)


def grade_force_N(mass_kg, grade_pct):
    """Gravity along the road, m g sin(atan(grade/100)) [N]; positive uphill.

    Parameters
    ----------
    mass_kg : float or array, test mass m [kg]
    grade_pct : float or array, road grade [%] (rise / run x 100)

    Returns
    -------
    force [N], the broadcast shape.

    >>> round(float(grade_force_N(1500.0, 5.0)), 1)
    734.6
    """
    weight, sine = grade_force_factors(mass_kg, grade_pct)
    return weight * sine


def grade_force_factors(mass_kg, grade_pct):
    """The two factors of :func:`grade_force_N`, m g [N] and sin(atan(grade/100)) [-]: their
    product is the grade force, bit for bit (for a caller that multiplies them step by step).

    Parameters
    ----------
    mass_kg : float or array, test mass m [kg]
    grade_pct : float or array, road grade [%] (rise / run x 100)

    Returns
    -------
    (weight m g [N], sine of the road's angle [-]), each the shape of its argument.
    """
    theta = np.arctan(np.asarray(grade_pct, float) / 100.0)
    return np.asarray(mass_kg, float) * STANDARD_GRAVITY_M_S2, np.sin(theta)


def tractive_force_N(speed_mps, accel_mps2, grade_pct, mass_kg, rotating_mass_fraction,
                     A_N, B_N_s_per_m, C_N_s2_per_m2):
    """Force the driven wheels must put on the road [N]: road load + inertia + grade.

    Inertia uses the effective mass m (1 + f_rot); grade uses the test mass. Negative means
    the vehicle must be slowed (engine overrun and brakes).

    Parameters
    ----------
    speed_mps : float or array, v [m/s]
    accel_mps2 : float or array, a [m/s^2]
    grade_pct : float or array, grade [%]
    mass_kg : float or array, test mass m [kg]
    rotating_mass_fraction : float or array, f_rot [-] (:data:`ROTATING_MASS_FRACTION`)
    A_N, B_N_s_per_m, C_N_s2_per_m2 : float or array, the SI coastdown coefficients [N, N s/m, N s^2/m^2]

    Returns
    -------
    force [N], the broadcast shape (C order).

    >>> round(float(tractive_force_N(10.0, 0.5, 0.0, 1500.0, 0.015, 100.0, 2.0, 0.4)), 2)
    921.25
    """
    m = np.asarray(mass_kg, float)
    # inertia first: a new array (C order, for the simulation's sums) to add the rest in place
    force = np.multiply(m * (1.0 + rotating_mass_fraction), accel_mps2, order="C")
    force += road_load_N(speed_mps, A_N, B_N_s_per_m, C_N_s2_per_m2)
    force += grade_force_N(m, grade_pct)
    return force
