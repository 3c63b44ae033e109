"""Budget arithmetic: on-road fuel, tax rates, CO2, fiscal years, calibration and exact sums.

One owner for each budget fact (constants in ``models/budget.toml``, with their sources):

- on-road fuel from cycle fuel: EPA's derived 5-cycle label formulas (40 CFR 600.210-12(a)(2);
  their coefficient sets by model year: fleetrun.physics.epa_label), ``none`` or a scenario
  factor (:func:`onroad_gal_per_mile`);
- tax rates per fuel: :meth:`fleetrun.workbook.reader.Scenario.state_tax_usd_per_gal` and
  ``federal_tax_usd_per_gal``, looked up for arrays by :func:`tax_rates`;
- CO2 per gallon (EPA-420-F-11-041, the fuel table ``models/fuels.toml``): :func:`co2_t`;
- budget year y -> fiscal year ``first_fiscal_year + y - 1`` and its share of the budget
  period's miles ``(1 + g)^(y - 1) / sum_k (1 + g)^(k - 1)`` (:func:`year_shares`);
- parts that add up exactly to a total (:func:`exact_parts`), so fiscal-year rows reconcile
  with results.csv to the last bit.
"""
from __future__ import annotations

import math

import numpy as np

from fleetrun.physics import epa_label
from fleetrun.physics.fuels import fuel_properties
from fleetrun.resources import model_file

CITY, HIGHWAY = "city", "highway"
GRAMS_PER_TONNE = 1e6


def constants() -> dict:
    """``models/budget.toml``.

    Returns
    -------
    dict, the file's tables.
    """
    return model_file("budget.toml")


def cycle_kind(name: str, mean_speed_kph: float) -> str:
    """``city`` or ``highway``: which label formula a drive cycle gets (models/budget.toml).

    Parameters
    ----------
    name : str, the drive cycle's name
    mean_speed_kph : float, the cycle's mean speed [km/h] (used when the name is not listed)

    Returns
    -------
    str, ``city`` or ``highway``.
    """
    rules = constants()["onroad"]["cycle_kind"]
    upper = name.upper()
    if upper in {c.upper() for c in rules["city"]}:
        return CITY
    if upper in {c.upper() for c in rules["highway"]}:
        return HIGHWAY
    return CITY if mean_speed_kph < rules["city_below_mean_speed_kph"] else HIGHWAY


def onroad_label(setting) -> str:
    """How a scenario turns cycle fuel into on-road fuel, in words for the reports.

    Parameters
    ----------
    setting : str or float, the scenario's ``onroad_adjustment``: ``epa_label``, ``none`` or a
        factor [-]

    Returns
    -------
    str, the sentence.
    """
    if setting == "epa_label":
        sets = "; ".join(f"from MY{x.first_model_year} city 1/mpg = {x.city[0]:g} + {x.city[1]:g}/mpg, highway "
                         f"1/mpg = {x.highway[0]:g} + {x.highway[1]:g}/mpg" for x in epa_label.label_sets().values())
        return (f"EPA label adjustment (40 CFR 600.210-12 derived 5-cycle, the set of each vehicle's model year: "
                f"{sets}; no model year: MY{epa_label.set_for_model_year(None).first_model_year}'s; "
                "light-duty only; EVs kWh / 0.7)")
    if setting == "none":
        return "none (dynamometer cycle fuel)"
    return f"factor {float(setting):g} x cycle fuel"


def onroad_gal_per_mile(cycle_gal_per_mile, setting, kind: str, adjusted, model_years) -> np.ndarray:
    """On-road fuel (or energy) per mile for one cycle.

    Parameters
    ----------
    cycle_gal_per_mile : array_like
        Cycle fuel per mile of each vehicle [gal/mi] (kWh/mi for electric rows).
    setting : str or float
        The scenario's ``onroad_adjustment``: ``epa_label``, ``none`` or a factor [-].
    kind : str
        ``city`` or ``highway`` (:func:`cycle_kind`).
    adjusted : array_like of bool
        Rows the EPA label formula applies to (light-duty); the others keep cycle fuel.
    model_years : sequence of int or None
        Each row's model year: it chooses the label formula's coefficient set
        (fleetrun.physics.epa_label; None: the set for rows without one).

    Returns
    -------
    on-road fuel per mile [gal/mi] (kWh/mi for electric rows), the shape of ``cycle_gal_per_mile``.
    """
    cycle = np.asarray(cycle_gal_per_mile, dtype=float)
    if setting == "none":
        return cycle.copy()
    if setting != "epa_label":
        return float(setting) * cycle
    intercept, slope = epa_label.coefficients(model_years, kind)
    label = epa_label.label_gal_per_mile(cycle, intercept, slope)
    return np.where(np.asarray(adjusted, dtype=bool), label, cycle)


def electric_onroad_factor(setting) -> float:
    """On-road / dynamometer energy of an electric vehicle: 1 / 0.7 for the EPA label.

    Parameters
    ----------
    setting : str or float, the scenario's ``onroad_adjustment``: ``epa_label``, ``none`` or a
        factor [-]

    Returns
    -------
    float, on-road / dynamometer energy [-].
    """
    if setting == "none":
        return 1.0
    if setting != "epa_label":
        return float(setting)
    return 1.0 / constants()["onroad"]["epa_label"]["electric"]["label_factor"]


def label_adjusted_duty(duty_classes) -> np.ndarray:
    """Which rows the EPA label formulas apply to (light-duty, models/budget.toml).

    Parameters
    ----------
    duty_classes : sequence of str, each row's duty class

    Returns
    -------
    array of bool, the rows the label formulas apply to.
    """
    adjusted = constants()["onroad"]["epa_label"]["duty_classes"]["adjusted"]
    return np.isin(np.asarray(duty_classes, dtype=object), adjusted)


def tax_rates(scenario, fuels) -> tuple[np.ndarray, np.ndarray]:
    """State and federal rates [$/gal] for each row's fuel, from the scenario's one owner.

    Parameters
    ----------
    scenario : Scenario, the scenario (fleetrun.workbook.reader)
    fuels : sequence of str, each row's fuel

    Returns
    -------
    (state rate [$/gal], federal rate [$/gal]), arrays of one entry per row.
    """
    fuels = np.asarray(fuels, dtype=object)
    state = np.zeros(len(fuels))
    federal = np.zeros(len(fuels))
    for fuel in set(fuels.tolist()):
        rows = fuels == fuel
        state[rows] = scenario.state_tax_usd_per_gal(fuel)
        federal[rows] = scenario.federal_tax_usd_per_gal(fuel)
    return state, federal


def co2_g_per_gal(fuel: str) -> float:
    """Tailpipe CO2 per gallon burned (EPA-420-F-11-041, in models/fuels.toml); 0 for electric.

    Parameters
    ----------
    fuel : str, ``gasoline``, ``diesel`` or ``electric``

    Returns
    -------
    float, CO2 per gallon [g/gal].
    """
    return 0.0 if fuel == "electric" else fuel_properties(fuel).co2_g_per_gal


def co2_t(fuel_gal, fuel: str):
    """CO2 [t] from ``fuel_gal`` gallons of ``fuel``: gallons x g/gal / 1e6.

    Parameters
    ----------
    fuel_gal : float or array, fuel burned [gal]
    fuel : str, ``gasoline``, ``diesel`` or ``electric``

    Returns
    -------
    CO2 [t], the shape of ``fuel_gal``.
    """
    return np.asarray(fuel_gal, dtype=float) * co2_g_per_gal(fuel) / GRAMS_PER_TONNE


def fiscal_years(scenario) -> list[int]:
    """The fiscal year of each budget year (budget year numbers 1..Y without a first year).

    Parameters
    ----------
    scenario : Scenario, the scenario (``first_fiscal_year``, ``budget_years``)

    Returns
    -------
    list of int, one fiscal year per budget year.
    """
    first = scenario.first_fiscal_year
    start = int(first) if first is not None else 1
    return [start + y for y in range(scenario.budget_years)]


def year_shares(scenario) -> np.ndarray:
    """Each budget year's share of the budget period's miles: (1+g)^(y-1) / sum_k (1+g)^(k-1).

    Parameters
    ----------
    scenario : Scenario, the scenario (``vmt_growth_pct_per_year`` [%/year], ``budget_years``)

    Returns
    -------
    share of the period's miles [-] per budget year.
    """
    g = scenario.vmt_growth_pct_per_year / 100.0
    weights = np.array([(1.0 + g) ** y for y in range(scenario.budget_years)])
    return weights / scenario.mile_factor()


def exact_parts(parts, total: float) -> list[float]:
    """``parts`` with the last one moved by a few units in the last place so that
    ``math.fsum(parts) == total`` exactly (the parts are shares of ``total`` computed apart).

    Parameters
    ----------
    parts : sequence of float, the parts [any unit]
    total : float, their intended sum [the parts' unit]

    Returns
    -------
    list of float, the parts with the last one adjusted.
    """
    parts = [float(p) for p in parts]
    if not parts or not math.isfinite(total):
        return parts
    last = total - math.fsum(parts[:-1])
    parts[-1] = last
    for _ in range(64):
        error = math.fsum(parts) - total
        if error == 0.0:
            break
        parts[-1] = float(np.nextafter(parts[-1], -math.inf if error > 0 else math.inf))
    return parts


def display_round(value: float, low: float | None = None, high: float | None = None) -> float:
    """``value`` rounded to the digit the range can support: the power of ten at or below a
    tenth of the range's width (4 significant digits without a range).

    Parameters
    ----------
    value : float, the number to show [any unit]
    low : float or None, the range's low end [the unit of value]
    high : float or None, the range's high end [the unit of value]

    Returns
    -------
    float, the rounded value (``value`` itself when None, 0 or not finite).
    """
    if value is None or not math.isfinite(value) or value == 0:
        return value
    width = (high - low) if (low is not None and high is not None and math.isfinite(high - low)) else 0.0
    if width > 0:
        step = 10.0 ** math.floor(math.log10(width / 10.0))
    else:
        step = 10.0 ** (math.floor(math.log10(abs(value))) - 3)
    return round(value / step) * step
