"""Windage (viscous drag) torques of rotating parts (thesis Sec. 5.1.1, 5.1.2).

Each function returns the drag torque [N m] that the part takes from the power path; the
chain turns it into a stage efficiency ``1 - loss / torque`` (thesis Eq. 3.8).
"""
from __future__ import annotations

import numpy as np

#: hp -> W, the factor the printed code uses (thesis B.2/B.4, "Moran and Shapiro").
HP_TO_W = 745.7


def cylindrical_windage_torque_Nm(viscosity_Pa_s, diameter_m, length_m, clearance_m, speed_rad_s):
    """Couette drag of a shaft in a concentric bore (thesis Eq. 5.1; Fox & McDonald Ex. 8.2).

    ``T = pi/4 * mu * D^3 * L / a * omega``.

    Parameters
    ----------
    viscosity_Pa_s : float, dynamic viscosity mu of the fluid in the gap [Pa s]
    diameter_m : float, shaft diameter D [m]
    length_m : float, wetted length L [m]
    clearance_m : float, radial gap a [m]
    speed_rad_s : float or array, omega [rad/s]

    Returns
    -------
    drag torque [N m], the shape of ``speed_rad_s``.

    >>> round(float(cylindrical_windage_torque_Nm(0.01, 0.05, 0.1, 0.001, 100.0)), 6)
    0.009817
    """
    return np.pi / 4 * viscosity_Pa_s * diameter_m ** 3 * length_m / clearance_m * np.asarray(speed_rad_s, dtype=float)


def spherical_windage_torque_Nm(viscosity_Pa_s, speed, inner_radius_m, outer_radius_m):
    """Drag of a sphere (the spider-gear carrier) in a concentric shell (thesis Eq. 5.2).

    ``T = 4 pi^2 / 45 * mu * n * r^4 / (R - r)``. The printed code passes the speed in rpm
    (``speed`` here, unit as given; see docs/thesis-quirks.md), not in rad/s.

    Parameters
    ----------
    viscosity_Pa_s : float, mu [Pa s]
    speed : float or array, n as the printed code passes it [rpm]
    inner_radius_m : float, carrier (sphere) radius r [m]
    outer_radius_m : float, housing (shell) radius R [m]

    Returns
    -------
    drag torque [N m as printed; with n in rpm it is 60/(2 pi) times the rad/s value].

    >>> round(float(spherical_windage_torque_Nm(0.01, 1000.0, 0.05, 0.06)), 6)
    0.005483
    """
    return (4 * np.pi ** 2 / 45 * viscosity_Pa_s * np.asarray(speed, dtype=float)
            * inner_radius_m ** 4 / (outer_radius_m - inner_radius_m))


def helical_gear_windage_torque_Nm(speed_rpm, face_width_m, pitch_radius_m, outer_diameter_m,
                                   inner_diameter_m, immersion, oil_density_kg_m3, oil_nu_m2_s,
                                   air_density_kg_m3, air_nu_m2_s, enclosure_factor=0.7):
    """Windage of a helical gear (thesis Eqs 5.5 and 5.7; code B.1, after Matthews App. C.4).

    ``T = 1.069e-4 C_E (1 + 2.3 L/R) n^1.85 (D_o^4.7 - D_i^4.7) (X rho_o nu_o^.15 + (1-X) rho_a nu_a^.15)``
    with n in rpm, as printed. ``enclosure_factor`` C_E = 0.7 is a loose enclosure;
    ``immersion`` X the equivalent immersed fraction.

    Parameters
    ----------
    speed_rpm : float or array, gear speed n [rpm]
    face_width_m : float, L [m]
    pitch_radius_m : float, R [m]
    outer_diameter_m, inner_diameter_m : float, D_o and D_i [m] (pinion: D_i = 0)
    immersion : float, X, equivalent immersed fraction [-]
    oil_density_kg_m3, air_density_kg_m3 : float, rho_o and rho_a [kg/m^3]
    oil_nu_m2_s, air_nu_m2_s : float, nu_o and nu_a [m^2/s]
    enclosure_factor : float, C_E [-]

    Returns
    -------
    windage torque [N m].

    >>> round(float(helical_gear_windage_torque_Nm(2000.0, 0.03, 0.05, 0.11, 0.0, 0.3, 850.0, 5e-5, 1.0, 2e-5)), 4)
    0.4116
    """
    fluid = (immersion * (oil_density_kg_m3 * oil_nu_m2_s ** .15)
             + (1 - immersion) * (air_density_kg_m3 * air_nu_m2_s ** .15))
    n = np.asarray(speed_rpm, dtype=float)
    size = outer_diameter_m ** 4.7 - inner_diameter_m ** 4.7  # pinion: inner 0, exact
    return (1.069e-4 * enclosure_factor * (1 + 2.3 * face_width_m / pitch_radius_m)
            * n ** 1.85 * size * fluid)


def bevel_gear_windage_torque_Nm(speed_rpm, pitch_radius_in, face_width_in, face_factor,
                                 helix_angle_rad, immersion, oil_mu_Pa_s, air_mu_Pa_s,
                                 inner_radius_in=None):
    """Windage of a bevel/hypoid gear after Dudley's Gear Handbook (thesis Eqs 5.3, 5.8, 5.10).

    Dudley's power loss in hp (radii and lengths in inches) divided by the angular speed
    ``1000/60 * 2 pi`` at 1000 rpm, then converted with 745.7 W/hp (code B.2/B.4):

    ``P = 15/0.746 * (X mu_o + (1-X) mu_a)/mu_a * (n/1000)^2 / (1000/60*2*pi) * (2 r/100)^4
    * (5 L/100 (1 + R_f / sqrt(tan psi)) + S)`` with ``S = 2 r / 100`` for the pinion and
    ``S = 2 (r^5 - r_i^5) / r^4 / 100`` for the ring gear (``inner_radius_in`` given).

    Parameters
    ----------
    speed_rpm : float or array, gear speed n [rpm]
    pitch_radius_in : float, mean pitch radius r [in]
    face_width_in : float, L [in]
    face_factor : float, R_f (:func:`dudley_face_factor`) [-]
    helix_angle_rad : float, spiral angle psi [rad]
    immersion : float, X [-]
    oil_mu_Pa_s, air_mu_Pa_s : float, dynamic viscosities [Pa s] (only their ratio enters)
    inner_radius_in : float or None, ring gear inner radius r_i [in]; None for the pinion

    Returns
    -------
    windage torque [N m] (Dudley's hp at 1000 rpm per rad/s x 745.7 W/hp, as code B.2/B.4).

    >>> round(float(bevel_gear_windage_torque_Nm(2000.0, 1.5, 1.2, 7.2175, np.radians(45), 0.3, 0.03, 2e-5)), 4)
    0.1094
    """
    n = np.asarray(speed_rpm, dtype=float)
    mix = (immersion * oil_mu_Pa_s + (1 - immersion) * air_mu_Pa_s) / air_mu_Pa_s
    r = pitch_radius_in
    if inner_radius_in is None:
        rim = 2 * r / 100
    else:
        rim = 2 * (r ** 5 - inner_radius_in ** 5) / r ** 4 / 100
    torque_hp_s = (15 / 0.746 * mix * (n / 1000) ** 2 / (1000 / 60 * 2 * np.pi) * (2 * r / 100) ** 4
                   * (5 * face_width_in / 100 * (1 + face_factor / np.sqrt(np.tan(helix_angle_rad))) + rim))
    return torque_hp_s * HP_TO_W


def dudley_face_factor(pinion_teeth, pinion_pitch_radius_in):
    """R_f of Dudley's bevel windage: a least-squares line through Dudley Table 12.5 (B.2).

    ``R_f = 7.7782 - 0.1682 * t_p / (2 r_p)``.

    Parameters
    ----------
    pinion_teeth : int, t_p
    pinion_pitch_radius_in : float, r_p [in]

    Returns
    -------
    R_f [-].

    >>> round(dudley_face_factor(10, 1.5), 4)
    7.2175
    """
    return 7.7782 - 0.1682 * pinion_teeth / (2 * pinion_pitch_radius_in)
