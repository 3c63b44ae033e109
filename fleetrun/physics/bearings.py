"""Taper roller bearing friction (thesis Sec. 5.1.3, Eq. 5.11; Khonsari & Booser Ch. 15).

``M = M_P + M_L + M_S``: load-dependent, viscous (lubricant) and seal/ end-flange terms.
Khonsari & Booser's forms give N mm with loads in N and diameters in mm; the printed code
uses the result as N m and computes the "load" as torque times a radius (see
docs/thesis-quirks.md). The functions keep the printed arithmetic; their names say what goes in.
"""
from __future__ import annotations

import numpy as np

from fleetrun.units import RAD_S_PER_RPM

#: Lubricant friction factors f_L of Khonsari & Booser Table 15.2; B.2 picks index 3 (MATLAB,
#: 1-based) = 8, "oil bath lubrication".
LUBRICATION_FACTORS = {"grease": 4.2, "oil_mist": 6.0, "oil_bath": 8.0, "oil_jet": 9.0}


def bearing_load_thesis(torque, radius, pressure_angle_rad, bearings=1, multiplier=1.0):
    """The bearing "load" of code B.1/B.2/B.4: ``P = torque * R_p / cos(phi) / n * k``.

    The printed code multiplies the torque by the pitch radius (a force would divide), and
    passes B.2/B.4 radii in inches. ``multiplier`` is the ``.*2`` of the carrier bearings.

    Parameters
    ----------
    torque : float or array, the stage torque [N m]
    radius : float, the pitch radius R_p as the printed code passes it [m in B.1, in in B.2/B.4]
    pressure_angle_rad : float, phi [rad]
    bearings : int, n, the bearings sharing the load
    multiplier : float, k [-] (2 for the carrier bearings of B.2/B.4)

    Returns
    -------
    the printed "load" [torque x radius unit, e.g. N m x in], the broadcast shape.

    >>> round(float(bearing_load_thesis(100.0, 2.0, np.radians(20))), 3)
    212.836
    """
    return np.asarray(torque, dtype=float) * radius / np.cos(pressure_angle_rad) / bearings * multiplier


def load_moment(load, bore_mm, friction_coefficient=0.0018):
    """M_P = 5e-4 mu P d (Khonsari & Booser Eq. 15.1).

    Parameters
    ----------
    load : float or array, P as :func:`bearing_load_thesis` gives it (Khonsari: radial load [N])
    bore_mm : float, bore diameter d [mm]
    friction_coefficient : float, mu [-] (0.0018 taper roller, Khonsari & Booser Table 15.1)

    Returns
    -------
    M_P (Khonsari: [N mm]; the printed code adds it as N m, docs/thesis-quirks.md).

    >>> round(float(load_moment(200.0, 40.0)), 6)
    0.0072
    """
    return 5e-4 * friction_coefficient * np.asarray(load, dtype=float) * bore_mm


def viscous_moment(speed_rpm, kinematic_viscosity, mean_diameter_mm, lubrication_factor=8.0,
                   threshold=2000.0):
    """M_L (Khonsari & Booser Eqs 15.3-15.4) with the printed switch.

    ``M_L = 1e-10 f_L (omega nu)^(2/3) d_m^3`` when ``omega nu > 2000`` else
    ``1.6e-8 f_L d_m^3``, with omega = 2 pi/60 n. Khonsari's switch is ``n nu > 2000`` with
    n in rpm and nu in cSt; the printed code uses rad/s and m^2/s, so the first branch never
    fires at road speeds (docs/thesis-quirks.md). Both branches are kept.

    Parameters
    ----------
    speed_rpm : float or array, bearing speed n [rpm]
    kinematic_viscosity : float, lubricant nu [m^2/s]
    mean_diameter_mm : float, d_m = (d + D) / 2 [mm]
    lubrication_factor : float, f_L [-] (:data:`LUBRICATION_FACTORS`; 8 oil bath)
    threshold : float, the printed switch on omega x nu [rad/s x m^2/s]

    Returns
    -------
    M_L (Khonsari: [N mm]; used as N m by the printed code).

    >>> viscous_moment(2000.0, 1e-4, 60.0).item()   # the slow branch at road speeds
    0.027648000000000002
    """
    omega_nu = RAD_S_PER_RPM * np.asarray(speed_rpm, dtype=float) * kinematic_viscosity
    with np.errstate(invalid="ignore"):
        fast = 1e-10 * lubrication_factor * np.abs(omega_nu) ** (2 / 3) * mean_diameter_mm ** 3
    slow = 1.6e-8 * lubrication_factor * mean_diameter_mm ** 3
    return np.where(omega_nu > threshold, fast, slow)


def seal_flange_moment(bore_mm, outer_mm, f1=20.0, f2=25.0):
    """M_S = 1e-3 (((d + D) / f1)^2 + f2) (Khonsari & Booser Eq. 15.5).

    Parameters
    ----------
    bore_mm : float, bore diameter d [mm]
    outer_mm : float, outer diameter D [mm]
    f1, f2 : float, Khonsari & Booser's seal constants [mm], [-]

    Returns
    -------
    M_S (Khonsari: [N mm]; used as N m by the printed code).

    >>> round(float(seal_flange_moment(40.0, 80.0)), 4)
    0.061
    """
    return 1e-3 * (((bore_mm + outer_mm) / f1) ** 2 + f2)


def taper_roller_moment(load, speed_rpm, bore_mm, outer_mm, kinematic_viscosity,
                        friction_coefficient=0.0018, lubrication_factor=8.0, f1=20.0, f2=25.0):
    """Total bearing moment M = M_P + M_L + M_S (thesis Eq. 5.11; Khonsari & Booser Eq. 15.2).

    Parameters
    ----------
    load : float or array, P [N, as Khonsari; the printed load, :func:`bearing_load_thesis`]
    speed_rpm : float or array, n [rpm]
    bore_mm, outer_mm : float, d and D [mm]
    kinematic_viscosity : float, nu [m^2/s]
    friction_coefficient, lubrication_factor, f1, f2 : float, mu [-], f_L [-], f1 [mm], f2 [-]

    Returns
    -------
    M = M_P + M_L + M_S, the drag torque the chain subtracts [N m, as printed].

    >>> round(float(taper_roller_moment(200.0, 2000.0, 40.0, 80.0, 1e-4)), 4)
    0.0958
    """
    mean = 0.5 * (bore_mm + outer_mm)
    return (load_moment(load, bore_mm, friction_coefficient)
            + viscous_moment(speed_rpm, kinematic_viscosity, mean, lubrication_factor)
            + seal_flange_moment(bore_mm, outer_mm, f1, f2))
