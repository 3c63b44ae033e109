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
from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd

from fleetrun.budget import arithmetic as budget
from fleetrun.cycles import load_cycle
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
CALIBRATION_COLUMNS = ["scenario_id", "fuel", "fiscal_year", "model_gallons", "observed_gallons",
                       "model_to_observed", "calibrated", "scale"]


@lru_cache(maxsize=64)
def cycle_mean_speed_kph(cycle: str) -> float:
    """A drive cycle's distance / duration, stops included [km/h]."""
    trace = load_cycle(cycle)
    hours = float(trace.time_s[-1] - trace.time_s[0]) / 3600.0
    return float(trace.miles) * METERS_PER_MILE / 1000.0 / hours


def _cycle_kind(cycle: str) -> str:
    return budget.cycle_kind(Path(cycle).stem if cycle.lower().endswith(".csv") else cycle,
                             cycle_mean_speed_kph(cycle))


def mix_per_mile(s, duty_of: np.ndarray, fuel: np.ndarray, per_condition: dict,
                 error_model=None, fuel_factor: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Per vehicle on scenario ``s``'s mix: cycle and on-road gallons per mile, the range's
    gallons per mile, on-road kWh per mile (electric rows) and the energies per mile.
    ``fuel_factor``: each row's cycle fuel per mile relative to its simulated vehicle (a
    registration cohort's model year, docs/registrations.md); None: 1."""
    n = len(duty_of)
    adjusted = budget.label_adjusted_duty(duty_of) & (fuel != ELECTRIC)
    kwh_factor = budget.electric_onroad_factor(s.onroad_adjustment)
    names = ("fuel_gal_cycle", "fuel_gal", "fuel_gal_low", "fuel_gal_high", "kwh") + ENERGY_FIELDS
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
            low, high = error_model.relative_range(cycle, kind) if error_model else (math.nan, math.nan)
            per_mile["fuel_gal_cycle"][rows] += share * cycle_gpm
            # central value and the range's ends: cycle gallons x (1 + e), then on the road
            for name, factor in (("fuel_gal", 1.0), ("fuel_gal_low", 1.0 + low), ("fuel_gal_high", 1.0 + high)):
                onroad = budget.onroad_gal_per_mile(cycle_gpm * factor, s.onroad_adjustment, kind, adjusted[rows])
                per_mile[name][rows] += share * onroad
            per_mile["kwh"][rows] += share * kwh_factor * (sim["kwh"][rows] / miles)
            for name in ENERGY_FIELDS:
                per_mile[name][rows] += share * (sim[name][rows] / miles)
    return per_mile


def calibration(s, fuel: np.ndarray, gallons: np.ndarray, first_share=None) -> tuple[dict[str, float], list[dict]]:
    """Scale per fuel (1 unless calibrated) and one row per fuel with observed gallons:
    the first fiscal year's modelled gallons, the observed ones and their ratio.
    ``first_share``: each row's first-year share of its miles (None: the scenario's)."""
    share = budget.year_shares(s)[0] if first_share is None else first_share
    first_year = budget.fiscal_years(s)[0]
    scales: dict[str, float] = {}
    rows = []
    for name in ("gasoline", "diesel"):
        observed = s.observed_base_gallons(name)
        if observed is None:
            continue
        model = math.fsum((gallons * share)[fuel == name]) if first_share is not None else \
            math.fsum(gallons[fuel == name]) * share
        ratio = model / observed
        scale = observed / model if (s.calibrate_to_observed and model > 0) else 1.0
        scales[name] = scale
        rows.append({"scenario_id": s.scenario_id, "fuel": name, "fiscal_year": first_year,
                     "model_gallons": model, "observed_gallons": observed, "model_to_observed": ratio,
                     "calibrated": "yes" if scale != 1.0 or s.calibrate_to_observed else "no",
                     "scale": scale})
    return scales, rows


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


def scenario_frame(s, vehicles, per_condition: dict, error_model=None, years=None) -> tuple[pd.DataFrame, list[dict]]:
    """One row per vehicle for scenario ``s`` and its calibration rows. ``years``: per-row
    miles by budget year and fuel factors (registration turnover, :func:`row_years`); None:
    ``count x annual_miles x (1 + g)^(y - 1)`` for every row."""
    count = np.array([v.count for v in vehicles], dtype=float)
    annual = np.array([v.annual_miles for v in vehicles], dtype=float)
    fuel = np.array([v.fuel for v in vehicles], dtype=object)
    duty_of = np.array([v.duty_class for v in vehicles], dtype=object)
    year_miles, factor = (None, None) if years is None else (years.year_miles(s), years.fuel_factor(s))
    per_mile = mix_per_mile(s, duty_of, fuel, per_condition, error_model, factor)
    miles_total = count * annual * s.mile_factor() if year_miles is None else year_miles.sum(axis=1)
    raw = miles_total * per_mile["fuel_gal"]
    first_share = None
    if year_miles is not None:
        with np.errstate(divide="ignore", invalid="ignore"):
            first_share = np.where(miles_total > 0, year_miles[:, 0] / miles_total, 0.0)
    scales, calibration_rows = calibration(s, fuel, raw, first_share)
    scale = np.array([scales.get(f, 1.0) for f in fuel])
    gallons = raw * scale
    calibrated = scale != 1.0
    low = np.where(calibrated, gallons, miles_total * per_mile["fuel_gal_low"])
    high = np.where(calibrated, gallons, miles_total * per_mile["fuel_gal_high"])
    energy = {name: miles_total * per_mile[name] for name in ENERGY_FIELDS}
    state_rate, federal_rate = budget.tax_rates(s, fuel)
    frame = pd.DataFrame({
        "scenario_id": s.scenario_id, "vehicle_id": [v.vehicle_id for v in vehicles],
        "vehicle_class": [v.vehicle_class for v in vehicles],
        "configuration": [v.configuration for v in vehicles], "fuel": fuel.astype(str),
        "count": _whole_if_possible(count), "miles_total": miles_total, "fuel_gal_total": gallons,
        **_ratios(per_mile, miles_total, gallons, energy),
        "state_tax_usd": gallons * state_rate, "federal_tax_usd": gallons * federal_rate, **energy,
        "duty_class": duty_of.astype(str), "fuel_gal_cycle_total": miles_total * per_mile["fuel_gal_cycle"],
        "fuel_gal_uncalibrated_total": raw, "fuel_gal_low_total": low, "fuel_gal_high_total": high,
        "kwh_total": miles_total * per_mile["kwh"],
        "ev_fee_usd": np.where(fuel == ELECTRIC, count * s.ev_fee_usd_per_vehicle_year * s.budget_years, 0.0),
        "model_year": pd.array([v.model_year for v in vehicles], dtype="Int64"),
    })
    frame.loc[fuel == ELECTRIC, "mpg"] = np.nan   # no gallons: kwh_total instead
    return frame, calibration_rows


def aggregate_vehicles(vehicles: Sequence, scenarios: Sequence, per_condition: dict,
                       error_model=None, years=None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """One row per scenario x vehicle (budget totals over ``count`` vehicles and budget
    years), and the calibration table (one row per scenario x fuel with observed gallons).
    ``years``: see :func:`scenario_frame`."""
    frames, rows = [], []
    for s in scenarios:
        frame, calibration_rows = scenario_frame(s, vehicles, per_condition, error_model, years)
        frames.append(frame)
        rows += calibration_rows
    calibration_table = pd.DataFrame(rows, columns=CALIBRATION_COLUMNS)
    if not frames:
        return pd.DataFrame(columns=RESULTS_COLUMNS), calibration_table
    return pd.concat(frames, ignore_index=True)[RESULTS_COLUMNS], calibration_table


def _whole_if_possible(values: np.ndarray) -> np.ndarray:
    """Counts as integers (``1000``, not ``1000.0``) unless some are fractional."""
    if np.all(np.isfinite(values)) and np.all(values == np.round(values)) and np.all(np.abs(values) < 2**53):
        return values.astype(np.int64)
    return values


def _ratio(numerator: float, denominator: float) -> float:
    return numerator / denominator if denominator > 0 else float("nan")


def _fsum(values) -> float:
    """fsum that stays NaN when any value is NaN (a range that was not measured)."""
    values = np.asarray(values, dtype=float)
    return math.nan if np.isnan(values).any() else math.fsum(values.tolist())


def aggregate_classes(results: pd.DataFrame) -> pd.DataFrame:
    """One row per scenario x vehicle_class: exact sums of the vehicle rows."""
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
    """One row per scenario: the fleet totals (sums of the class rows)."""
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


def _fiscal_group(s, fuel: str, vehicle_class: str, group: pd.DataFrame, row_shares=None) -> list[dict]:
    """The fiscal-year rows of one scenario x fuel x class: shares of the group's totals
    (``row_shares``: each row's own shares of its miles by year, registration turnover)."""
    years = budget.fiscal_years(s)
    shares = budget.year_shares(s)
    rows = [{"scenario_id": s.scenario_id, "fiscal_year": year, "fuel": fuel, "vehicle_class": vehicle_class}
            for year in years]
    for column, source in FISCAL_SOURCES.items():
        total = _fsum(group[source]) if source in group else 0.0
        # fees are per vehicle-year (even over the years); everything else follows the miles
        weights = np.full(len(years), 1.0 / len(years)) if column == "ev_fee_usd" else shares
        if row_shares is not None and column != "ev_fee_usd" and source in group and math.isfinite(total):
            mine = row_shares[group.index.to_numpy()][:, :len(years)]
            parts = budget.exact_parts(group[source].to_numpy(dtype=float) @ mine, total)
        elif math.isfinite(total):
            parts = budget.exact_parts(total * weights, total)
        else:
            parts = [math.nan] * len(years)
        for row, value in zip(rows, parts):
            row[column] = value
    for row in rows:
        row["co2_t"] = float(budget.co2_t(row["fuel_gal"], fuel))
    return rows


def row_year_shares(results: pd.DataFrame, scenarios: Sequence, vehicles, years) -> np.ndarray | None:
    """Per results row, its miles' shares by budget year (registration turnover), aligned
    with ``results``' index; None without ``years``."""
    if years is None:
        return None
    width = max(s.budget_years for s in scenarios)
    out = np.zeros((len(results), width))
    for k, s in enumerate(scenarios):
        year_miles = years.year_miles(s)
        total = year_miles.sum(axis=1, keepdims=True)
        with np.errstate(divide="ignore", invalid="ignore"):
            shares = np.where(total > 0, year_miles / total, budget.year_shares(s)[None, :])
        out[k * len(vehicles):(k + 1) * len(vehicles), :s.budget_years] = shares
    return out


def fiscal_summary(results: pd.DataFrame, scenarios: Sequence, row_shares=None) -> pd.DataFrame:
    """One row per scenario x fiscal year x fuel x vehicle class (fiscal_summary.csv).
    ``row_shares``: :func:`row_year_shares` (None: every row follows the scenario's years)."""
    rows = []
    by_id = {s.scenario_id: s for s in scenarios}
    for (scenario_id, fuel, vehicle_class), group in results.groupby(
            ["scenario_id", "fuel", "vehicle_class"], sort=False):
        rows += _fiscal_group(by_id[scenario_id], fuel, vehicle_class, group, row_shares)
    frame = pd.DataFrame(rows, columns=FISCAL_COLUMNS)
    order = {s.scenario_id: i for i, s in enumerate(scenarios)}
    frame["_order"] = frame["scenario_id"].map(order)
    return frame.sort_values(["_order", "fiscal_year"], kind="stable").drop(columns="_order").reset_index(drop=True)


def yearly_totals(fiscal: pd.DataFrame) -> pd.DataFrame:
    """Per scenario and fiscal year: the fleet's miles, gallons, CO2, kWh and revenue (exact
    sums of the fiscal_summary rows)."""
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
    the change in gallons per mile: turnover, the fleet's mix of model years)."""
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
