"""Why the model's light-duty fleet loses mpg over 2000-2008: the candidates pre-registered in
docs/validation-state-fuel.md ("Why the model's fleet loses mpg over 2000-2008"), measured.

    python validation/turnover_candidates.py [--candidates shipped,H1a,...] [--years 2000,2003]

For each candidate the issue's national workbook (the states' summed MV-1 counts and VM-2 miles,
``inputs/state_statistics/national_sum_years.csv``; ``cycle_mix = default``; uncalibrated) is
run over the base year and the next, and reports the national gasoline error against the
states' summed MF-21, the light-duty fleet's mpg change per year and the automobile / light
truck mpg. Candidates change only how a cohort's model year scales its simulated vehicle's fuel
(``fleetrun.registrations.turnover``), each from EPA Automotive Trends' own columns
(``inputs/epa_trends/trends_2022_light_duty.csv``, PROVENANCE.md there):

- ``shipped``: the default as the code has it now (H2e since 2026-11-25; the table's "present"
  row of docs/validation-state-fuel.md is this candidate at commit 270a407, the default before);
- ``rw_all``: the shipped rule on the 2022 edition's real-world "all" column (edition check);
- ``H1a``: the 2-cycle (lab) "all" column, the label formula's shortfall for every vintage;
- ``H1b``: H1a and the calendar year's share of Trends' phase-in of the shortfall,
  light-duty fuel x r(2005) / r(y) in calendar year y <= 2004 (r = real-world / 2-cycle of the
  "all" rows of model year y);
- ``H2``: the real-world car column for automobiles, the truck column for light trucks;
- ``H2lab``: the 2-cycle car / truck columns (H1a per class);
- ``H3``: miles per vehicle flat over age (OMEGA's curves' survival-weighted mean), on the
  shipped default;
- ``H4``: ``rw_all`` with the electric vehicles taken out of every model year (the library's
  MY2022 vehicles are non-electric); ``H1ae``, ``H2e``, ``H2labe``: H1a, H2, H2lab likewise;
- ``M2``: the shipped default with the base year's age distribution of automobiles and light
  trucks from the model years' own sales, P(B - a) x S(a) normalised, P Trends' car / truck
  production (``inputs/epa_trends/trends_2022_production.csv``; before 1975, 1975's) in place of
  the constant-sales steady state (docs/validation-state-fuel.md, pre-registration M2).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "validation"))

import state_fuel  # noqa: E402  (the issue's workbook, its one owner)

sys.path.insert(0, str(ROOT / "models" / "vehicle_library"))
import make_trends  # noqa: E402  (the non-electric Trends tables, their one owner)

import importlib  # noqa: E402

from fleetrun.registrations import turnover  # noqa: E402

expand = importlib.import_module("fleetrun.registrations.expand")   # the module (the package exports a function of that name)

NATIONAL = ROOT / "inputs" / "state_statistics" / "national_sum_years.csv"
LIGHT_DUTY = ("automobile", "light_truck")
CANDIDATES = ("shipped", "rw_all", "H1a", "H1b", "H2", "H2lab", "H3", "H4", "H1ae", "H2e", "H2labe", "M2")
PRODUCTION = ROOT / "inputs" / "epa_trends" / "trends_2022_production.csv"
TRENDS_CLASS = {"automobile": "car", "light_truck": "truck"}
PHASE_IN_END = 2005        # Trends: shortfall phased in over MY1986-2004, derived 5-cycle from 2005


def trends(column: str, regulatory_class: str, electric: bool = True) -> pd.Series:
    """One Trends column of one regulatory class (index: model year); ``electric=False``: the
    non-electric vehicles' harmonic mean (models/vehicle_library/make_trends.py, its one owner)."""
    return make_trends.nonelectric_mpg(regulatory_class, column, electric)


def _ratio_factor(series: pd.Series):
    years, mpg = series.index.to_numpy(float), series.to_numpy(float)

    def factor(model_years, reference_years):
        at = lambda y: np.interp(np.asarray(y, float), years, mpg)   # noqa: E731  (clipped at the ends)
        return at(reference_years) / at(model_years)
    return factor


def fuel_factor_for(candidate: str):
    """The candidate's ``turnover.fuel_factor`` (None: the shipped one)."""
    column = {"rw_all": "real_world_mpg", "H1a": "two_cycle_mpg", "H1b": "two_cycle_mpg",
              "H2": "real_world_mpg", "H2lab": "two_cycle_mpg", "H4": "real_world_mpg",
              "H1ae": "two_cycle_mpg", "H2e": "real_world_mpg", "H2labe": "two_cycle_mpg"}.get(candidate)
    if column is None:
        return None
    per_class, electric = candidate.startswith("H2"), not (candidate == "H4" or candidate.endswith("e"))
    tables = {c: _ratio_factor(trends(column, {"automobile": "car", "light_truck": "truck"}[c] if per_class else "all",
                                      electric)) for c in LIGHT_DUTY}
    shipped = turnover.fuel_factor

    def fuel_factor(fhwa_class, model_years, reference_years, future_rate=None):
        if fhwa_class not in tables:
            return shipped(fhwa_class, model_years, reference_years, future_rate)
        return tables[fhwa_class](model_years, reference_years)
    return fuel_factor


def calendar_phase_in(year: int) -> float:
    """H1b: on-road fuel of calendar year ``year`` relative to the label formula's (r(2005) / r(y))."""
    r = trends("real_world_mpg", "all") / trends("two_cycle_mpg", "all")
    return float(r[PHASE_IN_END] / r[min(max(year, int(r.index.min())), PHASE_IN_END)])


def production_age_distribution(fhwa_class: str, base: int) -> np.ndarray:
    """M2: share of the class's vehicles at age 0..max_age in ``base``, P(base - a) x S(a)
    normalised, P Trends' production of the model year (the first year's before it)."""
    table = pd.read_csv(PRODUCTION)
    table = table[table.regulatory_class == TRENDS_CLASS[fhwa_class]].set_index("model_year").production_thousand
    survival = turnover.survival(fhwa_class)
    years = base - np.arange(len(survival))
    sold = table.reindex(np.clip(years, table.index.min(), table.index.max())).to_numpy(float)
    weights = sold * survival
    return weights / weights.sum()


def _m2_model_years(shipped):
    def model_years(row, fhwa_class, base):
        if row.get("model_year") is not None or fhwa_class not in TRENDS_CLASS:
            return shipped(row, fhwa_class, base)
        shares = production_age_distribution(fhwa_class, base)
        return base - np.arange(len(shares)), shares, "age distribution from Trends' production (candidate M2)"
    return model_years


@contextmanager
def candidate_patch(candidate: str):
    """The candidate's turnover functions in place for the duration."""
    saved = turnover.fuel_factor, turnover.miles_by_age
    saved_years = expand._model_years
    if candidate == "M2":
        expand._model_years = _m2_model_years(saved_years)
    factor = fuel_factor_for(candidate)
    if factor is not None:
        turnover.fuel_factor = factor
    if candidate == "H3":
        curve = saved[1]

        def flat(fhwa_class):
            m, s = curve(fhwa_class), turnover.survival(fhwa_class)
            return np.full(len(m), float((m * s).sum() / s.sum()))
        turnover.miles_by_age = flat
    try:
        yield
    finally:
        turnover.fuel_factor, turnover.miles_by_age = saved
        expand._model_years = saved_years


def run_year(candidate: str, row: pd.Series, later: pd.Series, folder: Path) -> dict:
    """The national workbook over ``row.year`` and ``later.year`` under ``candidate``."""
    from fleetrun.run.runner import run_fleet
    from fleetrun.workbook import read_fleet

    growth = 100 * (later.vmt_million_mi / row.vmt_million_mi - 1)
    path = state_fuel.workbook(folder / f"us-{row.year}-{candidate}.xlsx", row, 2, growth)
    with candidate_patch(candidate):
        fiscal = run_fleet(read_fleet(path), error_model=None).fiscal.copy()
    if candidate == "H1b":
        ld = fiscal.vehicle_class.isin(LIGHT_DUTY)
        fiscal.loc[ld, "fuel_gal"] *= fiscal.loc[ld, "fiscal_year"].map(calendar_phase_in)
    base = int(row.year)
    first = fiscal[fiscal.fiscal_year == base]
    gasoline = first[first.fuel == "gasoline"].fuel_gal.sum() / 1e6
    cls = first.groupby("vehicle_class")[["miles", "fuel_gal"]].sum()
    return {"candidate": candidate, "year": base, "gasoline_model_Mgal": gasoline,
            "gasoline_observed_Mgal": row.highway_gasoline_kgal / 1e3,
            "gasoline_error_pct": 100 * (gasoline / (row.highway_gasoline_kgal / 1e3) - 1),
            "ld_mpg_change_pct_per_year": state_fuel.light_duty_mpg_change_pct(fiscal),
            "automobile_mpg": cls.miles["automobile"] / cls.fuel_gal["automobile"],
            "light_truck_mpg": cls.miles["light_truck"] / cls.fuel_gal["light_truck"]}


def main(argv=None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--candidates", default=",".join(CANDIDATES))
    parser.add_argument("--years", default="2000,2003,2006,2008,2009,2010,2017")
    parser.add_argument("--out", type=Path, default=None, help="CSV of every run")
    args = parser.parse_args(argv)
    nation = pd.read_csv(NATIONAL).set_index("year", drop=False)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for candidate in args.candidates.split(","):
            for year in (int(y) for y in args.years.split(",")):
                row = nation.loc[year].astype(object)
                row["state"], row["special_fuels_kgal"] = "United States", float("nan")
                rows.append(run_year(candidate, row, nation.loc[year + 1], Path(tmp)))
                r = rows[-1]
                print(f"{candidate:8s} {year}: gasoline {r['gasoline_error_pct']:+.1f} %, LD mpg change "
                      f"{r['ld_mpg_change_pct_per_year']:+.2f} %/yr, automobile {r['automobile_mpg']:.2f}, "
                      f"light truck {r['light_truck_mpg']:.2f} mpg", flush=True)
    table = pd.DataFrame(rows)
    if args.out:
        table.to_csv(args.out, index=False, float_format="%.4f")
    return table


if __name__ == "__main__":
    main()
