"""Budget arithmetic: on-road fuel, fiscal years, CO2, calibration to collections and ranges.

The runner's bookkeeping runs on the deterministic stand-in simulation (test_fleet_fakes);
the expected numbers are written from the published sources (40 CFR 600.210-12 label
formulas, EPA-420-F-11-041 CO2 per gallon), not taken from the package.
"""
from __future__ import annotations

import math

import pytest

import test_fleet_fakes as fakes
from test_fleet_fakes import read_csv, scenario, small_fleet, vehicle, write_fleet

ADDITIVE = {"miles": "miles_total", "fuel_gal": "fuel_gal_total", "fuel_gal_low": "fuel_gal_low_total",
            "fuel_gal_high": "fuel_gal_high_total", "state_tax_usd": "state_tax_usd",
            "federal_tax_usd": "federal_tax_usd"}
CO2_G_PER_GAL = {"gasoline": 8887.0, "diesel": 10180.0}   # EPA-420-F-11-041 (2011)


def run_to(tmp_path, path, **injected):
    out = tmp_path / "out"
    result = fakes.invoke_run(path, "--out", out, "--no-cache", "-q", **injected)
    assert result.exit_code == 0, result.stderr
    return out


def test_fiscal_years_reconcile_exactly_with_results(tmp_path):
    out = run_to(tmp_path, small_fleet(tmp_path / "fleet.xlsx"))
    results = read_csv(out / "results.csv")
    fiscal = read_csv(out / "fiscal_summary.csv")
    assert list(fiscal.columns) == ["scenario_id", "fiscal_year", "fuel", "vehicle_class", "miles", "fuel_gal",
                                    "fuel_gal_low", "fuel_gal_high", "co2_t", "kwh", "state_tax_usd",
                                    "federal_tax_usd", "ev_fee_usd"]
    groups = results.groupby(["scenario_id", "fuel", "vehicle_class"])
    assert len(fiscal) == sum(3 if s == "urban" else 2 for (s, _, _) in groups.groups)
    for (scenario_id, fuel, vehicle_class), group in groups:
        rows = fiscal[(fiscal.scenario_id == scenario_id) & (fiscal.fuel == fuel)
                      & (fiscal.vehicle_class == vehicle_class)]
        for column, total in ADDITIVE.items():
            # exact: the fiscal years add up to the results to the last bit
            assert math.fsum(rows[column]) == math.fsum(group[total]), (scenario_id, fuel, vehicle_class, column)
    for row in fiscal.itertuples():
        assert row.co2_t == row.fuel_gal * CO2_G_PER_GAL[row.fuel] / 1e6


def test_first_fiscal_year_labels_the_years_and_growth_splits_them(tmp_path):
    path = write_fleet(tmp_path / "f.xlsx", [vehicle("A", count=10, annual_miles=10000)],
                       [scenario("s", first_fiscal_year=2027, budget_years=2, vmt_growth_pct_per_year=10)])
    fiscal = read_csv(run_to(tmp_path, path) / "fiscal_summary.csv")
    assert list(fiscal.fiscal_year) == [2027, 2028]
    assert fiscal.miles[0] == pytest.approx(100000.0, rel=1e-12)
    assert fiscal.miles[1] == pytest.approx(110000.0, rel=1e-12)


@pytest.mark.parametrize("setting, factor", [("none", 1.0), (1.25, 1.25)])
def test_onroad_none_and_factor(tmp_path, setting, factor):
    path = write_fleet(tmp_path / "f.xlsx", [vehicle("A")], [scenario("s", onroad_adjustment=setting)])
    row = read_csv(run_to(tmp_path, path) / "results.csv").iloc[0]
    assert row.fuel_gal_total == pytest.approx(factor * row.fuel_gal_cycle_total, rel=1e-14)


def test_epa_label_leaves_heavy_trucks_at_cycle_fuel(tmp_path):
    out = run_to(tmp_path, small_fleet(tmp_path / "fleet.xlsx"))
    results = read_csv(out / "results.csv")
    hd = results[results.duty_class == "HD"]
    ld = results[(results.duty_class == "LD") & (results.miles_total > 0)]
    assert (hd.fuel_gal_total == hd.fuel_gal_cycle_total).all()
    # light duty: 1.18-1.35 x cycle fuel plus the intercept, so always more than the cycle
    assert (ld.fuel_gal_total > 1.18 * ld.fuel_gal_cycle_total).all()


def test_calibration_to_collections(tmp_path):
    fleet = [vehicle("CAR", count=1000), vehicle("TRUCK", vehicle_class="Truck", fuel="diesel", count=50)]
    observed = {"gasoline": 700_000.0, "diesel": 45_000.0}
    path = write_fleet(tmp_path / "f.xlsx", fleet, [
        scenario("raw", first_fiscal_year=2027, observed_base_gallons_gasoline=observed["gasoline"],
                 observed_base_gallons_diesel=observed["diesel"], calibrate_to_observed="no"),
        scenario("calibrated", first_fiscal_year=2027, observed_base_gallons_gasoline=observed["gasoline"],
                 observed_base_gallons_diesel=observed["diesel"], calibrate_to_observed="yes")])
    out = run_to(tmp_path, path)
    fiscal = read_csv(out / "fiscal_summary.csv")
    results = read_csv(out / "results.csv")
    for fuel, gallons in observed.items():
        base = fiscal[(fiscal.scenario_id == "calibrated") & (fiscal.fuel == fuel) & (fiscal.fiscal_year == 2027)]
        # the calibrated first fiscal year equals the collections (to floating-point rounding)
        assert math.fsum(base.fuel_gal) == pytest.approx(gallons, rel=1e-12)
        raw = fiscal[(fiscal.scenario_id == "raw") & (fiscal.fuel == fuel) & (fiscal.fiscal_year == 2027)]
        assert math.fsum(raw.fuel_gal) != pytest.approx(gallons, rel=1e-3)
        # the raw (uncalibrated) gallons are still in results.csv, equal to the raw scenario's
        calibrated_rows = results[(results.scenario_id == "calibrated") & (results.fuel == fuel)]
        raw_rows = results[(results.scenario_id == "raw") & (results.fuel == fuel)]
        assert list(calibrated_rows.fuel_gal_uncalibrated_total) == list(raw_rows.fuel_gal_total)
    import openpyxl

    ws = openpyxl.load_workbook(out / "report.xlsx")["Fiscal years"]
    texts = [c for row in ws.iter_rows(values_only=True) for c in row if isinstance(c, str)]
    assert any(t.startswith("Calibration to collections") for t in texts)


def test_ranges_follow_the_error_distribution(tmp_path):
    # one UDDS-only car without the on-road adjustment: the fixture's FTP 5-95 % error is
    # -12 % to +10 %, and gallons go as 1/mpg: measured = predicted x (1 + e)
    path = write_fleet(tmp_path / "f.xlsx", [vehicle("A")], [scenario("s", cycle_mix="UDDS:1", onroad_adjustment="none")])
    row = read_csv(run_to(tmp_path, path) / "results.csv").iloc[0]
    assert row.fuel_gal_low_total == pytest.approx(0.88 * row.fuel_gal_total, rel=1e-12)
    assert row.fuel_gal_high_total == pytest.approx(1.10 * row.fuel_gal_total, rel=1e-12)


def test_without_an_error_file_totals_say_they_have_no_range(tmp_path):
    import json

    path = write_fleet(tmp_path / "f.xlsx", [vehicle("A")], [scenario("s")])
    out = run_to(tmp_path, path, error_model=None)
    assert read_csv(out / "results.csv").fuel_gal_low_total.isna().all()
    assert any("no range" in w for w in json.loads((out / "manifest.json").read_text())["warnings"])


@pytest.mark.parametrize("overrides, message", [
    ({"onroad_adjustment": "label"}, "Scenarios!N2 onroad_adjustment: 'label' is not epa_label, none or a factor"),
    ({"onroad_adjustment": -1}, "Scenarios!N2 onroad_adjustment: -1 must be a factor greater than 0"),
    ({"calibrate_to_observed": "yes"}, "Scenarios!Q2 calibrate_to_observed: is yes, but neither"),
    ({"calibrate_to_observed": "maybe"}, "Scenarios!Q2 calibrate_to_observed: 'maybe' is not one of yes, no"),
])
def test_budget_column_errors(tmp_path, overrides, message):
    path = write_fleet(tmp_path / "f.xlsx", [vehicle("A")], [scenario("s", **overrides)])
    result = fakes.invoke_run(path, "--out", tmp_path / "o", "--no-cache", "-q")
    assert result.exit_code == 1
    assert message in result.stderr
