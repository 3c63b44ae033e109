"""The turnover efficiency by model year (models/turnover.toml ``[trend.*]``) against EPA
Automotive Trends, and the pre-registered candidates' findings (validation/turnover_candidates.py;
docs/validation-state-fuel.md, "Why the model's fleet loses mpg over 2000-2008").

Published numbers: EPA Automotive Trends 2022 edition, car / truck real-world and 2-cycle mpg
and production (M5)
(``inputs/epa_trends/``); FHWA VM-1 on-road mpg of 2000 (passenger cars 22.0, other 2-axle
4-tire vehicles 17.5; ``inputs/state_statistics/national_years.csv``) and VM-1's change
2000 -> 2001 (+0.91 / +1.15 %/yr) and 2003 -> 2004 (+1.35 / 0.00 %/yr).
"""
from __future__ import annotations

import sys
import tomllib
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]


def _modules():
    sys.path.insert(0, str(ROOT / "validation"))
    sys.path.insert(0, str(ROOT / "models" / "vehicle_library"))
    import make_trends
    import turnover_candidates

    return make_trends, turnover_candidates


def test_turnover_tables_are_the_non_electric_trends_columns():
    """turnover.toml's car and light-truck tables equal make_trends.py's derivation from the
    Trends export to the two decimals written; Trends' own values where no vehicle is electric
    (MY2000 car 22.5144, truck 16.83964 mpg)."""
    make_trends, _ = _modules()
    with open(ROOT / "models" / "turnover.toml", "rb") as f:
        trend = tomllib.load(f)["trend"]
    for name, regulatory_class in make_trends.TABLES.items():
        derived = make_trends.nonelectric_mpg(regulatory_class)
        shipped = pd.Series({int(y): v for y, v in trend[name]["mpg_by_model_year"].items()})
        assert list(shipped.index) == list(derived.index)
        assert shipped.to_numpy() == pytest.approx(derived.round(2).to_numpy(), abs=1e-9)
    assert trend["car"]["mpg_by_model_year"]["2000"] == pytest.approx(22.51, abs=0.005)
    assert trend["light_truck"]["mpg_by_model_year"]["2000"] == pytest.approx(16.84, abs=0.005)


def test_non_electric_all_light_duty_2022_matches_the_2023_report():
    """The derivation checked on a figure it was not built from: all light-duty MY2022 without
    electric vehicles 24.85 mpg (2022 edition, preliminary) against the 2023 edition's 24.8 mpg
    without BEVs and PHEVs (358 g/mi); 1 % covers the preliminary-to-final revision (26.36 ->
    26.0 mpg with them) and the PHEVs left in."""
    make_trends, _ = _modules()
    assert make_trends.nonelectric_mpg("all")[2022] == pytest.approx(24.8, rel=0.01)


@pytest.mark.slow
def test_calendar_shortfall_does_not_explain_the_2000_2003_turnover():
    """H1 (pre-registered): the real-world shortfall moved from the model year to the calendar
    year (H1b) leaves the turnover change from 2000 and 2003 within 0.15 %/yr of the rule it
    replaces (rw_all) and below VM-1's range; the adopted per-class tables (shipped) move both
    periods up by at least 0.25 %/yr and keep the national gasoline within the issue's 5 %."""
    _, candidates = _modules()
    table = candidates.main(["--candidates", "rw_all,H1b,shipped", "--years", "2000,2003"])
    change = table.set_index(["candidate", "year"]).ld_mpg_change_pct_per_year
    error = table.set_index(["candidate", "year"]).gasoline_error_pct
    for year, vm1_low in ((2000, 0.91), (2003, 0.00)):
        assert abs(change["H1b", year] - change["rw_all", year]) <= 0.15, year
        assert change["H1b", year] < vm1_low
        assert change["shipped", year] - change["rw_all", year] >= 0.25, year
        assert abs(error["shipped", year]) <= 5.0, year


@pytest.mark.slow
def test_class_mpg_of_2000_on_vm1():
    """The adopted tables put the nation's 2000 automobiles and light trucks within 2 % of VM-1's
    passenger cars (22.0 mpg) and other 2-axle 4-tire vehicles (17.5): measured 22.09 and 17.28
    (before: 22.79 and 18.07, +3.6 and +3.3 %)."""
    _, candidates = _modules()
    row = candidates.main(["--candidates", "shipped", "--years", "2000"]).iloc[0]
    assert row.automobile_mpg == pytest.approx(22.0, rel=0.02)
    assert row.light_truck_mpg == pytest.approx(17.5, rel=0.02)


def test_m2_age_distribution_is_production_times_survival():
    """Candidate M2 (pre-registered): the base year's age shares are Trends' production of each
    model year times survival, normalised. Trends 2022 export: cars MY2000 9,742 thousand,
    MY1990 8,875; so the share at age 0 over age 10 in 2000 is (9742 x S(0)) / (8875 x S(10))."""
    _, candidates = _modules()
    from fleetrun.registrations import turnover

    shares = candidates.production_age_distribution("automobile", 2000)
    survival = turnover.survival("automobile")
    assert shares.sum() == pytest.approx(1.0, abs=1e-12)
    assert shares[0] / shares[10] == pytest.approx(9742 * survival[0] / (8875 * survival[10]), rel=1e-12)
    # model years before Trends' first (1975) take 1975's production: ages 25 (MY1975) and 26 (MY1974)
    early = candidates.production_age_distribution("light_truck", 2000)
    truck_survival = turnover.survival("light_truck")
    assert early[26] / early[25] == pytest.approx(truck_survival[26] / truck_survival[25], rel=1e-12)


def test_m5_entering_volumes_are_scaled_production():
    """Candidate M5 (pre-registered, docs/validation-state-fuel.md): model year y enters k x P(y)
    vehicles, k = N / sum_a P(B - a) S(a). Trends 2022 export: cars MY2001 9,148 thousand, trucks
    MY2009 3,071 thousand; after the table (MY2021) and for classes without a Trends column the
    scrapped vehicles are replaced (stock kept at the previous year's count)."""
    import numpy as np

    _, candidates = _modules()
    from fleetrun.registrations import turnover

    survival = turnover.survival("automobile")
    cars = candidates.production("automobile")
    years = np.clip(2000 - np.arange(len(survival)), 1975, 2021)
    expected_k = 1e6 / float((cars.reindex(years).to_numpy(float) * survival).sum())
    total, kept = np.array([1e6, 9.4e5]), np.array([1e6, 9.4e5])
    sold, rule = candidates.entering("automobile", 2000, total, kept, 1)
    assert sold == pytest.approx(expected_k * 9148, rel=1e-12) and "Trends production" in rule
    assert candidates.production("light_truck")[2009] == 3071
    sold, rule = candidates.entering("automobile", 2021, total, kept, 1)
    assert sold == pytest.approx(6e4, rel=1e-12) and "replacement" in rule
    assert candidates.entering("bus", 2000, total, kept, 1)[0] == pytest.approx(6e4, rel=1e-12)


def test_m5_measured_leaves_75_of_98_within():
    """M5 measured on the 98 MV-1-only state-years (validation/data/turnover_candidates_m5_state_years.csv,
    judged by validation/gasoline_by_year.py as pre-registered P2): 75 within under both the shipped
    rule and M5, so M5's adoption condition (more state-years within) fails; 2000->01 / 2003->04
    move down, away from their ranges, 2008->09 / 2009->10 down but still above; the base-year
    gasoline is identical (the base year has no new sales)."""
    _, candidates = _modules()
    import gasoline_by_year

    table = pd.read_csv(ROOT / "validation" / "data" / "turnover_candidates_m5_state_years.csv")
    shipped, m5 = (table[table.candidate == name].set_index(["state", "year"]) for name in ("shipped", "M5"))
    stored = pd.read_csv(ROOT / "docs" / "validation-state-fuel.csv")
    stored = stored[stored.inputs == "mv1"].set_index(["state", "year"])
    assert (shipped.ld_mpg_change_pct_per_year - stored.ld_mpg_change_pct_per_year).abs().max() == 0.0
    assert (m5.gasoline_model_Mgal - shipped.gasoline_model_Mgal).abs().max() == 0.0
    periods = {name: gasoline_by_year.turnover_by_period(part.reset_index()).set_index(["start", "end"])
               for name, part in (("shipped", shipped), ("M5", m5))}
    verdicts = {name: gasoline_by_year.turnover_verdict(p.reset_index()) for name, p in periods.items()}
    assert verdicts["shipped"]["within"] == verdicts["M5"]["within"] == 75
    assert (periods["M5"].within >= periods["shipped"].within).all()
    moved = m5.ld_mpg_change_pct_per_year - shipped.ld_mpg_change_pct_per_year
    for year in (2000, 2003, 2008, 2009):
        assert (moved.xs(year, level="year") < 0).all(), year
    for period in ((2008, 2009), (2009, 2010)):
        row = periods["M5"].loc[period]
        assert row.vm1_high < row.model_low, period
