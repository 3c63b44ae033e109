"""Tooth friction of gear pairs (thesis Sec. 5.1.2).

The mesh efficiencies are ratios, independent of torque; the chain multiplies the torque by
the gear ratio and this efficiency, and divides the speed by the ratio.
"""
from __future__ import annotations

import numpy as np


def helical_mesh_efficiency(friction_coefficient, center_distance, pressure_angle_rad,
                            gear_ratio, contact_ratio=1.1337):
    """Helical gear-pair efficiency as code B.1 prints it (thesis Eq. 5.6, after Buckingham).

    ``1 - mu / (2 C/(1+G) cos a) * |1 - 1/G| * (C sin a /(1+G)) * (1+G^2)/|1-G|
    * (1 - e + e^2)`` with the contact ratio e = 1.1337 (B.1: "calculation needed to be
    bypassed for G=1"). Undefined at G = 1.

    Parameters
    ----------
    friction_coefficient : float or array, mu [-]
    center_distance : float or array, C [any length unit: only ratios of it enter]
    pressure_angle_rad : float or array, a [rad]
    gear_ratio : float or array, G [-] (not 1)
    contact_ratio : float, e [-]

    Returns
    -------
    efficiency [-], the broadcast shape.

    >>> round(float(helical_mesh_efficiency(0.05, 3.0, np.radians(20), 2.5)), 4)
    0.9696
    """
    G = gear_ratio
    C = center_distance
    a = pressure_angle_rad
    e = contact_ratio
    return 1 - ((friction_coefficient / (2 * C / (1 + G) * np.cos(a))) * abs(1 - 1 / G)
                * (C * np.sin(a) / (1 + G)) * (1 + G ** 2) / abs(1 - G) * (1 - e + e ** 2))


def hypoid_sliding_speed_fpm(speed_rpm, outer_pitch_radius_gap_in, face_width_gap_in, pinion_teeth):
    """Sliding speed of a hypoid mesh in ft/min as code B.4 prints it (thesis Eq. 5.9).

    ``v = n / 12 * sqrt(dr^2 + dL^2 / 4) * t_p`` with ``dr = r_o,p - r_p,p`` and
    ``dL = L_fw,p - L_fw,g`` in inches (B.2 orders it ``n * sqrt(..) / 12 * t_p``).

    Parameters
    ----------
    speed_rpm : float or array, pinion speed n [rpm]
    outer_pitch_radius_gap_in : float, dr = outer minus mean pinion pitch radius [in]
    face_width_gap_in : float, dL = pinion minus gear face width [in]
    pinion_teeth : int, t_p (as B.4 multiplies by it)

    Returns
    -------
    sliding speed [ft/min]

    >>> round(float(hypoid_sliding_speed_fpm(2000.0, 0.2, 0.5, 10)), 2)
    533.59
    """
    return (np.asarray(speed_rpm, dtype=float) / 12
            * np.sqrt(outer_pitch_radius_gap_in ** 2 + face_width_gap_in ** 2 / 4) * pinion_teeth)


def dudley_friction_coefficient(sliding_speed_fpm):
    """Friction coefficient vs sliding speed, a fit to Dudley Fig. 12.8 (code B.2/B.4).

    ``f = 0.8 / (v + 100)^0.5`` with v in ft/min.

    Parameters
    ----------
    sliding_speed_fpm : float or array, v [ft/min]

    Returns
    -------
    friction coefficient f [-]

    >>> round(float(dudley_friction_coefficient(900.0)), 4)
    0.0253
    """
    return 0.8 / (np.asarray(sliding_speed_fpm, dtype=float) + 100) ** 0.5


def hypoid_mesh_efficiency(friction_coefficient, normal_pressure_angle_rad, pinion_spiral_rad,
                           gear_spiral_rad):
    """Hypoid gear-pair efficiency, adapted from Dudley Eq. 12.36 (thesis Eq. 5.9, B.2/B.4).

    ``eta = (cos phi_n + f tan psi_g) / (cos phi_n + f tan psi_p)``.

    Parameters
    ----------
    friction_coefficient : float or array, f [-] (:func:`dudley_friction_coefficient`)
    normal_pressure_angle_rad : float, phi_n [rad]
    pinion_spiral_rad, gear_spiral_rad : float, psi_p and psi_g [rad]

    Returns
    -------
    efficiency [-]

    >>> round(float(hypoid_mesh_efficiency(0.05, np.radians(20), np.radians(45), np.radians(30))), 4)
    0.9786
    """
    f = np.asarray(friction_coefficient, dtype=float)
    return ((np.cos(normal_pressure_angle_rad) + f * np.tan(gear_spiral_rad))
            / (np.cos(normal_pressure_angle_rad) + f * np.tan(pinion_spiral_rad)))
