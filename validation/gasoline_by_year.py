"""Where the state gasoline error comes from, and the turnover mpg change against the same
period's published on-road change (docs/validation-state-fuel.md, "Where the state gasoline
error comes from" and "Turnover against the same period").

    python validation/gasoline_by_year.py [--no-runs] [--write]

1. per base year of ``docs/validation-state-fuel.csv`` (MV-1-only runs): the VMT-weighted error
   of the year's state-years, their median, and the sample's observed gasoline per 1,000
   vehicle-miles against the nation's of the same year (``national_sum_years.csv``: the sums of
   the 51 states' VM-2 miles and MF-21 highway gasoline);
2. the issue's workbook run for the whole nation in every year with national registrations
   (2000-2010 sums of the states' MV-1, 2017 MV-1) and for all 51 states in 2010 and 2017
   (``all_states_2010_2017.csv``): national error, sum of the states against the national run,
   states tried by validation/state_fuel.py against the others (Hawaii-Pennsylvania, whose 2008
   registrations the truck split uses, so they are never in a hit count);
3. per base year, the light-duty fleet's mpg change of the model (the CSV's
   ``ld_mpg_change_pct_per_year``, over the same years as the run) against the published range of
   the same calendar years (pre-registration P2 of the docs page: every published on-road series
   of one table and one light-duty category giving both years, ``vm1_onroad_mpg.csv`` and
   ``ld_onroad_mpg_series.csv``), state-years within / below / above, and the nation's miles per
   gallon of highway gasoline;
4. P3 (pre-registered, beside P2): the same model change against the range of the published
   series' trends around the period (least-squares slope of ln(mpg) over the period plus two
   years each side, one source and one category, at least 4 years, no category break), W = 3
   and W = 7 printed as information; ``--write`` stores the tables in ``validation/data``
   (``turnover_trend_p3.csv``, ``turnover_trend_p3_series.csv``).

Every input is in ``inputs/state_statistics/`` (PROVENANCE.md there); no constant is fitted.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "validation"))

import state_fuel  # noqa: E402  (the state validation's workbook and run, the one owner of them)

STATS = ROOT / "inputs" / "state_statistics"
RESULTS = ROOT / "docs" / "validation-state-fuel.csv"
DATA_OUT = ROOT / "validation" / "data"
MV1_COLUMNS = ["mv1_automobiles", "mv1_buses", "mv1_trucks", "mv1_motorcycles"]


def national() -> pd.DataFrame:
    """The nation per year: sums of the 51 states (index: year)."""
    return pd.read_csv(STATS / "national_sum_years.csv").set_index("year")


def gallons_per_thousand_miles(gasoline_kgal: float, vmt_million_mi: float) -> float:
    """Gasoline per 1,000 vehicle-miles: thousand gallons / million miles [gal / 1,000 mi]."""
    return gasoline_kgal / vmt_million_mi


def sample_by_year(results: pd.DataFrame) -> pd.DataFrame:
    """Per base year: state-years, VMT-weighted and median gasoline error, the sample's and the
    nation's observed and the model's gasoline per 1,000 vehicle-miles."""
    nation = national()
    rows = []
    for year, part in results[results.inputs == "mv1"].groupby("year"):
        observed = part.gasoline_observed_Mgal.sum()
        rows.append({"year": year, "state_years": len(part),
                     "vmt_weighted_error_pct": 100 * (part.gasoline_model_Mgal.sum() / observed - 1),
                     "median_error_pct": part.gasoline_error_pct.median(),
                     "share_of_national_vmt_pct": 100 * part.vmt_million_mi.sum() / nation.vmt_million_mi[year],
                     "sample_observed": 1e3 * observed / part.vmt_million_mi.sum(),
                     "sample_model": 1e3 * part.gasoline_model_Mgal.sum() / part.vmt_million_mi.sum(),
                     "nation_observed": gallons_per_thousand_miles(nation.highway_gasoline_kgal[year],
                                                                   nation.vmt_million_mi[year])})
    return pd.DataFrame(rows)


def run_rows(rows: pd.DataFrame) -> pd.DataFrame:
    """The issue's workbook (MV-1 counts, ``base_year_vmt_million``, uncalibrated) per row."""
    rows = rows.assign(special_fuels_kgal=float("nan"))
    with tempfile.TemporaryDirectory() as tmp:
        return pd.DataFrame([state_fuel.run_state(row, None, Path(tmp)) for _, row in rows.iterrows()])


def national_runs() -> pd.DataFrame:
    """The nation in every year with national registrations."""
    rows = national().dropna(subset=MV1_COLUMNS).reset_index().assign(state="United States")
    return run_rows(rows)


def all_states_runs(years=(2010, 2017)) -> pd.DataFrame:
    data = pd.read_csv(STATS / "all_states_2010_2017.csv")
    return run_rows(data[data.year.isin(years)])


def tried_states() -> set[tuple[str, int]]:
    """(state, year) of validation/state_fuel.py's state-years (its data file's spelling)."""
    data = pd.read_csv(state_fuel.DATA)
    names = data.state.replace({"Dist. of Col.": "District of Columbia"})
    return set(zip(names, data.year))


def sum_of_states(states: pd.DataFrame, nation_runs: pd.DataFrame) -> pd.DataFrame:
    """Per year: the national run, the sum of the 51 state runs, the states tried and the others."""
    tried = tried_states()
    data = pd.read_csv(STATS / "all_states_2010_2017.csv")
    states = states.merge(data[["state", "year", *MV1_COLUMNS, "highway_gasoline_kgal"]], on=["state", "year"])
    states["vehicles_per_million_mi"] = states[MV1_COLUMNS].sum(axis=1) / states.vmt_million_mi
    states["truck_share_pct"] = 100 * states.mv1_trucks / (states.mv1_trucks + states.mv1_automobiles)
    states["observed_gal_per_kmi"] = states.highway_gasoline_kgal / states.vmt_million_mi
    rows = []
    for year, part in states.groupby("year"):
        nation = nation_runs[nation_runs.year == year].iloc[0]
        is_tried = [(s, y) in tried for s, y in zip(part.state, part.year)]
        row = {"year": year, "national_model_Mgal": nation.gasoline_model_Mgal,
               "national_observed_Mgal": nation.gasoline_observed_Mgal,
               "national_error_pct": nation.gasoline_error_pct,
               "states_model_Mgal": part.gasoline_model_Mgal.sum(),
               "states_vs_national_run_pct": 100 * (part.gasoline_model_Mgal.sum() / nation.gasoline_model_Mgal - 1),
               "median_error_pct": part.gasoline_error_pct.median(),
               "hits": int((part.gasoline_error_pct.abs() <= 100 * state_fuel.GASOLINE_TOLERANCE).sum()),
               "above": int((part.gasoline_error_pct > 0).sum()),
               "corr_error_observed_gal_per_kmi": part.gasoline_error_pct.corr(part.observed_gal_per_kmi),
               "corr_error_vehicles_per_mile": part.gasoline_error_pct.corr(part.vehicles_per_million_mi),
               "corr_error_truck_share": part.gasoline_error_pct.corr(part.truck_share_pct),
               "model_gal_per_kmi_min": (1e3 * part.gasoline_model_Mgal / part.vmt_million_mi).min(),
               "model_gal_per_kmi_max": (1e3 * part.gasoline_model_Mgal / part.vmt_million_mi).max(),
               "observed_gal_per_kmi_min": part.observed_gal_per_kmi.min(),
               "observed_gal_per_kmi_max": part.observed_gal_per_kmi.max(),
               "observed_gal_per_kmi_median": part.observed_gal_per_kmi.median()}
        for name, sel in (("tried", part[is_tried]), ("others", part[[not t for t in is_tried]])):
            row[f"{name}_states"] = len(sel)
            row[f"{name}_vmt_weighted_error_pct"] = 100 * (sel.gasoline_model_Mgal.sum() / sel.gasoline_observed_Mgal.sum() - 1)
            row[f"{name}_median_error_pct"] = sel.gasoline_error_pct.median()
            row[f"{name}_vehicles_per_million_mi"] = sel[MV1_COLUMNS].sum().sum() / sel.vmt_million_mi.sum()
            row[f"{name}_truck_share_pct"] = 100 * sel.mv1_trucks.sum() / (sel.mv1_trucks.sum() + sel.mv1_automobiles.sum())
        rows.append(row)
    return pd.DataFrame(rows)


def pct_per_year(start: float, end: float, years: int) -> float:
    return 100 * ((end / start) ** (1 / years) - 1)


HALF_DIGIT = 0.05          # [mpg] half the last printed digit of every published value

# VM-1's categories in the two BTS tables of ``vm1_onroad_mpg.csv`` (one column each)
VM1_TSAR_CATEGORIES = {"passenger_car_mpg": "passenger_car", "other_2axle_4tire_mpg": "other_2axle_4tire"}


def published_series() -> pd.DataFrame:
    """Every published on-road light-duty mpg value, one row per source (table and edition),
    year and vehicle category: the BTS tables of ``vm1_onroad_mpg.csv`` and the EIA / ORNL tables
    of ``ld_onroad_mpg_series.csv`` (PROVENANCE.md there)."""
    tsar = pd.read_csv(STATS / "vm1_onroad_mpg.csv").melt(
        id_vars=["year", "edition"], value_vars=list(VM1_TSAR_CATEGORIES), var_name="category", value_name="mpg")
    tsar = tsar.rename(columns={"edition": "source"}).replace({"category": VM1_TSAR_CATEGORIES})
    other = pd.read_csv(STATS / "ld_onroad_mpg_series.csv")
    return pd.concat([tsar, other], ignore_index=True)[["source", "year", "category", "mpg"]]


def series_changes(start: int, end: int) -> pd.DataFrame:
    """The compound change [%/yr] from ``start`` to ``end`` of every published series (one
    source, one category) that gives both years; never a pair across categories or sources
    (docs/validation-state-fuel.md, pre-registration P2). ``rounded_low`` / ``rounded_high``: the
    change with each printed value moved by half its last digit (0.05 mpg) against / in favour of
    a gain (information only; P2's range adds no such allowance)."""
    values = published_series().pivot_table(index=["source", "category"], columns="year", values="mpg")
    if start not in values.columns or end not in values.columns:
        return pd.DataFrame(columns=["source", "category", "change_pct_per_year", "rounded_low", "rounded_high"])
    both = values[[start, end]].dropna().to_numpy()
    years = end - start
    return pd.DataFrame({"change_pct_per_year": [pct_per_year(a, b, years) for a, b in both],
                         "rounded_low": [pct_per_year(a + HALF_DIGIT, b - HALF_DIGIT, years) for a, b in both],
                         "rounded_high": [pct_per_year(a - HALF_DIGIT, b + HALF_DIGIT, years) for a, b in both]},
                        index=values[[start, end]].dropna().index).reset_index()


def published_change(start: int, end: int) -> dict:
    """The published range [%/yr] of on-road light-duty mpg from ``start`` to ``end`` (min and
    max over :func:`series_changes`; NaN where no series gives both years) and the nation's
    miles per gallon of highway gasoline (VM-2 miles / MF-21 gasoline)."""
    series = series_changes(start, end)
    changes = series.change_pct_per_year
    nation = national()
    mpg = nation.vmt_million_mi / nation.highway_gasoline_kgal * 1e3
    return {"vm1_low": changes.min() if len(changes) else float("nan"),
            "vm1_high": changes.max() if len(changes) else float("nan"),
            "series": len(changes),
            "rounded_low": series.rounded_low.min() if len(series) else float("nan"),
            "rounded_high": series.rounded_high.max() if len(series) else float("nan"),
            "nation_mi_per_gal_gasoline": pct_per_year(mpg[start], mpg[end], end - start)}


def judge(model: pd.Series, low: float, high: float) -> dict:
    """State-years within the published range (ends included), below and above it; a period
    without a published range is not judged."""
    if low != low:
        return {"within": 0, "below": 0, "above": 0, "not_judged": len(model)}
    return {"within": int(((model >= low) & (model <= high)).sum()), "below": int((model < low).sum()),
            "above": int((model > high).sum()), "not_judged": 0}


def runs_with_end(results: pd.DataFrame, inputs: str = "mv1") -> pd.DataFrame:
    """The runs of one input variant with the calendar year each run ends (``end``: the state's
    next judged year, or the next year)."""
    runs = results[results.inputs == inputs].copy()
    data = pd.read_csv(state_fuel.DATA)
    by_key = {(r.state, r.year): r for _, r in data.iterrows()}

    def end_year(state: str, year: int) -> int:
        later = state_fuel.later_year(data, by_key[(state, year)])
        return int(later.year) if later is not None else year + 1

    runs["end"] = [end_year(s, y) for s, y in zip(runs.state, runs.year)]
    return runs


def turnover_by_period(results: pd.DataFrame, inputs: str = "mv1") -> pd.DataFrame:
    """Per base year and period of the runs of one input variant (``mv1``: the issue's workbook;
    ``mv1+vm4``): the model's light-duty mpg change against the published range of the same
    calendar years."""
    rows = []
    for (start, end), part in runs_with_end(results, inputs).groupby(["year", "end"]):
        published = published_change(int(start), int(end))
        model = part.ld_mpg_change_pct_per_year
        counts = judge(model, published["vm1_low"], published["vm1_high"])
        rows.append({"start": int(start), "end": int(end), "state_years": len(part),
                     "model_low": model.min(), "model_high": model.max(), **published,
                     "in_vm1_range": counts["within"] if published["series"] else pd.NA, **counts})
    return pd.DataFrame(rows)


def turnover_verdict(table: pd.DataFrame) -> dict:
    """The issue's line over every judged period: state-years within / outside the published
    range, and whether every judged state-year is within."""
    judged = table[table.not_judged == 0]
    outside = int(judged.below.sum() + judged.above.sum())
    return {"judged": int(judged.state_years.sum()), "within": int(judged.within.sum()), "outside": outside,
            "not_judged": int(table.not_judged.sum()), "holds": outside == 0,
            "periods_outside": [f"{r.start}->{r.end}" for r in judged.itertuples() if r.below + r.above]}


# P3 (docs/validation-state-fuel.md, "P3, pre-registered"): the published trend around a period
TREND_WIDTH = 5                      # the judgement's window: the period plus 2 years each side
TREND_WIDTHS_INFO = (3, 7)           # printed beside it, information only
TREND_MIN_YEARS = 4                  # a series is usable with at least 4 of the window's years
# category breaks the stored labels do not carry: (source, category) -> first year of the new
# category (TEDB 37's cars / light trucks are VM-1's categories through 2008, ORNL's own from 2010)
CATEGORY_BREAKS = {("TEDB-37", "car"): 2010, ("TEDB-37", "light_truck"): 2010}


def trend_pct_per_year(years, mpg) -> float:
    """The least-squares slope b of ln(mpg) against the calendar year, as 100 (exp(b) - 1)
    [%/yr]."""
    slope = np.polyfit(np.asarray(years, dtype=float), np.log(np.asarray(mpg, dtype=float)), 1)[0]
    return 100 * (np.exp(slope) - 1)


def trend_window(start: int, end: int, width: int = TREND_WIDTH) -> tuple[int, int]:
    """First and last calendar year of the window: the period plus (width - 1) / 2 years on each
    side."""
    side = (width - 1) // 2
    return start - side, end + side


def crosses_break(source: str, category: str, years) -> bool:
    """Whether a series' years lie on both sides of a tagged category break."""
    first_new = CATEGORY_BREAKS.get((source, category))
    return first_new is not None and min(years) < first_new <= max(years)


def series_trends(start: int, end: int, width: int = TREND_WIDTH) -> pd.DataFrame:
    """Every published series (one source, one category) with a value in the window of the
    period: its years there, whether it is usable (at least ``TREND_MIN_YEARS`` years, no
    category break inside) and, if so, its trend [%/yr]."""
    first, last = trend_window(start, end, width)
    values = published_series()
    values = values[(values.year >= first) & (values.year <= last)]
    rows = []
    for (source, category), part in values.groupby(["source", "category"]):
        years = sorted(part.year)
        enough, broken = len(years) >= TREND_MIN_YEARS, crosses_break(source, category, years)
        usable = enough and not broken
        rows.append({"source": source, "category": category, "first_year": years[0], "last_year": years[-1],
                     "years": len(years), "usable": usable,
                     "excluded": "" if usable else ("category break" if broken else f"fewer than {TREND_MIN_YEARS} years"),
                     "trend_pct_per_year": trend_pct_per_year(part.year, part.mpg) if usable else float("nan")})
    return pd.DataFrame(rows)


def published_trend(start: int, end: int, width: int = TREND_WIDTH) -> dict:
    """The P3 range [%/yr]: min and max of the usable series' trends (NaN if none)."""
    trends = series_trends(start, end, width)
    usable = trends[trends.usable].trend_pct_per_year if len(trends) else pd.Series(dtype=float)
    return {"trend_low": usable.min() if len(usable) else float("nan"),
            "trend_high": usable.max() if len(usable) else float("nan"), "trend_series": len(usable)}


def trend_by_period(results: pd.DataFrame, inputs: str = "mv1") -> pd.DataFrame:
    """P3 per period: the model's light-duty mpg change of each state-year against the range of
    the published series' trends around the period (W = 5, judged), with W = 3 and W = 7 beside
    it (information only)."""
    rows = []
    for (start, end), part in runs_with_end(results, inputs).groupby(["year", "end"]):
        model = part.ld_mpg_change_pct_per_year
        trend = published_trend(int(start), int(end))
        row = {"start": int(start), "end": int(end), "state_years": len(part), "model_low": model.min(),
               "model_high": model.max(), **trend, **judge(model, trend["trend_low"], trend["trend_high"])}
        for width in TREND_WIDTHS_INFO:
            info = published_trend(int(start), int(end), width)
            row |= {f"w{width}_low": info["trend_low"], f"w{width}_high": info["trend_high"],
                    f"w{width}_series": info["trend_series"],
                    f"w{width}_within": judge(model, info["trend_low"], info["trend_high"])["within"]}
        rows.append(row)
    return pd.DataFrame(rows)


def write_trend(out: dict, folder: Path = DATA_OUT) -> None:
    """P3's tables as ``validation/data`` stores them (PROVENANCE.md there)."""
    out["trend"].to_csv(folder / "turnover_trend_p3.csv", index=False, float_format="%.6f")
    out["trend_series"].to_csv(folder / "turnover_trend_p3_series.csv", index=False, float_format="%.6f")


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--no-runs", action="store_true", help="only the analyses of the saved results")
    parser.add_argument("--write", action="store_true",
                        help="store P3's tables in validation/data (turnover_trend_p3*.csv)")
    args = parser.parse_args(argv)
    results = pd.read_csv(RESULTS)
    out = {"sample": sample_by_year(results), "turnover": turnover_by_period(results)}
    out["turnover_series"] = pd.concat([series_changes(r.start, r.end).assign(start=r.start, end=r.end)
                                        for r in out["turnover"].itertuples()], ignore_index=True)
    out["turnover_vm4"] = turnover_by_period(results, "mv1+vm4")
    out["turnover_verdict"] = pd.DataFrame([{"inputs": name, **turnover_verdict(out[key])}
                                            for name, key in (("mv1", "turnover"), ("mv1+vm4", "turnover_vm4"))])
    out["trend"] = trend_by_period(results)
    out["trend_series"] = pd.concat([series_trends(r.start, r.end).assign(start=r.start, end=r.end)
                                     for r in out["trend"].itertuples()], ignore_index=True)
    out["trend_vm4"] = trend_by_period(results, "mv1+vm4")
    out["trend_verdict"] = pd.DataFrame([{"inputs": name, **turnover_verdict(out[key])}
                                         for name, key in (("mv1", "trend"), ("mv1+vm4", "trend_vm4"))])
    if args.write:
        write_trend(out)
    if not args.no_runs:
        nation = national_runs()
        out["national"] = nation
        out["sum_of_states"] = sum_of_states(all_states_runs(), nation)
    with pd.option_context("display.width", 200, "display.max_columns", 30):
        for name, table in out.items():
            print(f"== {name}")
            print(table.round(2).to_string(index=False))
    return out


if __name__ == "__main__":
    main()
