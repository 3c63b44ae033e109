"""Forecast drivers besides the vehicles: fuel price and the price response of gallons, tax
rates per fiscal year (docs/budget.md, "Drivers"; constants in models/budget.toml).

Price response (partial adjustment, the form behind short- and long-run elasticities): the
cumulative elasticity k years after a price change is ``e_k = long x (1 - (1 - short/long)^k)``
(``e_1`` = short, ``e_inf`` = long). The model's gallons describe the first fiscal year at its
price; with log prices ``x_y = ln(P_y / P_1)`` (x_0 = 0) year y's gallons are multiplied by
``exp(sum_{j=1..y} (x_j - x_{j-1}) e_{y-j+1})``.
"""
from __future__ import annotations

import numpy as np

from fleetrun.budget.arithmetic import constants

FUELS = ("gasoline", "diesel")


def elasticities(scenario) -> tuple[float, float]:
    """(short run, long run) price elasticity of gallons: the scenario's, else models/budget.toml.

    Parameters
    ----------
    scenario : Scenario, the scenario (fleetrun.workbook.reader)

    Returns
    -------
    (short-run, long-run) elasticity [-].
    """
    default = constants()["drivers"]["price_elasticity"]
    short = scenario.price_elasticity_short_run
    long = scenario.price_elasticity_long_run
    return (float(default["short_run"] if short is None else short),
            float(default["long_run"] if long is None else long))


def cumulative_elasticity(short: float, long: float, years: int) -> np.ndarray:
    """``e_k`` for k = 1..years: long x (1 - (1 - short / long)^k); short when long is 0.

    Parameters
    ----------
    short : float, short-run elasticity [-]
    long : float, long-run elasticity [-]
    years : int, number of years

    Returns
    -------
    e_k [-], shape (years,).
    """
    k = np.arange(1, years + 1)
    if long == 0:
        return np.full(years, short)
    return long * (1.0 - (1.0 - short / long) ** k)


def price_path(scenario, fuel: str) -> np.ndarray:
    """Price [$/gal] of each budget year (NaN without a price): a schedule's year, or the last
    listed year before it (the first listed before all).

    Parameters
    ----------
    scenario : Scenario, the scenario
    fuel : str, ``gasoline`` or ``diesel``

    Returns
    -------
    price [$/gal] per budget year.
    """
    value = {"gasoline": scenario.fuel_price_gasoline_usd_per_gal,
             "diesel": scenario.fuel_price_diesel_usd_per_gal}.get(fuel)
    years = scenario.budget_years
    if value is None:
        return np.full(years, np.nan)
    if not isinstance(value, dict):
        return np.full(years, float(value))
    first = scenario.first_fiscal_year or 1
    out = []
    for y in range(years):
        listed = [k for k in value if k <= first + y]
        out.append(float(value[max(listed)] if listed else value[min(value)]))
    return np.array(out)


def response_factor(log_price, short: float, long: float) -> np.ndarray:
    """Gallons factor per year for log prices relative to year 1's (last axis = years):
    ``exp(sum_j (x_j - x_{j-1}) e_{y-j+1})`` with x_0 = 0.

    Parameters
    ----------
    log_price : array, ln(P_y / P_1) [-], years on the last axis
    short : float, short-run elasticity [-]
    long : float, long-run elasticity [-]

    Returns
    -------
    gallons factor [-], the shape of ``log_price``.
    """
    x = np.asarray(log_price, dtype=float)
    years = x.shape[-1]
    steps = np.diff(x, axis=-1, prepend=0.0)
    e = cumulative_elasticity(short, long, years)
    # lag[y, j] = e_{y-j+1} for j <= y
    lag = np.array([[e[y - j] if j <= y else 0.0 for j in range(years)] for y in range(years)])
    return np.exp(steps @ lag.T)


def price_factor(scenario, fuel: str) -> np.ndarray:
    """Each budget year's gallons factor from the scenario's fuel-price path (1 without one).

    Parameters
    ----------
    scenario : Scenario, the scenario
    fuel : str, ``gasoline`` or ``diesel``

    Returns
    -------
    gallons factor [-] per budget year.
    """
    prices = price_path(scenario, fuel)
    if not np.all(np.isfinite(prices)):
        return np.ones(scenario.budget_years)
    short, long = elasticities(scenario)
    return response_factor(np.log(prices / prices[0]), short, long)


def state_rates(scenario, fuel: str) -> np.ndarray:
    """State tax [$/gal] of each budget year (the scenario owns the schedule or index).

    Parameters
    ----------
    scenario : Scenario, the scenario
    fuel : str, the fuel

    Returns
    -------
    state tax [$/gal] per budget year.
    """
    return np.array([scenario.state_tax_usd_per_gal(fuel, y) for y in range(1, scenario.budget_years + 1)])


def federal_rates(scenario, fuel: str) -> np.ndarray:
    """Federal tax [$/gal] of each budget year (one rate: federal rates are not indexed).

    Parameters
    ----------
    scenario : Scenario, the scenario
    fuel : str, the fuel

    Returns
    -------
    federal tax [$/gal] per budget year.
    """
    return np.full(scenario.budget_years, scenario.federal_tax_usd_per_gal(fuel))


def start_month(scenario) -> int:
    """First month of the fiscal year (1-12): the scenario's, else models/budget.toml.

    Parameters
    ----------
    scenario : Scenario, the scenario

    Returns
    -------
    int, the month (1-12).
    """
    month = scenario.fiscal_year_start_month
    return int(month if month is not None else constants()["drivers"]["fiscal_year"]["default_start_month"])


def uncertainty() -> dict:
    """The drivers' spreads and the Monte Carlo settings (models/budget.toml).

    Returns
    -------
    dict, the ``[drivers.uncertainty]`` table.
    """
    return dict(constants()["drivers"]["uncertainty"])
