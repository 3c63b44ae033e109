"""Lip-seal drag (thesis Sec. 5.1.4, Eq. 5.12; Matthews App. C)."""
from __future__ import annotations

import numpy as np


def seal_tangential_force_N_per_m(seal_strength=1.0):
    """Tangential friction force per circumference, ``F' = 50 + 170 s`` N/m (Matthews App. C).

    ``s`` scales between a light (0) and a heavy (1) seal; B.1 uses 0.5, B.2/B.4 use 1.

    Parameters
    ----------
    seal_strength : float, s [-] from 0 (light) to 1 (heavy)

    Returns
    -------
    tangential force per metre of circumference F' [N/m]

    >>> seal_tangential_force_N_per_m(0.5)
    135.0
    """
    return 50 + 170 * seal_strength


def seal_torque_Nm(shaft_radius_m, tangential_force_N_per_m):
    """Seal drag torque ``T = 2 pi r^2 F'`` (thesis Eq. 5.12).

    Parameters
    ----------
    shaft_radius_m : float or array, r [m]
    tangential_force_N_per_m : float or array, F' [N/m] (:func:`seal_tangential_force_N_per_m`)

    Returns
    -------
    drag torque T [N m]

    >>> round(float(seal_torque_Nm(0.02, 220.0)), 4)
    0.5529
    """
    return 2 * np.pi * shaft_radius_m ** 2 * tangential_force_N_per_m
