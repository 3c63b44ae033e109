"""From per-cycle simulation sums to the run's tables: results, classes, fiscal years, calibration.

How the numbers are put together (also in docs/report.md):

- A scenario's ``cycle_mix`` shares are shares of each vehicle's annual miles (MD and HD
  vehicles drive ``cycle_mix_MD`` / ``cycle_mix_HD`` where given). Per cycle, cycle fuel per
  mile becomes on-road fuel per mile (:func:`fleetrun.budget.arithmetic.onroad_gal_per_mile`);
  fuel per mile on the mix is ``sum_c share_c * onroad_c``; likewise each energy per mile.
- Budget miles per vehicle are ``annual_miles * sum_{y=1..Y} (1 + g)^(y-1)``; totals are over
  ``count`` vehicles. Gallons = miles x gallons per mile; taxes = gallons x the rate of the
  vehicle's fuel (the scenario owns the rates); mpg = miles / gallons.
- Calibration (``calibrate_to_observed`` = yes): each fuel's gallons are scaled by observed /
  modelled gallons of the first fiscal year; ``fuel_gal_uncalibrated_total`` keeps the raw ones.
- ``fuel_gal_low_total`` / ``fuel_gal_high_total``: the range from the measured model error
  (:mod:`fleetrun.budget.uncertainty`); empty without an error file, equal to the total when
  calibrated (the level then comes from collections, not from the model).
- Class and fiscal rows are exact sums (``math.fsum``) of the vehicle rows; each fiscal row is
  the group's total x the year's share of the miles, the last year absorbing the rounding so
  that the fiscal years add up to the results exactly.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd

from fleetrun.budget import arithmetic as budget
from fleetrun.cycles import load_cycle
from fleetrun.physics import epa_label
from fleetrun.budget import drivers
from fleetrun.units import METERS_PER_MILE
from fleetrun.workbook.schema import DUTY_CLASSES

ENERGY_FIELDS = ("diff_input_energy_J", "diff_output_energy_J", "drivetrain_input_energy_J",
                 "wheel_energy_J")
RESULTS_COLUMNS = ["scenario_id", "vehicle_id", "vehicle_class", "configuration", "fuel", "count",
                   "miles_total", "fuel_gal_total", "mpg", "diff_efficiency",
                   "drivetrain_efficiency", "state_tax_usd", "federal_tax_usd",
                   # beyond the contract: what the efficiencies are ratios of
                   "diff_input_energy_J", "diff_output_energy_J", "drivetrain_input_energy_J",
                   "wheel_energy_J", "duty_class",
                   # budget: cycle (dynamometer) and uncalibrated fuel, the range, CO2
                   "fuel_gal_cycle_total", "fuel_gal_uncalibrated_total", "fuel_gal_low_total",
                   "fuel_gal_high_total", "kwh_total", "ev_fee_usd",
                   # registrations (docs/registrations.md): empty where a row has none
                   "model_year"]
CLASS_COLUMNS = ["scenario_id", "vehicle_class", "vehicles", "miles_total", "fuel_gal_total", "mpg",
                 "diff_efficiency", "state_tax_usd", "federal_tax_usd",
                 "drivetrain_efficiency", "vehicle_types", "fuel_gal_low_total", "fuel_gal_high_total",
                 "kwh_total", "ev_fee_usd"]
FISCAL_COLUMNS = ["scenario_id", "fiscal_year", "fuel", "vehicle_class", "miles", "fuel_gal",
                  "fuel_gal_low", "fuel_gal_high", "co2_t", "kwh", "state_tax_usd", "federal_tax_usd",
                  "ev_fee_usd"]
# fiscal column <- results column it is a share of (None: computed from the fiscal gallons)
FISCAL_SOURCES = {"miles": "miles_total", "fuel_gal": "fuel_gal_total", "fuel_gal_low": "fuel_gal_low_total",
                  "fuel_gal_high": "fuel_gal_high_total", "kwh": "kwh_total",
                  "state_tax_usd": "state_tax_usd", "federal_tax_usd": "federal_tax_usd",
                  "ev_fee_usd": "ev_fee_usd"}
ELECTRIC = "electric"
CALIBRATION_COLUMNS = ["scenario_id", "fuel", "class_group", "fiscal_year", "model_gallons", "observed_gallons",
                       "model_to_observed", "calibrated", "scale", "fitted_on"]
TORNADO_COLUMNS = ["scenario_id", "driver", "low_usd", "high_usd", "central_usd"]


@dataclass
class BudgetTables:
    """What the budget arithmetic hands the runner."""
    results: pd.DataFrame
    yearly: dict            # scenario_id -> {column: rows x budget years}
    calibration: pd.DataFrame
    ranges: dict            # (scenario_id, fuel or "all") -> ranges.YearRange
    tornado: pd.DataFrame
    warnings: list
    period_ranges: dict     # scenario_id -> ranges.PeriodRange


@lru_cache(maxsize=64)
def cycle_mean_speed_kph(cycle: str) -> float:
    """A drive cycle's distance / duration, stops included [km/h].

    Parameters
    ----------
    cycle : str, a drive cycle name or path (fleetrun.cycles.load_cycle)

    Returns
    -------
    float, mean speed [km/h].
    """
    trace = load_cycle(cycle)
    hours = float(trace.time_s[-1] - trace.time_s[0]) / 3600.0
    return float(trace.miles) * METERS_PER_MILE / 1000.0 / hours


def _cycle_kind(cycle: str) -> str:
    return budget.cycle_kind(Path(cycle).stem if cycle.lower().endswith(".csv") else cycle,
                             cycle_mean_speed_kph(cycle))


def mix_per_mile(s, duty_of: np.ndarray, fuel: np.ndarray, per_condition: dict,
                 fuel_factor: np.ndarray | None = None, model_year=None) -> dict[str, np.ndarray]:
    """Per vehicle on scenario ``s``'s mix: cycle and on-road gallons per mile, on-road kWh per
    mile (electric rows) and the energies per mile. ``fuel_factor``: each row's cycle fuel per
    mile relative to its simulated vehicle (a registration cohort's model year,
    docs/registrations.md); None: 1.

    Parameters
    ----------
    s : Scenario, the scenario (its cycle mixes, ambient temperature [C], on-road adjustment)
    duty_of : array of str, each row's duty class
    fuel : array of str, each row's fuel
    per_condition : dict, (cycle, ambient [C]) -> the simulation's per-vehicle sums (miles [mi],
        fuel [gal], kWh, energies [J])
    fuel_factor : array or None, each row's cycle fuel per mile relative to its simulated vehicle [-]
    model_year : sequence of int or None, or None
        Each row's model year (None or NA: none), which chooses the label formulas' coefficients
        (fleetrun.physics.epa_label); None: no row has one.

    Returns
    -------
    dict of arrays, per row: ``fuel_gal_cycle`` and ``fuel_gal`` [gal/mi], ``kwh`` [kWh/mi] and each
    energy [J/mi].
    """
    n = len(duty_of)
    years = np.full(n, np.nan) if model_year is None else epa_label.model_year_array(model_year)
    adjusted = budget.label_adjusted_duty(duty_of) & (fuel != ELECTRIC)
    kwh_factor = budget.electric_onroad_factor(s.onroad_adjustment)
    names = ("fuel_gal_cycle", "fuel_gal", "kwh") + ENERGY_FIELDS
    per_mile = {name: np.zeros(n) for name in names}
    for duty in DUTY_CLASSES:
        rows = duty_of == duty
        if not rows.any():
            continue
        for cycle, share in s.mix_for(duty).items():
            sim = per_condition[(cycle, s.ambient_temp_C)]
            miles = sim["miles"][rows]
            cycle_gpm = sim["fuel_gal"][rows] / miles
            if fuel_factor is not None:
                cycle_gpm = cycle_gpm * fuel_factor[rows]
            kind = _cycle_kind(cycle)
            per_mile["fuel_gal_cycle"][rows] += share * cycle_gpm
            per_mile["fuel_gal"][rows] += share * budget.onroad_gal_per_mile(
                cycle_gpm, s.onroad_adjustment, kind, adjusted[rows], years[rows])
            per_mile["kwh"][rows] += share * kwh_factor * (sim["kwh"][rows] / miles)
            for name in ENERGY_FIELDS:
                per_mile[name][rows] += share * (sim[name][rows] / miles)
    return per_mile


def bias_factor(duty_of: np.ndarray, fuel: np.ndarray, error_model) -> np.ndarray:
    """1 + the model's known fleet-level bias per row (measured / predicted gallons), the
    centre's correction (docs/budget.md); 1 for electric rows and without an error model.

    Parameters
    ----------
    duty_of : array of str, each row's duty class
    fuel : array of str, each row's fuel
    error_model : ErrorModel or None, the fleet-level error (fleetrun.budget.uncertainty)

    Returns
    -------
    bias factor [-] per row.
    """
    if error_model is None:
        return np.ones(len(duty_of))
    bias = np.zeros(len(duty_of))
    for duty in set(duty_of.tolist()):
        bias[duty_of == duty] = error_model.for_duty(duty).bias
    return np.where(fuel == ELECTRIC, 1.0, 1.0 + bias)


@dataclass(frozen=True)
class _Rows:
    """The Vehicles rows' values the budget reads, taken from the rows once for every scenario
    (the arrays are read, never written)."""
    count: np.ndarray          # vehicles per row [-]
    annual: np.ndarray         # annual miles per vehicle [mi]
    fuel: np.ndarray
    duty: np.ndarray
    model_year: object         # pandas Int64 array
    makers: np.ndarray         # manufacturer, else make
    ids: list
    classes: list
    configurations: list

    @classmethod
    def of(cls, vehicles) -> "_Rows":
        return cls(count=np.array([v.count for v in vehicles], dtype=float),
                   annual=np.array([v.annual_miles for v in vehicles], dtype=float),
                   fuel=np.array([v.fuel for v in vehicles], dtype=object),
                   duty=np.array([v.duty_class for v in vehicles], dtype=object),
                   model_year=pd.array([v.model_year for v in vehicles], dtype="Int64"),
                   makers=np.array([v.manufacturer or v.make for v in vehicles], dtype=object),
                   ids=[v.vehicle_id for v in vehicles], classes=[v.vehicle_class for v in vehicles],
                   configurations=[v.configuration for v in vehicles])


class _Scenario:
    """One scenario's per-vehicle, per-budget-year arrays before calibration (rows x years)."""

    def __init__(self, s, rows: _Rows, per_condition: dict, error_model, years=None):
        """``rows``: the Vehicles rows' values (:class:`_Rows`); ``years``: per-row miles by
        budget year and fuel factors (registration turnover, fleetrun.registrations); None:
        count x annual_miles x (1 + g)^(y - 1) for every row."""
        self.s = s
        self.rows = rows
        self.count, annual, self.fuel, self.duty = rows.count, rows.annual, rows.fuel, rows.duty
        self.model_year = rows.model_year
        self.per_mile = mix_per_mile(s, self.duty, self.fuel, per_condition,
                                     None if years is None else years.fuel_factor(s), self.model_year)
        g = s.vmt_growth_pct_per_year / 100.0
        self.years = np.arange(s.budget_years)
        if years is None:
            self.miles = (self.count * annual)[:, None] * ((1.0 + g) ** self.years)[None, :]
        else:
            self.miles = np.asarray(years.year_miles(s), dtype=float)[:, :s.budget_years]
        factor = np.ones((len(self.fuel), len(self.years)))
        for name in drivers.FUELS:
            factor[self.fuel == name] = drivers.price_factor(s, name)[None, :]
        self.gpm = self.per_mile["fuel_gal"] * bias_factor(self.duty, self.fuel, error_model)
        self.raw = self.miles * self.gpm[:, None] * factor      # on-road, bias-corrected, priced

    def base_year_gallons(self, fuel: str, group: str = "all") -> float:
        """Modelled gallons of ``fuel`` in the first budget year, of all rows or of a class group
        (``LD``: light duty; ``HD``: medium and heavy duty)."""
        rows = self.fuel == fuel
        if group != "all":
            rows &= (self.duty == "LD") if group == "LD" else (self.duty != "LD")
        return math.fsum(self.raw[rows, 0])


def row_scale(scales: dict, fuel: np.ndarray, duty: np.ndarray) -> np.ndarray:
    """Each row's calibration factor: its fuel and class group's (``scales[(fuel, "LD"|"HD")]``),
    else its fuel's (``scales[(fuel, "all")]``), else 1.

    Parameters
    ----------
    scales : dict, (fuel, ``all`` | ``LD`` | ``HD``) -> calibration factor [-]
    fuel : array of str, each row's fuel
    duty : array of str, each row's duty class

    Returns
    -------
    calibration factor [-] per row.
    """
    fuel = np.asarray(fuel)
    light = np.asarray(duty) == "LD"
    out = np.ones(len(fuel))
    for f in dict.fromkeys(fuel.tolist()):   # each fuel and class group once, not each row
        of_fuel = fuel == f
        for g, rows in (("LD", of_fuel & light), ("HD", of_fuel & ~light)):
            out[rows] = scales.get((f, g), scales.get((f, "all"), 1.0))
    return out


def calibrated_fuels(scales: dict) -> set:
    """The fuels that have a calibration factor (of any class group).

    Parameters
    ----------
    scales : dict, (fuel, class group) -> calibration factor [-]

    Returns
    -------
    set of str, the fuels.
    """
    return {fuel for fuel, _ in scales}


def fit_calibration(prepared: list, warnings: list) -> tuple[dict[tuple, float], pd.DataFrame]:
    """One factor per fuel (or per fuel and class group where the observed gallons are split
    into light duty and medium/heavy duty): observed / modelled gallons of the base fiscal year
    of the first scenario that gives observed gallons and says calibrate_to_observed = yes; and
    one row per scenario x fuel (x group) with observed gallons (the ratio reported, a warning
    outside the band). Keys: (fuel, "all" | "LD" | "HD").

    Parameters
    ----------
    prepared : list of _Scenario, the prepared scenarios
    warnings : list of str, receives a warning for a ratio outside the band

    Returns
    -------
    (dict (fuel, group) -> factor [-], DataFrame with one row per scenario x fuel (x group)).
    """
    scales: dict[tuple, float] = {}
    fitted_on: dict[str, str] = {}
    rows = []
    for p in prepared:
        s = p.s
        for name in drivers.FUELS:
            split = s.observed_split(name)
            parts = split.items() if split else [("all", s.observed_base_gallons(name))]
            for group, observed in parts:
                if observed is not None:
                    rows.append(_calibrate_one(p, name, group, observed, scales, fitted_on, warnings))
    table = pd.DataFrame(rows, columns=CALIBRATION_COLUMNS)
    key = list(zip(table.fuel, table.class_group))
    table["calibrated"] = ["yes" if k in scales else "no" for k in key]
    table["scale"] = [scales.get(k, 1.0) for k in key]
    table["fitted_on"] = [fitted_on.get(f, "") for f in table.fuel]
    return scales, table


def _calibrate_one(p, name: str, group: str, observed: float, scales: dict, fitted_on: dict, warnings: list) -> dict:
    """Fit (fuel, group)'s factor on scenario ``p`` if it is the first to say yes; its table row."""
    s = p.s
    band = budget.constants()["calibration"]["plausible_model_to_observed"]
    model = p.base_year_gallons(name, group)
    ratio = model / observed
    what = name if group == "all" else f"{name} ({'light duty' if group == 'LD' else 'medium/heavy duty'})"
    if s.calibrate_to_observed and fitted_on.get(name, s.scenario_id) == s.scenario_id and model > 0:
        scales[(name, group)], fitted_on[name] = observed / model, s.scenario_id
        if not band[0] <= ratio <= band[1]:
            warnings.append(f"calibration: the model's {what} gallons are {ratio:.0%} of the observed "
                            f"{observed:,.0f} gal (scenario {s.scenario_id}, base fiscal year "
                            f"{budget.fiscal_years(s)[0]}); outside the plausible {band[0]:.0%}-"
                            f"{band[1]:.0%}: check the vehicles, miles and the year of the collections")
    elif s.calibrate_to_observed and model <= 0 and fitted_on.get(name, s.scenario_id) == s.scenario_id:
        warnings.append(f"calibration: scenario {s.scenario_id} gives observed {what} gallons ({observed:,.0f}), "
                        f"but the fleet has no such gallons; they calibrate nothing (check the fuel and duty class "
                        f"of the vehicles, or the column)")
    elif s.calibrate_to_observed and fitted_on.get(name) not in (None, s.scenario_id):
        warnings.append(f"calibration: scenario {s.scenario_id}'s observed {what} gallons are not used; "
                        f"the factor is fitted once, on scenario {fitted_on[name]}, and applies to all")
    return {"scenario_id": s.scenario_id, "fuel": name, "class_group": group,
            "fiscal_year": budget.fiscal_years(s)[0], "model_gallons": model, "observed_gallons": observed,
            "model_to_observed": ratio}


def _ratios(per_mile: dict, miles_total: np.ndarray, gallons: np.ndarray, energy: dict) -> dict:
    with np.errstate(divide="ignore", invalid="ignore"):
        # A row with no miles still gets its per-vehicle mpg and efficiencies.
        return {
            "mpg": np.where(miles_total > 0, miles_total / gallons, 1.0 / per_mile["fuel_gal"]),
            "diff_efficiency": np.where(energy["diff_input_energy_J"] > 0,
                                        energy["diff_output_energy_J"] / energy["diff_input_energy_J"],
                                        per_mile["diff_output_energy_J"] / per_mile["diff_input_energy_J"]),
            "drivetrain_efficiency": np.where(energy["drivetrain_input_energy_J"] > 0,
                                              energy["wheel_energy_J"] / energy["drivetrain_input_energy_J"],
                                              per_mile["wheel_energy_J"] / per_mile["drivetrain_input_energy_J"]),
        }


def _yearly(p: _Scenario, vehicles, scales: dict, ratios: dict) -> dict[str, np.ndarray]:
    """Per vehicle and budget year: miles, gallons, range, kWh, taxes, fees (rows x years)."""
    s, fuel = p.s, p.fuel
    gallons = p.raw * row_scale(scales, fuel, p.duty)[:, None]
    low, high = gallons.copy(), gallons.copy()       # rows without gallons (electric): 0
    for name, found in ratios.items():
        rows = fuel == name
        low[rows], high[rows] = gallons[rows] * found.low[None, :], gallons[rows] * found.high[None, :]
    state = np.zeros_like(gallons)
    federal = np.zeros_like(gallons)
    for name in drivers.FUELS:
        rows = fuel == name
        state[rows] = gallons[rows] * drivers.state_rates(s, name)[None, :]
        federal[rows] = gallons[rows] * drivers.federal_rates(s, name)[None, :]
    fee = np.where(fuel == ELECTRIC, p.count * s.ev_fee_usd_per_vehicle_year, 0.0)
    return {"miles": p.miles, "fuel_gal": gallons, "fuel_gal_low": low, "fuel_gal_high": high,
            "kwh": p.miles * p.per_mile["kwh"][:, None], "state_tax_usd": state, "federal_tax_usd": federal,
            "ev_fee_usd": np.repeat(fee[:, None], len(p.years), axis=1)}


def _total(values: np.ndarray) -> np.ndarray:
    """Row sums over the budget years (the fiscal rows are reconciled to these sums to the
    last bit by :func:`fleetrun.budget.arithmetic.exact_parts`)."""
    return values.sum(axis=1) if values.size else np.zeros(len(values))


def _tax_total(gallons: np.ndarray, yearly: np.ndarray, fuel: np.ndarray, rates, s) -> np.ndarray:
    """Tax over the budget years: gallons x the rate where the rate is one for all years (so
    that tax = gallons x rate exactly), else the exact sum of the years."""
    out = _total(yearly)
    for name in drivers.FUELS:
        per_year = rates(s, name)
        if np.all(per_year == per_year[0]):
            rows = fuel == name
            out[rows] = gallons[rows] * per_year[0]
    return out


def scenario_frame(p: _Scenario, vehicles, scales: dict, ratios: dict) -> tuple[pd.DataFrame, dict]:
    """One row per vehicle for a prepared scenario, and its per-year arrays.

    Parameters
    ----------
    p : _Scenario, a prepared scenario
    vehicles : sequence of VehicleSpec, the Vehicles rows
    scales : dict, (fuel, group) -> calibration factor [-]
    ratios : dict, fuel -> its fuel range (fleetrun.budget.ranges.fuel_ranges)

    Returns
    -------
    (DataFrame with one row per vehicle (results.csv columns), dict of per-year arrays (rows x years)).
    """
    s, fuel, count = p.s, p.fuel, p.count
    yearly = _yearly(p, vehicles, scales, ratios)
    miles_total = _total(p.miles)
    gallons = _total(yearly["fuel_gal"])
    energy = {name: miles_total * p.per_mile[name] for name in ENERGY_FIELDS}
    frame = pd.DataFrame({
        "scenario_id": s.scenario_id, "vehicle_id": p.rows.ids, "vehicle_class": p.rows.classes,
        "configuration": p.rows.configurations, "fuel": fuel.astype(str),
        "count": _whole_if_possible(count), "miles_total": miles_total, "fuel_gal_total": gallons,
        **_ratios(p.per_mile, miles_total, gallons, energy),
        "state_tax_usd": _tax_total(gallons, yearly["state_tax_usd"], fuel, drivers.state_rates, s),
        "federal_tax_usd": _tax_total(gallons, yearly["federal_tax_usd"], fuel, drivers.federal_rates, s),
        **energy, "duty_class": p.duty.astype(str), "fuel_gal_cycle_total": miles_total * p.per_mile["fuel_gal_cycle"],
        "fuel_gal_uncalibrated_total": _total(p.raw), "fuel_gal_low_total": _total(yearly["fuel_gal_low"]),
        "fuel_gal_high_total": _total(yearly["fuel_gal_high"]), "kwh_total": _total(yearly["kwh"]),
        "ev_fee_usd": _total(yearly["ev_fee_usd"]), "model_year": p.model_year,
    })
    frame.loc[fuel == ELECTRIC, "mpg"] = np.nan   # no gallons: kwh_total instead
    return frame, yearly


def _range_spec(p: _Scenario, error_model, scales: dict, warnings: list) -> tuple[dict, dict]:
    """The Monte Carlo's central gallons per (fuel, duty) and year, and its settings."""
    from fleetrun.budget.ranges import DUTIES

    gallons = p.raw * row_scale(scales, p.fuel, p.duty)[:, None]
    makers = p.rows.makers
    central, sd = {}, {}
    for fuel in drivers.FUELS:
        for duty in DUTIES:
            rows = (p.fuel == fuel) & ((p.duty == "LD") if duty == "LD" else (p.duty != "LD"))
            if not rows.any():
                continue
            central[(fuel, duty)] = gallons[rows].sum(axis=0)
            model = error_model.for_duty(duty) if error_model is not None else None
            sd[(fuel, duty)] = (*model.scales(gallons[rows].sum(axis=1), makers[rows]), model.df, model) if model else (
                0.0, 0.0, np.inf, None)
    short, long = drivers.elasticities(p.s)
    spec = {"u": drivers.uncertainty(), "years": len(p.years), "growth": p.s.vmt_growth_pct_per_year / 100.0,
            "short": short, "long": long, "calibrated": calibrated_fuels(scales), "model_error": sd,
            "observed_sd": budget.constants()["calibration"]["observed_relative_sd"]}
    return central, spec


def aggregate_vehicles(vehicles: Sequence, scenarios: Sequence, per_condition: dict,
                       error_model=None, years=None) -> "BudgetTables":
    """One row per scenario x vehicle (budget totals over ``count`` vehicles and budget years),
    the per-year arrays, the calibration table, the ranges and the tornado rows.

    Parameters
    ----------
    vehicles : sequence of VehicleSpec, the Vehicles rows
    scenarios : sequence of Scenario, the scenarios
    per_condition : dict, (cycle, ambient [C]) -> the simulation's per-vehicle sums
    error_model : ErrorModel or None, the fleet-level error (None: no ranges)
    years : FleetYears or None, per-row miles by budget year and fuel factors
        (fleetrun.registrations.expand; None: count x annual miles x growth)

    Returns
    -------
    BudgetTables, results, per-year arrays, calibration, ranges, period ranges, tornado and warnings.
    """
    from fleetrun.budget import ranges

    warnings: list[str] = []
    rows = _Rows.of(vehicles)
    prepared = [_Scenario(s, rows, per_condition, error_model, years) for s in scenarios]
    scales, calibration_table = fit_calibration(prepared, warnings)
    u = drivers.uncertainty()
    z = ranges.standard_normals(int(u["monte_carlo_samples"]), int(u["seed"]))
    frames, yearly, fuel_ranges, tornado, period = [], {}, {}, [], {}
    for p in prepared:
        central, spec = _range_spec(p, error_model, scales, warnings)
        found = ranges.fuel_ranges(central, z, spec)
        fuel_ranges.update({(p.s.scenario_id, name): r for name, r in found.items()})
        frame, yearly[p.s.scenario_id] = scenario_frame(p, vehicles, scales,
                                                        {k: v for k, v in found.items() if k != "all"})
        frames.append(frame)
        rates = {f: drivers.state_rates(p.s, f) for f in drivers.FUELS}
        period[p.s.scenario_id] = ranges.period_range(central, z, spec, rates,
                                                      {f: drivers.federal_rates(p.s, f) for f in drivers.FUELS})
        tornado += [{"scenario_id": p.s.scenario_id, **row} for row in ranges.tornado(central, spec, rates)]
    if error_model is not None and any(d != "LD" for d in (v.duty_class for v in vehicles)):
        warnings += list(error_model.warnings)
    results = pd.concat(frames, ignore_index=True)[RESULTS_COLUMNS] if frames else pd.DataFrame(columns=RESULTS_COLUMNS)
    return BudgetTables(results=results, yearly=yearly, calibration=calibration_table, ranges=fuel_ranges, period_ranges=period,
                        tornado=pd.DataFrame(tornado, columns=TORNADO_COLUMNS), warnings=warnings)


def _whole_if_possible(values: np.ndarray) -> np.ndarray:
    """Counts as integers (``1000``, not ``1000.0``) unless some are fractional."""
    if np.all(np.isfinite(values)) and np.all(values == np.round(values)) and np.all(np.abs(values) < 2**53):
        return values.astype(np.int64)
    return values


def _ratio(numerator: float, denominator: float) -> float:
    return numerator / denominator if denominator > 0 else float("nan")


def _fsum(values) -> float:
    """fsum that stays NaN when any value is NaN (a range that was not measured)."""
    array = np.asarray(values, dtype=float)
    return math.nan if np.isnan(array).any() else math.fsum(array.tolist())


def aggregate_classes(results: pd.DataFrame) -> pd.DataFrame:
    """One row per scenario x vehicle_class: exact sums of the vehicle rows.

    Parameters
    ----------
    results : DataFrame, the vehicle rows (:func:`aggregate_vehicles`)

    Returns
    -------
    DataFrame, one row per scenario x vehicle class (miles [mi], gallons [gal], taxes [$], mpg).
    """
    rows = []
    for (scenario_id, vehicle_class), group in results.groupby(["scenario_id", "vehicle_class"], sort=False):
        total = {name: _fsum(group[name]) for name in
                 ("count", "miles_total", "fuel_gal_total", "state_tax_usd", "federal_tax_usd",
                  "fuel_gal_low_total", "fuel_gal_high_total", "kwh_total", "ev_fee_usd") + ENERGY_FIELDS}
        fuel_miles = math.fsum(group["miles_total"][group["fuel"] != ELECTRIC])
        rows.append({
            "scenario_id": scenario_id, "vehicle_class": vehicle_class,
            "vehicles": int(total["count"]) if group["count"].dtype.kind == "i" else total["count"],
            "miles_total": total["miles_total"], "fuel_gal_total": total["fuel_gal_total"],
            "mpg": _ratio(fuel_miles, total["fuel_gal_total"]),   # miles of fuel-burning vehicles
            "diff_efficiency": _ratio(total["diff_output_energy_J"], total["diff_input_energy_J"]),
            "state_tax_usd": total["state_tax_usd"], "federal_tax_usd": total["federal_tax_usd"],
            "drivetrain_efficiency": _ratio(total["wheel_energy_J"], total["drivetrain_input_energy_J"]),
            "vehicle_types": len(group), "fuel_gal_low_total": total["fuel_gal_low_total"],
            "fuel_gal_high_total": total["fuel_gal_high_total"], "kwh_total": total["kwh_total"],
            "ev_fee_usd": total["ev_fee_usd"],
        })
    return pd.DataFrame(rows, columns=CLASS_COLUMNS)


SCENARIO_TOTAL_COLUMNS = ["scenario_id", "vehicles", "miles_total", "fuel_gal_total", "fuel_gal_low_total",
                          "fuel_gal_high_total", "mpg", "state_tax_usd", "federal_tax_usd", "total_tax_usd",
                          "kwh_total", "ev_fee_usd"]


def scenario_totals(classes: pd.DataFrame) -> pd.DataFrame:
    """One row per scenario: the fleet totals (sums of the class rows).

    Parameters
    ----------
    classes : DataFrame, the class rows (:func:`aggregate_classes`)

    Returns
    -------
    DataFrame, one row per scenario.
    """
    rows = []
    for scenario_id, group in classes.groupby("scenario_id", sort=False):
        miles = math.fsum(group["miles_total"])
        gallons = math.fsum(group["fuel_gal_total"])
        state = math.fsum(group["state_tax_usd"])
        federal = math.fsum(group["federal_tax_usd"])
        burned = group["mpg"] * group["fuel_gal_total"]          # miles of fuel-burning vehicles
        rows.append({"scenario_id": scenario_id, "vehicles": math.fsum(group["vehicles"]),
                     "miles_total": miles, "fuel_gal_total": gallons,
                     "fuel_gal_low_total": _fsum(group["fuel_gal_low_total"]),
                     "fuel_gal_high_total": _fsum(group["fuel_gal_high_total"]),
                     "mpg": _ratio(math.fsum(burned[np.isfinite(burned)]), gallons), "state_tax_usd": state,
                     "federal_tax_usd": federal, "total_tax_usd": state + federal,
                     "kwh_total": math.fsum(group["kwh_total"]), "ev_fee_usd": math.fsum(group["ev_fee_usd"])})
    return pd.DataFrame(rows, columns=SCENARIO_TOTAL_COLUMNS)


def _fiscal_group(s, fuel: str, vehicle_class: str, group: pd.DataFrame, yearly: dict) -> list[dict]:
    """The fiscal-year rows of one scenario x fuel x class: the group's per-year sums, the last
    year moved by a few units in the last place so that they add up to the results exactly."""
    years = budget.fiscal_years(s)
    rows = [{"scenario_id": s.scenario_id, "fiscal_year": year, "fuel": fuel, "vehicle_class": vehicle_class}
            for year in years]
    positions = group["_position"].to_numpy()
    for column, source in FISCAL_SOURCES.items():
        total = _fsum(group[source]) if source in group else 0.0
        per_year = [_fsum(yearly[column][positions, y]) for y in range(len(years))]
        parts = budget.exact_parts(per_year, total) if math.isfinite(total) else [math.nan] * len(years)
        for row, value in zip(rows, parts):
            row[column] = value
    for row in rows:
        row["co2_t"] = float(budget.co2_t(row["fuel_gal"], fuel))
    return rows


def fiscal_summary(results: pd.DataFrame, scenarios: Sequence, yearly: dict) -> pd.DataFrame:
    """One row per scenario x fiscal year x fuel x vehicle class (fiscal_summary.csv).

    Parameters
    ----------
    results : DataFrame, the vehicle rows
    scenarios : sequence of Scenario, the scenarios (their order is kept)
    yearly : dict, scenario id -> per-year arrays (:func:`scenario_frame`)

    Returns
    -------
    DataFrame, the fiscal_summary.csv rows.
    """
    rows = []
    for s in scenarios:
        own = results[results.scenario_id == s.scenario_id]
        own = own.assign(_position=np.arange(len(own)))
        for (fuel, vehicle_class), group in own.groupby(["fuel", "vehicle_class"], sort=False):
            rows += _fiscal_group(s, fuel, vehicle_class, group, yearly[s.scenario_id])
    frame = pd.DataFrame(rows, columns=FISCAL_COLUMNS)
    return frame.sort_values(["fiscal_year"], kind="stable").pipe(
        lambda f: f.iloc[np.argsort(f.scenario_id.map({s.scenario_id: i for i, s in enumerate(scenarios)}).to_numpy(),
                                    kind="stable")]).reset_index(drop=True)


def yearly_totals(fiscal: pd.DataFrame) -> pd.DataFrame:
    """Per scenario and fiscal year: the fleet's miles, gallons, CO2, kWh and revenue (exact
    sums of the fiscal_summary rows).

    Parameters
    ----------
    fiscal : DataFrame, the fiscal_summary rows (:func:`fiscal_summary`)

    Returns
    -------
    DataFrame, one row per scenario x fiscal year (miles [mi], gallons [gal], CO2 [t], kWh, revenue [$]).
    """
    columns = ["miles", "fuel_gal", "fuel_gal_low", "fuel_gal_high", "co2_t", "kwh", "state_tax_usd",
               "federal_tax_usd", "ev_fee_usd"]
    rows = []
    for (scenario_id, year), group in fiscal.groupby(["scenario_id", "fiscal_year"], sort=False):
        rows.append({"scenario_id": scenario_id, "fiscal_year": int(year),
                     **{c: _fsum(group[c]) for c in columns}})
    return pd.DataFrame(rows, columns=["scenario_id", "fiscal_year"] + columns)


CHANGE_COLUMNS = ["scenario_id", "fiscal_year", "miles", "fuel_gal", "gal_per_mile", "mpg", "change_gal",
                  "change_from_vmt_gal", "change_from_gal_per_mile_gal"]


def change_decomposition(fiscal: pd.DataFrame) -> pd.DataFrame:
    """Per scenario and fiscal year, the fleet's fuel-burning miles, gallons and gallons per
    mile, and the change in gallons from the year before split exactly into VMT
    (change in miles x last year's gallons per mile) and gallons per mile (this year's miles x
    the change in gallons per mile: turnover, the fleet's mix of model years).

    Parameters
    ----------
    fiscal : DataFrame, the fiscal_summary rows (:func:`fiscal_summary`)

    Returns
    -------
    DataFrame, one row per scenario x fiscal year (miles [mi], gallons [gal], gal/mi, mpg and the
    change split into VMT and gallons per mile [gal]).
    """
    burning = fiscal[fiscal["fuel"] != ELECTRIC]
    rows = []
    for scenario_id, group in burning.groupby("scenario_id", sort=False):
        previous = None
        for year, part in group.groupby("fiscal_year", sort=True):
            miles, gallons = math.fsum(part["miles"]), math.fsum(part["fuel_gal"])
            gpm = gallons / miles if miles > 0 else math.nan
            row = {"scenario_id": scenario_id, "fiscal_year": int(year), "miles": miles, "fuel_gal": gallons,
                   "gal_per_mile": gpm, "mpg": 1.0 / gpm if gpm else math.nan,
                   "change_gal": math.nan, "change_from_vmt_gal": math.nan, "change_from_gal_per_mile_gal": math.nan}
            if previous is not None:
                row["change_gal"] = gallons - previous["fuel_gal"]
                row["change_from_vmt_gal"] = (miles - previous["miles"]) * previous["gal_per_mile"]
                row["change_from_gal_per_mile_gal"] = miles * (gpm - previous["gal_per_mile"])
            rows.append(row)
            previous = row
    return pd.DataFrame(rows, columns=CHANGE_COLUMNS)
