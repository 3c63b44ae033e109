"""Forecast drivers: fuel price through the price elasticity, tax per fiscal year (docs/budget.md).

Expected values are hand calculations of the documented formulas, not the package's output:
partial adjustment, cumulative elasticity k years after a change e_k = long (1 - (1 - short/long)^k)
(Havranek, Irsova and Janda 2012 give the defaults short -0.09, long -0.31).
"""
from __future__ import annotations

import math

import pytest

from test_budget import run_to
from test_fleet_fakes import read_csv, scenario, vehicle, write_fleet


def _yearly(tmp_path, **columns):
    path = write_fleet(tmp_path / "f.xlsx", [vehicle("A", count=10)],
                       [scenario("s", first_fiscal_year=2027, budget_years=3, vmt_growth_pct_per_year=0, **columns)])
    fiscal = read_csv(run_to(tmp_path, path) / "fiscal_summary.csv")
    return fiscal.set_index("fiscal_year")


def test_price_rise_cuts_gallons_as_the_hand_calculation(tmp_path):
    f = _yearly(tmp_path, fuel_price_gasoline_usd_per_gal="2027:3.00,2028:3.60,2029:3.60",
                price_elasticity_short_run=-0.1, price_elasticity_long_run=-0.4)
    # year 2: +20 % price, first-year response: 1.2^-0.1 = 0.981934
    assert f.fuel_gal[2028] / f.fuel_gal[2027] == pytest.approx(1.2 ** -0.1, rel=1e-12)
    # year 3: the same rise a year later: e_2 = -0.4 (1 - 0.75^2) = -0.175; 1.2^-0.175 = 0.968591
    assert f.fuel_gal[2029] / f.fuel_gal[2027] == pytest.approx(1.2 ** -0.175, rel=1e-12)
    assert f.miles[2028] == f.miles[2027]          # price moves gallons, not the miles input


def test_default_elasticities_are_the_documented_literature_values(tmp_path):
    f = _yearly(tmp_path, fuel_price_gasoline_usd_per_gal="2027:3.00,2028:4.00")   # 2029: as 2028
    assert f.fuel_gal[2028] / f.fuel_gal[2027] == pytest.approx((4 / 3) ** -0.09, rel=1e-12)
    e2 = -0.31 * (1 - (1 - 0.09 / 0.31) ** 2)
    assert f.fuel_gal[2029] / f.fuel_gal[2027] == pytest.approx((4 / 3) ** e2, rel=1e-12)


def test_tax_schedule_and_index(tmp_path):
    f = _yearly(tmp_path / "a", state_tax_schedule_gasoline_usd_per_gal="2027:0.30,2029:0.35")
    rates = f.state_tax_usd / f.fuel_gal
    # 2028 is not listed: the latest listed year before it (2027) applies
    assert list(rates.round(12)) == [0.30, 0.30, 0.35]
    g = _yearly(tmp_path / "b", state_tax_index_pct_per_year=3.0)
    assert list((g.state_tax_usd / g.fuel_gal).round(12)) == [0.2, round(0.2 * 1.03, 12), round(0.2 * 1.03 ** 2, 12)]
    # the federal rate stays one
    assert list((g.federal_tax_usd / g.fuel_gal).round(12)) == [0.184] * 3
    results = read_csv(tmp_path / "b" / "out" / "results.csv")
    assert results.state_tax_usd.iloc[0] == math.fsum(g.state_tax_usd)


def test_bad_schedule_is_an_error_line(tmp_path):
    import test_fleet_fakes as fakes

    path = write_fleet(tmp_path / "f.xlsx", [vehicle("A")],
                       [scenario("s", fuel_price_gasoline_usd_per_gal="2027=3.0")])
    result = fakes.invoke_run(path, "--out", tmp_path / "o", "--no-cache", "-q")
    assert result.exit_code == 1
    assert "Scenarios!" in result.stderr and "YEAR:value" in result.stderr


# FHWA Traffic Volume Trends, April 2019, Figure 2: 2018 average daily VMT [billion], urban + rural
DAILY_2018 = [5.60 + 2.25, 5.76 + 2.28, 6.13 + 2.56, 6.41 + 2.67, 6.35 + 2.79, 6.47 + 2.89, 6.36 + 2.98,
              6.33 + 2.90, 6.09 + 2.68, 6.36 + 2.74, 6.07 + 2.54, 6.19 + 2.51]
DAYS = [31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31]


def test_fiscal_periods_follow_the_start_month_and_published_seasonality(tmp_path):
    path = write_fleet(tmp_path / "f.xlsx", [vehicle("A", count=10)],
                       [scenario("s", first_fiscal_year=2027, budget_years=2, fiscal_year_start_month=9)])
    out = run_to(tmp_path, path)
    periods = read_csv(out / "fiscal_periods.csv", keep_default_na=False)
    memo = read_csv(out / "revenue_memo.csv")
    fy = periods[(periods.fiscal_year == 2027) & (periods.fuel == "gasoline")]
    months = fy[fy.period.str.startswith("M")]
    # FY2027 starting in September: September 2026 to August 2027
    assert list(months.calendar_month) == ["Sep", "Oct", "Nov", "Dec", "Jan", "Feb", "Mar", "Apr", "May", "Jun",
                                           "Jul", "Aug"]
    assert list(months.calendar_year) == [2026] * 4 + [2027] * 8
    total = sum(d * n for d, n in zip(DAILY_2018, DAYS))
    assert months.share.iloc[0] == pytest.approx(DAILY_2018[8] * 30 / total, rel=1e-12)        # September
    gallons = memo[(memo.fiscal_year == 2027) & (memo.fuel == "gasoline")].fuel_gal.iloc[0]
    assert math.fsum(months.fuel_gal) == gallons                      # the months add up exactly
    quarters = fy[fy.period.str.startswith("Q")]
    assert math.fsum(quarters.fuel_gal) == pytest.approx(gallons, rel=1e-12)
    # the memo's all-fuels row is the sum of the fuels, with a range around it
    fy_memo = memo[memo.fiscal_year == 2027].set_index("fuel")
    assert fy_memo.fuel_gal["all fuels"] == pytest.approx(fy_memo.fuel_gal.drop("all fuels").sum(), rel=1e-12)
    assert (fy_memo.fuel_gal_low < fy_memo.fuel_gal).all() and (fy_memo.state_tax_high_usd > fy_memo.state_tax_usd).all()
