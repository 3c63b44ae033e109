"""EPA's derived 5-cycle label formulas and their coefficient sets by model year.

40 CFR 600.210-12(a)(2): ``1 / mpg_label = intercept + slope / mpg_test`` (city: the FTP,
highway: the HWFET), i.e. on-road gal/mi = intercept + slope x test gal/mi; the label's
combined figure is 55 % city, 45 % highway in fuel per mile (600.210-12(c)). The regulation
leaves the intercepts and slopes to the Administrator ("based on historic vehicle-specific
5-cycle ... data"); the sets are data in ``models/budget.toml`` ``[onroad.epa_label.sets]``, each
with the first model year it applies to and its source (docs/report.md, the on-road
gallons per mile).

The one owner of these facts: the budget's on-road adjustment (test fuel -> on-road fuel,
fleetrun.budget.arithmetic) and the label calibration (label -> test figures,
fleetrun.simulation.measured) choose their set here, by name or by model year.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from fleetrun.errors import unknown_name_error
from fleetrun.resources import model_file

CITY_SHARE = 0.55   # the label's combined figure: 55 % city, 45 % highway (40 CFR 600.210-12(c))
KINDS = ("city", "highway")


@dataclass(frozen=True)
class LabelSet:
    """One set of derived 5-cycle coefficients: ``city`` and ``highway`` are (intercept
    [gal/mi], slope [-]); it applies from ``first_model_year`` until the next set's."""

    name: str
    first_model_year: int
    city: tuple[float, float]
    highway: tuple[float, float]
    source: str

    def of(self, kind: str) -> tuple[float, float]:
        """(intercept [gal/mi], slope [-]) of ``kind`` (``city`` or ``highway``)."""
        return self.city if kind == "city" else self.highway


def _table() -> dict:
    return model_file("budget.toml")["onroad"]["epa_label"]


@lru_cache(maxsize=None)
def label_sets() -> dict[str, LabelSet]:
    """Every coefficient set of models/budget.toml, oldest first.

    Returns
    -------
    dict, set name -> LabelSet.
    """
    sets = []
    for name, v in _table()["sets"].items():
        pair = {kind: (float(v[kind]["intercept_gal_per_mile"]), float(v[kind]["slope"])) for kind in KINDS}
        sets.append(LabelSet(name, int(v["first_model_year"]), pair["city"], pair["highway"], str(v["source"])))
    return {s.name: s for s in sorted(sets, key=lambda s: s.first_model_year)}


def label_set(name: str) -> LabelSet:
    """The set called ``name``; an unknown name: error listing the valid ones and the closest.

    Parameters
    ----------
    name : str, a set name of models/budget.toml (e.g. ``derived_2017``)

    Returns
    -------
    LabelSet.
    """
    sets = label_sets()
    if name not in sets:
        raise unknown_name_error("label coefficient set", name, sets,
                                 hint="See models/budget.toml [onroad.epa_label.sets]")
    return sets[name]


def set_for_model_year(model_year) -> LabelSet:
    """The set EPA's labels of ``model_year`` use: the newest set whose first model year is at or
    before it; a model year before every set takes the oldest; none (None, NaN, NA) takes
    ``without_model_year`` of models/budget.toml.

    Parameters
    ----------
    model_year : int or None, the vehicle's model year

    Returns
    -------
    LabelSet.
    """
    sets = list(label_sets().values())
    if is_missing(model_year):
        return label_set(_table()["without_model_year"])
    in_force = [s for s in sets if s.first_model_year <= int(model_year)]
    return in_force[-1] if in_force else sets[0]


def is_missing(x) -> bool:
    """Whether ``x`` is None, NaN or pandas' NA (a model year or a label group not given).

    Parameters
    ----------
    x : any, one vehicle's value [-]

    Returns
    -------
    bool.
    """
    if x is None:
        return True
    try:
        return bool(x != x)
    except TypeError:       # pandas NA: its comparison has no truth value
        return True


def model_year_array(model_years) -> np.ndarray:
    """Model years as floats, NaN where a vehicle has none (None, NaN or pandas' NA).

    Parameters
    ----------
    model_years : sequence of int or None, each vehicle's model year

    Returns
    -------
    float array, one entry per vehicle.
    """
    try:
        return np.asarray(model_years, dtype=float)       # None becomes NaN
    except (TypeError, ValueError):                      # pandas' NA has no float value
        return np.array([np.nan if is_missing(my) else float(my) for my in model_years], dtype=float)


def coefficients(model_years, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """(intercept [gal/mi], slope [-]) of ``kind`` per vehicle, each by its model year (the rule
    of :func:`set_for_model_year`, vectorised: a run may hold hundreds of thousands of rows).

    Parameters
    ----------
    model_years : sequence of int or None, each vehicle's model year (None: ``without_model_year``)
    kind : str, ``city`` or ``highway``

    Returns
    -------
    (intercepts [gal/mi], slopes [-]), float arrays of one entry per vehicle.
    """
    years = model_year_array(model_years).reshape(-1)
    sets = list(label_sets().values())
    first_years = np.array([s.first_model_year for s in sets], dtype=float)
    which = np.maximum(np.searchsorted(first_years, years, side="right") - 1, 0)
    without = sets.index(set_for_model_year(None))
    which = np.where(np.isnan(years), without, which)
    pairs = np.array([s.of(kind) for s in sets], dtype=float)
    return pairs[which, 0], pairs[which, 1]


def label_gal_per_mile(test_gal_per_mile, intercept_gal_per_mile, slope):
    """Label (on-road) fuel per mile from test fuel per mile: ``intercept + slope x test``.

    Parameters
    ----------
    test_gal_per_mile : array_like, unadjusted test (dynamometer) fuel per mile [gal/mi]
    intercept_gal_per_mile : float or array, the set's intercept [gal/mi]
    slope : float or array, the set's slope [-]

    Returns
    -------
    label fuel per mile [gal/mi], the broadcast shape.
    """
    return np.asarray(intercept_gal_per_mile, float) + np.asarray(slope, float) * np.asarray(test_gal_per_mile, float)


def combined_label_mpg(ftp_mpg, hwfet_mpg, label: LabelSet):
    """The label's combined figure [mpg] of unadjusted FTP and HWFET figures (600.210-12(a)(2), (c)).

    Parameters
    ----------
    ftp_mpg : float or array, unadjusted FTP [mpg]
    hwfet_mpg : float or array, unadjusted HWFET [mpg]
    label : LabelSet, the coefficients

    Returns
    -------
    combined label [mpg], the broadcast shape.
    """
    city = label_gal_per_mile(1.0 / np.asarray(ftp_mpg, float), *label.city)
    highway = label_gal_per_mile(1.0 / np.asarray(hwfet_mpg, float), *label.highway)
    return 1.0 / (CITY_SHARE * city + (1.0 - CITY_SHARE) * highway)
