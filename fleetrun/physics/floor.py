"""The efficiency floor of the thesis code (thesis Appendix B.6, ``EtaNTorqCorrect``).

Every stage of a differential chain ends with ``EtaNTorqCorrect(eta, torque, true)``: a
negative efficiency (the stage lost more than it was given) turns efficiency and torque into
NaN, and NaN then rides through every later stage. The chain ends with
``EtaNTorqCorrect(eta, torque, false)``, which turns every NaN into 0.
"""
from __future__ import annotations

import numpy as np


def mark_negative(eta, torque, copy=True):
    """B.6 with ``zeroornan`` true: where ``eta < 0`` set eta and torque to NaN.

    ``copy=False`` works in place on float arrays the caller owns (the differential chain).
    """
    eta = np.array(eta, dtype=float, copy=copy)
    torque = np.array(torque, dtype=float, copy=copy)
    bad = eta < 0  # NaN < 0 is False, as in MATLAB
    eta[bad] = np.nan
    torque[bad] = np.nan
    return eta, torque


def zero_nan(eta, torque, copy=True):
    """B.6 with ``zeroornan`` false: where eta is NaN set eta and torque to 0."""
    eta = np.array(eta, dtype=float, copy=copy)
    torque = np.array(torque, dtype=float, copy=copy)
    bad = np.isnan(eta)
    eta[bad] = 0.0
    torque[bad] = 0.0
    return eta, torque
