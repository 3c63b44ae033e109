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
  the constant-sales steady state (docs/validation-state-fuel.md, pre-registration M2);
- ``M5``: the shipped default with the entering model years' own volumes: model year y of
  automobiles (light trucks) enters k x P(y), P Trends' car (truck) production, k = N / sum_a
  P(B - a) S(a) the base-year stock N of the class and fuel read as survived production; after
  the table (MY2021) the scrapped vehicles are replaced, the stock kept at the previous year's
  count (docs/validation-state-fuel.md, pre-registration M5). ``--state-years`` runs it on
  validation/state_fuel.py's MV-1 state-years and judges every period as
  validation/gasoline_by_year.py does.
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
CANDIDATES = ("shipped", "rw_all", "H1a", "H1b", "H2", "H2lab", "H3", "H4", "H1ae", "H2e", "H2labe", "M2", "M5")
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


def production(fhwa_class: str) -> pd.Series:
    """Trends' production [thousand] of the class's regulatory class by model year."""
    table = pd.read_csv(PRODUCTION)
    return table[table.regulatory_class == TRENDS_CLASS[fhwa_class]].set_index("model_year").production_thousand


def production_scale(fhwa_class: str, base: int, stock: float) -> float:
    """M5: k = N / sum_a P(base - a) S(a), vehicles of the state per vehicle produced."""
    table = production(fhwa_class)
    survival = turnover.survival(fhwa_class)
    years = np.clip(base - np.arange(len(survival)), table.index.min(), table.index.max())
    return stock / float((table.reindex(years).to_numpy(float) * survival).sum())


def entering(fhwa_class: str, base: int, total: np.ndarray, kept: np.ndarray, j: int) -> tuple[float, str]:
    """M5: vehicles of model year base + j entering, and the rule that gave them."""
    if fhwa_class in TRENDS_CLASS:
        table = production(fhwa_class)
        if base + j in table.index:
            return production_scale(fhwa_class, base, total[0]) * float(table[base + j]), "Trends production (M5)"
    return max(kept[j - 1] - kept[j], 0.0), "replacement of the scrapped (M5, after the table)"


def m5_new_sales(acc, keys, counts0, h) -> None:
    """M5's ``expand._new_sales``: the shipped function's loop with :func:`entering`."""
    base = acc.base
    ages0 = np.array([max(base - k[3], 0) for k in keys])
    stock = expand._cohort_counts([k[1] for k in keys], ages0, counts0, h)
    groups: dict[tuple, np.ndarray] = {}
    for i, k in enumerate(keys):
        groups[(k[1], k[2])] = groups.get((k[1], k[2]), np.zeros(h)) + stock[i]
    for (fhwa_class, fuel), total in groups.items():
        mix, assumed = expand.lib.class_mix(fhwa_class, fuel)
        if not mix:
            continue
        kept = total.copy()
        for j in range(1, h):
            sold, rule = entering(fhwa_class, base, total, kept, j)
            if sold <= 0:
                continue
            kept = kept + sold * expand._shifted_survival(fhwa_class, h, j)
            for v, share in mix:
                acc.add(v.library_id, v, fhwa_class, fuel, base + j, None, 0.0)
                key = (v.library_id, fhwa_class, fuel, base + j, None)
                acc.new_sales[key] = acc.new_sales.get(key, 0.0) + sold * share
            acc.choices.append({"registration_row": "new sales", "vehicle_class": fhwa_class,
                                "fhwa_class": fhwa_class, "fuel": fuel, "count": sold, "model_year": base + j,
                                "vehicle": f"default {fhwa_class} {fuel} mix", "matched_on": "turnover",
                                "assumed": "; ".join(t for t in (rule, assumed) if t)})


@contextmanager
def candidate_patch(candidate: str):
    """The candidate's turnover functions in place for the duration."""
    saved = turnover.fuel_factor, turnover.miles_by_age
    saved_years, saved_sales = expand._model_years, expand._new_sales
    if candidate == "M5":
        expand._new_sales = m5_new_sales
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
        expand._model_years, expand._new_sales = saved_years, saved_sales


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


def state_years(candidate: str, years: str = "") -> pd.DataFrame:
    """validation/state_fuel.py's MV-1-only runs of every base state-year (``years``: a comma
    list of base years, default all) under ``candidate``."""
    data = pd.read_csv(state_fuel.DATA)
    bases = data[data.mv1_automobiles.notna()]
    if years:
        bases = bases[bases.year.isin([int(y) for y in years.split(",")])]
    rows = []
    with tempfile.TemporaryDirectory() as tmp, candidate_patch(candidate):
        for _, row in bases.iterrows():
            rows.append(state_fuel.run_state(row, state_fuel.later_year(data, row), Path(tmp)))
    return pd.DataFrame(rows)


def judge_state_years(table: pd.DataFrame) -> None:
    """Print every period's judgement (validation/gasoline_by_year.py, its one owner) and the
    calibrated next-year gasoline forecast errors against the naive ones."""
    import gasoline_by_year

    periods = gasoline_by_year.turnover_by_period(table)
    print(periods[["start", "end", "state_years", "model_low", "model_high", "vm1_low", "vm1_high",
                   "within", "below", "above"]].round(2).to_string(index=False))
    print(gasoline_by_year.turnover_verdict(periods))
    fc = table.reindex(columns=[*table.columns, "gasoline_forecast_error_pct"]).dropna(subset=["gasoline_forecast_error_pct"])
    fc = fc.loc[:, ~fc.columns.duplicated()]
    print(f"gasoline forecast: {len(fc)} state-years, mean |error| {fc.gasoline_forecast_error_pct.abs().mean():.3f} %, "
          f"better than naive {(fc.gasoline_forecast_error_pct.abs() < fc.gasoline_naive_error_pct.abs()).sum()}")


def main(argv=None) -> pd.DataFrame:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--candidates", default=",".join(CANDIDATES))
    parser.add_argument("--state-years", action="store_true",
                        help="run the candidates on validation/state_fuel.py's MV-1 state-years and judge every period")
    parser.add_argument("--base-years", default="", help="with --state-years: comma list of base years (default all)")
    parser.add_argument("--years", default="2000,2003,2006,2008,2009,2010,2017")
    parser.add_argument("--out", type=Path, default=None, help="CSV of every run")
    args = parser.parse_args(argv)
    if args.state_years:
        tables = []
        for candidate in args.candidates.split(","):
            table = state_years(candidate, args.base_years).assign(candidate=candidate)
            print(f"== {candidate}", flush=True)
            judge_state_years(table)
            tables.append(table)
        table = pd.concat(tables, ignore_index=True)
        if args.out:
            table.to_csv(args.out, index=False, float_format="%.4g")
        return table
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
