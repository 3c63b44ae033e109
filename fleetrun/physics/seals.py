"""Lip-seal drag (thesis Sec. 5.1.4, Eq. 5.12; Matthews App. C)."""
from __future__ import annotations

import numpy as np


def seal_tangential_force_N_per_m(seal_strength=1.0):
    """Tangential friction force per circumference, ``F' = 50 + 170 s`` N/m (Matthews App. C).

    ``s`` scales between a light (0) and a heavy (1) seal; B.1 uses 0.5, B.2/B.4 use 1.
    """
    return 50 + 170 * seal_strength


def seal_torque_Nm(shaft_radius_m, tangential_force_N_per_m):
    """Seal drag torque ``T = 2 pi r^2 F'`` (thesis Eq. 5.12)."""
    return 2 * np.pi * shaft_radius_m ** 2 * tangential_force_N_per_m
