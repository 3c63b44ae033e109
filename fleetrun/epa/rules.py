"""The documented rules that turn an EPA Test Car List row into fleet-workbook values.

Each function is one rule; its constants live in ``models/epa_import.toml`` (loaded once by
:func:`constants`), and docs/epa-import.md explains them. Units are in the argument names.
"""
from __future__ import annotations

import math
import re
from functools import lru_cache

from fleetrun.resources import model_file

CONSTANTS_FILE = "epa_import.toml"


def constants() -> dict:
    """The parsed ``models/epa_import.toml``.

    Returns
    -------
    dict, the file's tables.
    """
    return model_file(CONSTANTS_FILE)


def peak_torque_Nm(rated_power_kW: float, displacement_L: float, diesel: bool = False) -> tuple[float, float]:
    """Peak engine torque from rated power and displacement, and the peak BMEP used [bar].

    T = bmep V_d / (4 pi) for a four-stroke engine (Heywood, *Internal Combustion Engine
    Fundamentals*, 1988, Eq. 2.19), with the peak bmep interpolated linearly in specific power
    P / V_d between a naturally aspirated and a turbocharged level (``[torque]`` in the
    constants file: published ratings of production engines), clamped at both ends; diesels
    use ``diesel_bmep_bar``.

    Parameters
    ----------
    rated_power_kW : float, rated power [kW]
    displacement_L : float, displacement V_d [L]
    diesel : bool, use the diesel peak bmep

    Returns
    -------
    (peak torque [N m], peak bmep [bar]).
    """
    c = constants()["torque"]
    if diesel:
        bmep_bar = float(c["diesel_bmep_bar"])
    else:
        (sp0, sp1), (b0, b1) = c["specific_power_kW_per_L"], c["bmep_bar"]
        specific = rated_power_kW / displacement_L
        w = min(max((specific - sp0) / (sp1 - sp0), 0.0), 1.0)
        bmep_bar = b0 + w * (b1 - b0)
    torque = bmep_bar * 1e5 * displacement_L * 1e-3 / (4.0 * math.pi)
    return torque, bmep_bar


def tyre_size_for_weight(test_weight_lb: float) -> str:
    """A common original-equipment tyre size for the equivalent test weight (``[[tyres]]``).

    Parameters
    ----------
    test_weight_lb : float, equivalent test weight [lb]

    Returns
    -------
    str, a tyre size code (e.g. ``P235/75R15``).
    """
    for tyre in constants()["tyres"]:
        if test_weight_lb <= float(tyre["max_test_weight_lb"]):
            return str(tyre["size"])
    return str(constants()["tyres"][-1]["size"])


def nv_ratio_rpm_per_mph(top_ratio: float, axle_ratio: float, tyre_radius_m: float) -> float:
    """Engine speed per vehicle speed in top gear [rpm/mph] (EPA's N/V): the engine turns
    top x axle times per wheel turn, and a wheel of radius r turns v / (2 pi r) per second.

    Parameters
    ----------
    top_ratio : float, top-gear transmission ratio [-]
    axle_ratio : float, axle (final-drive) ratio [-]
    tyre_radius_m : float, tyre rolling radius [m]

    Returns
    -------
    float, N/V [rpm/mph].
    """
    mph = constants()["units"]["mph_to_m_per_s"]
    return top_ratio * axle_ratio * mph * 60.0 / (2.0 * math.pi * tyre_radius_m)


def generic_gear_set(gears: int) -> tuple[list[float], str] | None:
    """The generic gear set for ``gears`` forward gears and its source (``[gears.N]``), or None.

    Parameters
    ----------
    gears : int, number of forward gears

    Returns
    -------
    (ratios [-], source) or None when the file has no set for ``gears``.
    """
    entry = constants()["gears"].get(str(int(gears)))
    return None if entry is None else ([float(r) for r in entry["ratios"]], str(entry["source"]))


def cvt_ratio_set() -> list[float]:
    """A CVT's ratio range as ``steps`` geometric ratios from the lowest to the highest (``[cvt]``).

    Returns
    -------
    list of float, ratios [-], from ``low_ratio`` to ``high_ratio`` of ``[cvt]``.
    """
    c = constants()["cvt"]
    low, high, n = float(c["low_ratio"]), float(c["high_ratio"]), int(c["steps"])
    return [low * (high / low) ** (k / (n - 1)) for k in range(n)]


def scale_to_nv(ratios, axle_ratio: float, nv_rpm_per_mph: float, tyre_radius_m: float) -> tuple[list[float], float]:
    """``ratios`` scaled as a whole so that the top (last) gear meets N/V with the axle and
    tyre given; returns the scaled ratios and the scale factor.

    Parameters
    ----------
    ratios : sequence of float, transmission ratios [-], top gear last
    axle_ratio : float, axle (final-drive) ratio [-]
    nv_rpm_per_mph : float, the N/V to meet [rpm/mph]
    tyre_radius_m : float, tyre rolling radius [m]

    Returns
    -------
    (scaled ratios [-], scale factor [-]).
    """
    scale = nv_rpm_per_mph / nv_ratio_rpm_per_mph(ratios[-1], axle_ratio, tyre_radius_m)
    return [r * scale for r in ratios], scale


@lru_cache(maxsize=1)
def _hybrid_patterns() -> tuple[re.Pattern, ...]:
    return tuple(re.compile(p, re.IGNORECASE) for p in constants()["hybrids"]["name_patterns"])


def hybrid_name_match(model: str) -> str | None:
    """The first hybrid name pattern (``[hybrids] name_patterns``) the model name matches, or None.

    Parameters
    ----------
    model : str, the EPA model name

    Returns
    -------
    str or None, the matching pattern.
    """
    for pattern in _hybrid_patterns():
        if pattern.search(model or ""):
            return pattern.pattern
    return None


def fuel_of(description: str) -> str | None:
    """fleetrun fuel of an EPA test fuel description (``[fuels]``), or None if unsupported.

    Parameters
    ----------
    description : str, the EPA test fuel description

    Returns
    -------
    str or None, ``gasoline`` or ``diesel``; None if unsupported or unknown.
    """
    text = (description or "").lower()
    fuels = constants()["fuels"]
    if any(n in text for n in fuels["unsupported"]):
        return None
    for fuel in ("gasoline", "diesel"):
        if any(n in text for n in fuels[fuel]):
            return fuel
    return None
