"""Fleet turnover: survival by age, miles by age, the age distribution, the efficiency trend.

Constants and curves are data in ``models/turnover.toml`` (sources in
models/vehicle_library/PROVENANCE.md); docs/registrations.md gives the arithmetic:

- survival S(a): the share of a model year still registered at age a (EPA OMEGA
  re-registration by age); a cohort of age a0 counted in the base year keeps
  ``count x S(a0 + k) / S(a0)`` vehicles k years later;
- default age distribution of a class (a registration row without model year): the steady
  state of constant sales, share(a) = S(a) / sum S;
- miles per vehicle by age (EPA OMEGA annual VMT by age) or flat per class (FHWA VM-1);
- new model years' fuel economy relative to the library's model year from EPA Automotive
  Trends, each class its own column (real-world mpg of new non-electric cars for automobiles,
  of trucks for light trucks), beyond the table a yearly rate.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from fleetrun.resources import model_file


def constants() -> dict:
    """``models/turnover.toml``.

    Returns
    -------
    dict, the file's tables.
    """
    return model_file("turnover.toml")


def class_info(fhwa_class: str) -> dict:
    """The class's entry of models/turnover.toml ``[classes]``.

    Parameters
    ----------
    fhwa_class : str, a key of ``[classes]``

    Returns
    -------
    dict, the class's survival curve, miles and trend names.
    """
    return constants()["classes"][fhwa_class]


@lru_cache(maxsize=16)
def survival(fhwa_class: str) -> np.ndarray:
    """S(a) for a = 0..max_age (S(0) = 1), then 0.

    Parameters
    ----------
    fhwa_class : str, a key of ``[classes]``

    Returns
    -------
    S(a) [-] for a = 0..max_age (EPA OMEGA re-registration by age), shape (max_age + 1,).
    """
    c = constants()
    curve = np.asarray(c["survival"][class_info(fhwa_class)["survival"]]["reregistered_by_age"], dtype=float)
    out = np.zeros(c["max_age"] + 1)
    out[:min(len(curve), len(out))] = curve[:len(out)]
    return out


def survival_at(fhwa_class: str, ages) -> np.ndarray:
    """S at integer ``ages`` (0 beyond the curve, 1 below 0: not yet built counts as new).

    Parameters
    ----------
    fhwa_class : str, a key of ``[classes]``
    ages : int or array of int, ages [years]

    Returns
    -------
    S(ages) [-], the shape of ``ages``.
    """
    s = survival(fhwa_class)
    ages = np.asarray(ages, dtype=np.int64)
    return np.where(ages < 0, 1.0, s[np.clip(ages, 0, len(s) - 1)] * (ages < len(s)))


@lru_cache(maxsize=16)
def miles_by_age(fhwa_class: str) -> np.ndarray:
    """Annual miles per vehicle at age 0..max_age [mi].

    Parameters
    ----------
    fhwa_class : str, a key of ``[classes]``

    Returns
    -------
    annual miles per vehicle [mi] at age 0..max_age (EPA OMEGA VMT by age, or the class's flat
    FHWA VM-1 figure).
    """
    c = constants()
    info = class_info(fhwa_class)
    n = c["max_age"] + 1
    if "miles_by_age" in info:
        curve = np.asarray(c["miles_by_age"][info["miles_by_age"]]["annual_miles_by_age"], dtype=float)
        return np.concatenate([curve, np.full(max(0, n - len(curve)), curve[-1])])[:n]
    return np.full(n, float(info["annual_miles"]))


def miles_at(fhwa_class: str, ages) -> np.ndarray:
    """Annual miles per vehicle at integer ``ages`` (clipped to the curve).

    Parameters
    ----------
    fhwa_class : str, a key of ``[classes]``
    ages : int or array of int, ages [years]

    Returns
    -------
    annual miles per vehicle [mi], the shape of ``ages``.
    """
    m = miles_by_age(fhwa_class)
    return m[np.clip(np.asarray(ages, dtype=np.int64), 0, len(m) - 1)]


def age_distribution(fhwa_class: str) -> np.ndarray:
    """Default share of a class's vehicles at age 0..max_age: S(a) / sum S (constant sales).

    Parameters
    ----------
    fhwa_class : str, a key of ``[classes]``

    Returns
    -------
    share [-] at age 0..max_age, summing to 1.
    """
    s = survival(fhwa_class)
    return s / s.sum()


@lru_cache(maxsize=8)
def _trend_table(name: str) -> tuple[np.ndarray, np.ndarray]:
    table = constants()["trend"][name]["mpg_by_model_year"]
    years = np.array(sorted(int(y) for y in table), dtype=float)
    return years, np.array([float(table[str(int(y))]) for y in years])


def default_future_rate(name: str) -> float:
    """Yearly fuel-economy change after the trend table: the mean of its last N published years.

    Parameters
    ----------
    name : str, a trend table of ``[trend]`` (EPA Automotive Trends)

    Returns
    -------
    float, yearly relative mpg change [1/year] (0 for an empty table).
    """
    years, mpg = _trend_table(name)
    if not len(years):
        return 0.0
    span = int(constants()["trend"][name].get("future_from_last_years", 10))
    first = np.searchsorted(years, years[-1] - span)
    return float((mpg[-1] / mpg[first]) ** (1.0 / (years[-1] - years[first])) - 1.0)


def trend_mpg(name: str, model_years, future_rate: float | None = None) -> np.ndarray:
    """New vehicles' mpg of each model year (interpolated in the table, the first value
    before it, ``future_rate`` per year after it); NaN for a class without a trend.

    Parameters
    ----------
    name : str, a trend table of ``[trend]``
    model_years : int or array, model years
    future_rate : float or None, yearly relative mpg change after the table [1/year]
        (None: :func:`default_future_rate`)

    Returns
    -------
    new-vehicle fuel economy [mpg], the shape of ``model_years``.
    """
    years, mpg = _trend_table(name)
    model_years = np.asarray(model_years, dtype=float)
    if not len(years):
        return np.full(model_years.shape, math.nan)
    rate = default_future_rate(name) if future_rate is None else future_rate
    inside = np.interp(model_years, years, mpg)
    after = mpg[-1] * (1.0 + rate) ** (model_years - years[-1])
    return np.where(model_years > years[-1], after, inside)


def fuel_factor(fhwa_class: str, model_years, reference_years, future_rate: float | None = None) -> np.ndarray:
    """Fuel per mile of each model year relative to its representing vehicle's model year:
    mpg(reference) / mpg(model year) from the class's trend (1 without a trend).

    Parameters
    ----------
    fhwa_class : str, a key of ``[classes]``
    model_years : int or array, model years
    reference_years : int or array, the representing vehicles' model years
    future_rate : float or None, yearly relative mpg change after the table [1/year]

    Returns
    -------
    fuel per mile relative to the reference [-], the broadcast shape.
    """
    name = class_info(fhwa_class)["trend"]
    factor = trend_mpg(name, reference_years, future_rate) / trend_mpg(name, model_years, future_rate)
    return np.where(np.isfinite(factor), factor, 1.0)
