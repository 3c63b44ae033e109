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

    Parameters
    ----------
    eta : float or array, stage efficiency [-]
    torque : float or array, stage output torque [N m] (any torque unit: only NaN is set)
    copy : bool, False to work in place

    Returns
    -------
    (eta, torque) as float arrays, NaN where eta < 0.

    >>> mark_negative([0.9, -0.1], [10.0, 20.0])
    (array([0.9, nan]), array([10., nan]))
    """
    eta = np.array(eta, dtype=float, copy=copy)
    torque = np.array(torque, dtype=float, copy=copy)
    bad = eta < 0  # NaN < 0 is False, as in MATLAB
    eta[bad] = np.nan
    torque[bad] = np.nan
    return eta, torque


def zero_nan(eta, torque, copy=True):
    """B.6 with ``zeroornan`` false: where eta is NaN set eta and torque to 0.

    Parameters
    ----------
    eta : float or array, efficiency [-]
    torque : float or array, torque [N m]
    copy : bool, False to work in place

    Returns
    -------
    (eta, torque) as float arrays, 0 where eta is NaN.

    >>> zero_nan([0.9, np.nan], [10.0, np.nan])
    (array([0.9, 0. ]), array([10.,  0.]))
    """
    eta = np.array(eta, dtype=float, copy=copy)
    torque = np.array(torque, dtype=float, copy=copy)
    bad = np.isnan(eta)
    eta[bad] = 0.0
    torque[bad] = 0.0
    return eta, torque
