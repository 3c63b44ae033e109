"""The national registrations run class by class against FHWA VM-1 (docs/validation-state-fuel.md,
"Class by class against VM-1").

    python validation/vm1_by_class.py [--years 2000,2003,2006,2008,2009,2010] [--markdown] [--out CSV]
    python validation/vm1_by_class.py --vm1-shares      # candidate V1, national
    python validation/vm1_by_class.py --states          # candidate V1 on the state-years (~1 min)

For each year the issue's national workbook (the states' summed MV-1 counts and VM-2 miles,
``inputs/state_statistics/national_sum_years.csv``; ``cycle_mix = default``; uncalibrated) is run
for that year alone, and each FHWA class's share of the miles, its fuel (all fuels) per 1,000
vehicle-miles of all traffic, its gasoline and diesel and its mpg are printed beside VM-1's
(``inputs/state_statistics/vm1_by_class.csv``, PROVENANCE.md there). VM-1 gives fuel by class,
not by fuel type; its light-duty fuel is its miles over its on-road mpg (``vm1_onroad_mpg.csv``,
the same editions), its motorcycles' fuel (where not given) their miles at 2000's mpg. 2009-2010
are VM-1's revised wheelbase categories, so light duty is compared as one class there; their fuel
by class was not found stored. No constant is fitted. Candidate V1 (pre-registered in the docs,
not adopted) puts each year's VM-1 class shares of the miles into the scenario's
``base_year_vmt_share_pct``.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "validation"))

import state_fuel  # noqa: E402  (the issue's workbook, its one owner)

STATS = ROOT / "inputs" / "state_statistics"
CLASSES = ("automobile", "light_truck", "motorcycle", "bus", "single_unit_truck", "combination_truck")
# VM-1's classes -> the model's FHWA classes (the wheelbase categories of 2007 on: light duty)
VM1_CLASS = {"passenger_car": "automobile", "other_2axle_4tire": "light_truck", "motorcycle": "motorcycle",
             "bus": "bus", "single_unit": "single_unit_truck", "combination": "combination_truck",
             "light_duty_short_wb": "light_duty", "light_duty_long_wb": "light_duty"}
# The edition of vm1_onroad_mpg.csv whose light-duty mpg goes with each year's miles
MPG_EDITION = {2000: "TSAR2006-E9", 2003: "TSAR2006-E9", 2006: "TSAR2010-5-9", 2008: "TSAR2010-5-9"}
YEARS = (2000, 2003, 2006, 2008, 2009, 2010)


def vm1(year: int) -> pd.DataFrame:
    """VM-1 of ``year`` by model class: miles and fuel [millions] (fuel NaN where not found)."""
    data = pd.read_csv(STATS / "vm1_by_class.csv")
    data = data[data.year == year].assign(model_class=lambda d: d.vm1_class.map(VM1_CLASS))
    if year in MPG_EDITION:
        mpg = pd.read_csv(STATS / "vm1_onroad_mpg.csv")
        mpg = mpg[(mpg.year == year) & (mpg.edition == MPG_EDITION[year])].iloc[0]
        for name, column in (("passenger_car", "passenger_car_mpg"), ("other_2axle_4tire", "other_2axle_4tire_mpg")):
            row = data.vm1_class == name
            data.loc[row, "fuel_million_gal"] = data.loc[row, "vmt_million_mi"] / mpg[column]
    first = pd.read_csv(STATS / "vm1_by_class.csv").query("year == 2000 and vm1_class == 'motorcycle'").iloc[0]
    moto = (data.vm1_class == "motorcycle") & data.fuel_million_gal.isna()
    data.loc[moto, "fuel_million_gal"] = data.loc[moto, "vmt_million_mi"] * first.fuel_million_gal / first.vmt_million_mi
    return data.groupby("model_class")[["vmt_million_mi", "fuel_million_gal"]].sum(min_count=1)


def vm1_share_text(year: int, motorcycles: bool = True) -> str:
    """Candidate V1 (pre-registered in docs/validation-state-fuel.md): VM-1's national percent of
    the year's miles for the classes ``base_year_vmt_share_pct`` takes, where VM-1 gives them
    (not motorcycles where the registrations count none: their miles stay with light duty)."""
    data = pd.read_csv(STATS / "vm1_by_class.csv").query("year == @year")
    miles = data.groupby(data.vm1_class.map(VM1_CLASS)).vmt_million_mi.sum()
    listed = [name for name in state_fuel.SHARE_CLASSES if name in miles.index and (motorcycles or name != "motorcycle")]
    return ", ".join(f"{name}:{100 * miles[name] / miles.sum():.4f}" for name in listed)


def model(year: int, folder: Path, vm1_shares: bool = False) -> pd.DataFrame:
    """The national run of ``year`` by class and fuel: miles and gallons [millions]; with
    ``vm1_shares`` the scenario carries VM-1's class shares of the year (V1)."""
    import openpyxl

    from fleetrun.run.runner import run_fleet
    from fleetrun.workbook import read_fleet

    row = pd.read_csv(STATS / "national_sum_years.csv").set_index("year", drop=False).loc[year].astype(object)
    row["state"], row["special_fuels_kgal"] = "United States", float("nan")
    path = state_fuel.workbook(folder / f"us-{year}.xlsx", row, 1, 0.0)
    if vm1_shares:
        wb = openpyxl.load_workbook(path)
        wb["Scenarios"].cell(2, state_fuel.SCENARIO.index("base_year_vmt_share_pct") + 1).value = vm1_share_text(year)
        wb.save(path)
    fiscal = run_fleet(read_fleet(path), error_model=None).fiscal
    fiscal = fiscal[fiscal.fiscal_year == year]
    return fiscal.groupby(["vehicle_class", "fuel"])[["miles", "fuel_gal"]].sum() / 1e6


def compare(year: int, runs: pd.DataFrame) -> pd.DataFrame:
    """One year's table: per class the model's and VM-1's share of the miles, fuel per 1,000
    vehicle-miles of all traffic, gasoline and diesel and mpg."""
    published = vm1(year)
    total_model = runs.miles.sum()
    total_vm1 = published.vmt_million_mi.sum()
    by_class = runs.groupby(level="vehicle_class").sum()
    fuel = runs.fuel_gal.unstack("fuel").reindex(columns=["gasoline", "diesel"]).fillna(0.0)
    classes = list(CLASSES) if "automobile" in published.index else ["light_duty", *CLASSES[2:]]
    if "light_duty" in classes:
        for frame in (by_class, fuel):
            frame.loc["light_duty"] = frame.loc[["automobile", "light_truck"]].sum()
    rows = []
    for name in classes:
        m, p = by_class.loc[name], published.loc[name] if name in published.index else None
        rows.append({"year": year, "class": name,
                     "model_miles_pct": 100 * m.miles / total_model,
                     "vm1_miles_pct": 100 * p.vmt_million_mi / total_vm1 if p is not None else float("nan"),
                     "model_gal_per_kmi": 1e3 * m.fuel_gal / total_model,
                     "vm1_gal_per_kmi": 1e3 * p.fuel_million_gal / total_vm1 if p is not None else float("nan"),
                     "model_gasoline_Mgal": fuel.loc[name, "gasoline"], "model_diesel_Mgal": fuel.loc[name, "diesel"],
                     "model_diesel_pct": 100 * fuel.loc[name, "diesel"] / m.fuel_gal,
                     "vm1_fuel_Mgal": p.fuel_million_gal if p is not None else float("nan"),
                     "model_mpg": m.miles / m.fuel_gal,
                     "vm1_mpg": p.vmt_million_mi / p.fuel_million_gal if p is not None else float("nan")})
    return pd.DataFrame(rows)


def totals(year: int, runs: pd.DataFrame) -> dict:
    """The year's national gasoline against the states' summed MF-21 and all fuel against VM-1's."""
    nation = pd.read_csv(STATS / "national_sum_years.csv").set_index("year").loc[year]
    published = vm1(year)
    gasoline = runs.xs("gasoline", level="fuel").fuel_gal.sum()
    diesel = runs.xs("diesel", level="fuel").fuel_gal.sum()
    special = pd.read_csv(STATS / "national_years.csv").set_index("year").special_fuels_mgal
    special = special.get(year, float("nan")) if year != 2009 else float("nan")   # 2009: rounded to the billion
    return {"year": year, "diesel_model_Mgal": diesel,
            "special_fuels_error_pct": 100 * (diesel / special - 1), "gasoline_model_Mgal": gasoline, "gasoline_mf21_Mgal": nation.highway_gasoline_kgal / 1e3,
            "gasoline_error_pct": 100 * (gasoline / (nation.highway_gasoline_kgal / 1e3) - 1),
            "vm1_vmt_vs_vm2_pct": 100 * (published.vmt_million_mi.sum() / nation.vmt_million_mi - 1),
            "all_fuel_model_gal_per_kmi": 1e3 * runs.fuel_gal.sum() / runs.miles.sum(),
            "all_fuel_vm1_gal_per_kmi": 1e3 * published.fuel_million_gal.sum() / published.vmt_million_mi.sum()
            if published.fuel_million_gal.notna().all() and "bus" in published.index else float("nan")}


def gap_parts(year: int, runs: pd.DataFrame) -> dict:
    """The model's gasoline per 1,000 vehicle-miles minus the nation's (MF-21 / VM-2), split by
    VM-1 [gal / 1,000 mi]: ``light_duty`` = model light-duty gasoline - VM-1 light-duty fuel (of
    which ``ld_share``: the light-duty share of the miles at VM-1's mpg, ``ld_mpg``: the rest),
    ``other_gasoline`` = the model's gasoline of motorcycles, buses and single-unit trucks, and
    ``vm1_room`` = the nation's gasoline - VM-1's light-duty fuel, what VM-1's fuel by class leaves
    for the other classes' gasoline (net of light-duty diesel); gap = light_duty + other_gasoline -
    vm1_room (VM-1's light-duty fuel per VM-1 mile, the nation's gasoline per VM-2 mile)."""
    nation = pd.read_csv(STATS / "national_sum_years.csv").set_index("year").loc[year]
    published = vm1(year)
    miles = runs.miles.sum()
    light = runs.loc[["automobile", "light_truck"]]
    ld_gas = 1e3 * light.xs("gasoline", level="fuel").fuel_gal.sum() / miles
    ld_share_m = light.miles.sum() / miles
    ld_share_v = published.loc[["automobile", "light_truck"]].vmt_million_mi.sum() / published.vmt_million_mi.sum() \
        if "automobile" in published.index else published.vmt_million_mi["light_duty"] / published.vmt_million_mi.sum()
    ld_fuel_v = 1e3 * published.fuel_million_gal.reindex(["automobile", "light_truck", "light_duty"]).sum(min_count=1) \
        / published.vmt_million_mi.sum()
    observed = nation.highway_gasoline_kgal / nation.vmt_million_mi
    other = 1e3 * runs.drop(index=["automobile", "light_truck"]).xs("gasoline", level="fuel").fuel_gal.sum() / miles
    parts = {"year": year, "gap": 1e3 * runs.xs("gasoline", level="fuel").fuel_gal.sum() / miles - observed,
             "light_duty": ld_gas - ld_fuel_v, "ld_share": ld_fuel_v * (ld_share_m / ld_share_v - 1),
             "other_gasoline": other, "vm1_room": observed - ld_fuel_v}
    parts["ld_mpg"] = parts["light_duty"] - parts["ld_share"]
    parts["observed_gal_per_kmi"] = observed
    return parts


def markdown(table: pd.DataFrame, summary: pd.DataFrame) -> str:
    """The two tables as docs/validation-state-fuel.md prints them."""
    def num(value, fmt):
        return "" if pd.isna(value) else format(value, fmt)
    lines = ["| year | class | miles % model / VM-1 | fuel per 1,000 mi model / VM-1 | model gasoline / diesel, M gal"
             " | mpg model / VM-1 |", "|---|---|---|---|---|---|"]
    for r in table.itertuples():
        lines.append(f"| {r.year} | {r._2} | {r.model_miles_pct:.2f} / {num(r.vm1_miles_pct, '.2f')} | "
                     f"{r.model_gal_per_kmi:.2f} / {num(r.vm1_gal_per_kmi, '.2f')} | "
                     f"{r.model_gasoline_Mgal:,.0f} / {r.model_diesel_Mgal:,.0f} | {r.model_mpg:.2f} / {num(r.vm1_mpg, '.2f')} |")
    lines += ["", "| year | gasoline error | all fuel per 1,000 mi model / VM-1 | gap | light duty (share / mpg)"
              " | other classes' gasoline | VM-1's room for it |", "|---|---:|---|---:|---|---:|---:|"]
    for r in summary.itertuples():
        lines.append(f"| {r.year} | {r.gasoline_error_pct:+.1f} % | {r.all_fuel_model_gal_per_kmi:.2f} / "
                     f"{num(r.all_fuel_vm1_gal_per_kmi, '.2f')} | {r.gap:+.2f} | {num(r.light_duty, '+.2f')} "
                     f"({num(r.ld_share, '+.2f')} / {num(r.ld_mpg, '+.2f')}) | {r.other_gasoline:.2f} | "
                     f"{num(r.vm1_room, '+.2f')} |")
    return "\n".join(lines)


def states_v1(years) -> pd.DataFrame:
    """Candidate V1 on every state-year of validation/state_fuel.py in ``years`` (MV-1-only
    workbook plus the year's national VM-1 class shares), beside the saved MV-1-only result."""
    data = pd.read_csv(state_fuel.DATA)
    saved = pd.read_csv(state_fuel.ROOT / "docs" / "validation-state-fuel.csv").query("inputs == 'mv1'")
    saved = saved.set_index(["state", "year"])
    rows, share_text = [], state_fuel.share_text
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for _, row in data[data.year.isin(years)].iterrows():
                state_fuel.share_text = lambda shares, r: vm1_share_text(int(r.year), pd.notna(r.mv1_motorcycles))
                shares = pd.Series(float("nan"), index=list(state_fuel.SHARE_CLASSES))
                out = state_fuel.run_state(row, None, Path(tmp), shares)
                before = saved.loc[(row.state, int(row.year))]
                rows.append({"state": row.state, "year": int(row.year),
                             "gasoline_error_pct": out["gasoline_error_pct"], "gasoline_hit": out["gasoline_hit"],
                             "diesel_error_pct": out["diesel_error_pct"],
                             "diesel_hit": out["diesel_hit"] if pd.notna(row.special_fuels_kgal) else pd.NA,
                             "before_gasoline_error_pct": before.gasoline_error_pct,
                             "before_gasoline_hit": bool(before.gasoline_hit),
                             "before_diesel_error_pct": before.diesel_error_pct,
                             "before_diesel_hit": bool(before.diesel_hit) if pd.notna(row.special_fuels_kgal) else pd.NA})
    finally:
        state_fuel.share_text = share_text
    return pd.DataFrame(rows)


def print_states(states: pd.DataFrame) -> pd.DataFrame:
    """V1's state-years and the hit counts beside the saved MV-1-only runs."""
    both = states.dropna(subset=["diesel_hit"])
    with pd.option_context("display.width", 220, "display.max_columns", 30):
        print(states.round(2).to_string(index=False))
    gas, diesel = both.gasoline_hit, both.diesel_hit.astype(bool)
    gas0, diesel0 = both.before_gasoline_hit, both.before_diesel_hit.astype(bool)
    print(f"V1 on {len(states)} state-years: gasoline within 5 % {int(states.gasoline_hit.sum())} "
          f"(saved MV-1-only {int(states.before_gasoline_hit.sum())}); of {len(both)} with special fuels: "
          f"within 10 % {int(diesel.sum())} ({int(diesel0.sum())}), both {int((gas & diesel).sum())} "
          f"({int((gas0 & diesel0).sum())})")
    return states


def main(argv=None) -> tuple[pd.DataFrame, pd.DataFrame]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--years", default=",".join(map(str, YEARS)))
    parser.add_argument("--out", type=Path, default=None, help="CSV of the class table")
    parser.add_argument("--markdown", action="store_true", help="print the tables as the docs page has them")
    parser.add_argument("--states", action="store_true",
                        help="candidate V1 on the state-years of the years given, hit counts beside the saved ones")
    parser.add_argument("--vm1-shares", action="store_true",
                        help="candidate V1: each year's VM-1 class shares of the miles in the scenario")
    args = parser.parse_args(argv)
    if args.states:
        return print_states(states_v1([int(y) for y in args.years.split(",")])), pd.DataFrame()
    tables, sums = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for year in (int(y) for y in args.years.split(",")):
            runs = model(year, Path(tmp), args.vm1_shares)
            tables.append(compare(year, runs))
            sums.append({**totals(year, runs), **gap_parts(year, runs)})
    table, summary = pd.concat(tables, ignore_index=True), pd.DataFrame(sums)
    with pd.option_context("display.width", 220, "display.max_columns", 30):
        print(table.round(2).to_string(index=False))
        print(summary.round(2).to_string(index=False))
    if args.markdown:
        print(markdown(table, summary))
    if args.out:
        table.to_csv(args.out, index=False, float_format="%.4f")
    return table, summary


if __name__ == "__main__":
    main()
