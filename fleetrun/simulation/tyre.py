"""Tyre rolling radius from the size code (thesis Sec. 7.2.1).

The thesis takes the rolling radius as constant and "directly dictated by the specifications
of the tire": half the nominal unloaded diameter. fleetrun does the same by default; a
vehicle may scale it (``extra['tire_rolling_radius_factor']``, e.g. 0.97 for the loaded
dynamic radius), which changes engine and differential speeds but not wheel work.

Size codes understood (ISO metric, P-metric, LT-metric, flotation and HD inch sizes):
``P235/75R15``, ``195/65VR16``, ``225/45ZR17 94W``, ``LT245/75R16``, ``295/75R22.5``,
``31x10.50R15``, ``11R22.5``, ``11.00R20``.
"""
from __future__ import annotations

import re

from fleetrun.errors import InputError

INCH_M = 0.0254  # exact

_METRIC = re.compile(
    r"^\s*(?:P|LT|T|ST|C)?\s*(\d{3})\s*/\s*(\d{2,3})\s*(?:[A-Z]{0,2})?\s*(?:R|D|B|-)\s*(\d{2}(?:\.\d)?)\b",
    re.IGNORECASE)
_FLOTATION = re.compile(r"^\s*(?:LT)?\s*(\d{2}(?:\.\d+)?)\s*[xX]\s*(\d{1,2}(?:\.\d+)?)\s*(?:R|D|B|-)\s*(\d{2}(?:\.\d)?)\b",
                        re.IGNORECASE)
# Inch (width-only) truck sizes, e.g. 11R22.5 or 11.00R20: the aspect ratio is not printed;
# "conventional" truck tyres of this kind run close to 88 % section height (Tire & Rim
# Association dimensions of 11R22.5: 1054 mm overall diameter -> (1054/25.4 - 22.5)/2/11).
_INCH = re.compile(r"^\s*(\d{1,2}(?:\.\d{1,2})?)\s*(?:R|-)\s*(\d{2}(?:\.\d)?)\b", re.IGNORECASE)
INCH_SIZE_ASPECT = 0.88


def tire_diameter_m(size: str) -> float:
    """Nominal unloaded overall diameter [m] of a tyre size code.

    Metric: D = rim + 2 x width x aspect (width in mm, rim in inches). Flotation: the first
    number is the diameter in inches. Inch truck sizes: aspect :data:`INCH_SIZE_ASPECT`.
    Raises :class:`InputError` for a code that does not parse.

    Parameters
    ----------
    size : str, the sidewall size code

    Returns
    -------
    diameter [m].

    >>> round(tire_diameter_m("P235/75R15"), 4)
    0.7335
    """
    text = str(size).strip()
    m = _METRIC.match(text)
    if m:
        width_mm, aspect, rim_in = float(m.group(1)), float(m.group(2)), float(m.group(3))
        return rim_in * INCH_M + 2.0 * width_mm * 1e-3 * aspect / 100.0
    m = _FLOTATION.match(text)
    if m:
        return float(m.group(1)) * INCH_M
    m = _INCH.match(text)
    if m:
        width_in, rim_in = float(m.group(1)), float(m.group(2))
        if 5.0 <= width_in <= 20.0 and rim_in >= 15.0:
            return (rim_in + 2.0 * width_in * INCH_SIZE_ASPECT) * INCH_M
    raise InputError(f"tire size '{size}' does not parse", column="tire_size", value=size,
                     hint="Write it as on the sidewall, e.g. P235/75R15, 195/65VR16, 295/75R22.5 or 11R22.5")


def rolling_radius_m(size: str, factor: float = 1.0) -> float:
    """Rolling radius [m]: half the nominal diameter times ``factor`` (thesis Sec. 7.2.1: constant).

    Parameters
    ----------
    size : str, the sidewall size code
    factor : float, rolling radius / nominal radius [-]

    Returns
    -------
    radius [m].

    >>> round(rolling_radius_m("295/75R22.5", 0.97), 4)
    0.4918
    """
    return 0.5 * tire_diameter_m(size) * float(factor)
