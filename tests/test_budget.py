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
FIXTURE_BIAS = 0.02     # tests/data/fleet_error_fixture.toml: the centre is model x (1 + bias)


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
    # the known fleet bias is corrected in the centre: x (1 + bias) on top of the setting
    assert row.fuel_gal_total == pytest.approx(factor * (1 + FIXTURE_BIAS) * row.fuel_gal_cycle_total, rel=1e-14)


def test_epa_label_leaves_heavy_trucks_at_cycle_fuel(tmp_path):
    out = run_to(tmp_path, small_fleet(tmp_path / "fleet.xlsx"))
    results = read_csv(out / "results.csv")
    hd = results[results.duty_class == "HD"]
    ld = results[(results.duty_class == "LD") & (results.miles_total > 0)]
    # no label formula for heavy trucks: cycle fuel, with only the bias correction (the fixture
    # has no heavy-duty constants, so the light-duty ones stand in)
    assert hd.fuel_gal_total.to_numpy() == pytest.approx((1 + FIXTURE_BIAS) * hd.fuel_gal_cycle_total.to_numpy(),
                                                         rel=1e-14)
    # light duty: 1.18-1.35 x cycle fuel plus the intercept, so always more than the cycle
    assert (ld.fuel_gal_total > 1.18 * ld.fuel_gal_cycle_total).all()


def _calibration_fleet(tmp_path, observed, first_says="yes", second=None):
    fleet = [vehicle("CAR", count=1000), vehicle("TRUCK", vehicle_class="Truck", fuel="diesel", count=50)]
    gallons = {"observed_base_gallons_gasoline": observed["gasoline"],
               "observed_base_gallons_diesel": observed["diesel"]}
    return write_fleet(tmp_path / "f.xlsx", fleet, [
        scenario("base", first_fiscal_year=2027, calibrate_to_observed=first_says, **gallons),
        scenario("hot", first_fiscal_year=2027, ambient_temp_C=38, **(second or {})),
        scenario("urban", first_fiscal_year=2027, cycle_mix="UDDS:1", vmt_growth_pct_per_year=3)])


def _totals(out):
    results = read_csv(out / "results.csv")
    return {(s, f): math.fsum(g.fuel_gal_total) for (s, f), g in results.groupby(["scenario_id", "fuel"])}


def test_calibration_is_one_factor_that_keeps_scenarios_apart(tmp_path):
    observed = {"gasoline": 700_000.0, "diesel": 45_000.0}
    raw = _totals(run_to(tmp_path / "raw", _calibration_fleet(tmp_path / "raw", observed, "no")))
    out = run_to(tmp_path / "cal", _calibration_fleet(tmp_path / "cal", observed, "yes"))
    calibrated = _totals(out)
    fiscal = read_csv(out / "fiscal_summary.csv")
    for fuel, gallons in observed.items():
        base = fiscal[(fiscal.scenario_id == "base") & (fiscal.fuel == fuel) & (fiscal.fiscal_year == 2027)]
        # the base scenario's first fiscal year equals the collections (to floating-point rounding)
        assert math.fsum(base.fuel_gal) == pytest.approx(gallons, rel=1e-12)
        for other in ("hot", "urban"):
            # one factor for every scenario: the scenario-to-baseline ratio is the model's
            assert calibrated[(other, fuel)] / calibrated[("base", fuel)] == pytest.approx(
                raw[(other, fuel)] / raw[("base", fuel)], rel=1e-12)
            assert calibrated[(other, fuel)] != pytest.approx(gallons * 2, rel=1e-3)
    results = read_csv(out / "results.csv")
    assert (results.fuel_gal_low_total < results.fuel_gal_total).all()     # a calibrated total has a range
    import openpyxl

    ws = openpyxl.load_workbook(out / "report.xlsx")["Fiscal years"]
    texts = [c for row in ws.iter_rows(values_only=True) for c in row if isinstance(c, str)]
    assert any(t.startswith("Calibration to collections") for t in texts)


def test_calibrated_range_is_year_two_uncertainty(tmp_path):
    observed = {"gasoline": 700_000.0, "diesel": 45_000.0}
    fiscal = read_csv(run_to(tmp_path, _calibration_fleet(tmp_path, observed)) / "fiscal_summary.csv")
    base = fiscal[fiscal.scenario_id == "base"].groupby("fiscal_year")[["fuel_gal", "fuel_gal_low", "fuel_gal_high"]].sum()
    width = (base.fuel_gal_high - base.fuel_gal_low) / base.fuel_gal
    # year 1 is observed: only the 1 % sd of the collections (90 %: +-1.645 %); year 2 adds
    # growth and price (models/budget.toml), so it is wider
    assert width[2027] == pytest.approx(2 * 1.645 * 0.01, rel=0.1)
    assert width[2028] > 1.5 * width[2027]


def test_an_implausible_calibration_ratio_warns(tmp_path):
    import json

    observed = {"gasoline": 70_000.0, "diesel": 45_000.0}     # the model burns ~10x this
    out = run_to(tmp_path, _calibration_fleet(tmp_path, observed))
    warnings = json.loads((out / "manifest.json").read_text())["warnings"]
    assert any("calibration: the model's gasoline gallons are" in w and "plausible 80%-125%" in w for w in warnings)


def test_ranges_shrink_with_fleet_size_and_centre_on_the_bias(tmp_path):
    # fixture: tau 0.03 between manufacturers, sigma 0.08 per vehicle type; one light-duty
    # fuel, growth 0, no price path. Model part of the 90 % range for n equal unknown-make
    # types: 1.645 x sqrt((tau^2 (1 - HHI) + sigma^2) / n), HHI = 0.6^2 + 0.4^2 = 0.52.
    widths = {}
    for n in (1, 25):
        path = write_fleet(tmp_path / f"f{n}.xlsx", [vehicle(f"V{i}") for i in range(n)],
                           [scenario("s", cycle_mix="UDDS:1", budget_years=1, vmt_growth_pct_per_year=0)])
        results = read_csv(run_to(tmp_path / str(n), path) / "results.csv")
        total = math.fsum(results.fuel_gal_total)
        widths[n] = (math.fsum(results.fuel_gal_high_total) - math.fsum(results.fuel_gal_low_total)) / total / 2
    model = {n: 1.645 * math.sqrt((0.03 ** 2 * 0.48 + 0.08 ** 2) / n) for n in (1, 25)}
    # year 1: price sd 0.15 x short-run -0.09 and mix sd 0.02 add in quadrature
    other = 1.645 * math.hypot(0.15 * 0.09, 0.02)
    for n in (1, 25):
        expected = math.sqrt(model[n] ** 2 + other ** 2)
        assert widths[n] == pytest.approx(expected, rel=0.06), n   # Monte Carlo, 4000 draws


def test_without_an_error_file_ranges_hold_the_drivers_only(tmp_path):
    import json

    path = write_fleet(tmp_path / "f.xlsx", [vehicle("A")], [scenario("s")])
    out = run_to(tmp_path, path, error_model=None)
    results = read_csv(out / "results.csv")
    assert (results.fuel_gal_low_total < results.fuel_gal_total).all()
    assert any("drivers only" in w for w in json.loads((out / "manifest.json").read_text())["warnings"])


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


def test_heavy_duty_error_file_of_per_test_distributions(tmp_path, monkeypatch):
    """models/heavy_duty/fuel_economy_error.toml in the heavy-duty validation's format: no
    centre correction; the error of a total mixes the tests by an unknown share s ~ U(0, 1)
    (mean and sd interpolated between the tests'), so a one-sided miss widens one side only.
    Checked against a direct Monte Carlo of that description (200,000 draws: its percentiles
    are good to ~0.1 point)."""
    import shutil
    import tomllib

    import numpy as np

    from fleetrun.budget import uncertainty

    models = tmp_path / "models"
    shutil.copytree(uncertainty.models_dir(), models)
    (models / "heavy_duty").mkdir(exist_ok=True)
    (models / "heavy_duty" / "fuel_economy_error.toml").write_text(
        'source = "fixture"\n[tests.A]\nmean = 0.30\np05 = 0.20\np95 = 0.40\n'
        '[tests.B]\nmean = -0.01\np05 = -0.05\np95 = 0.03\n')
    monkeypatch.setattr(uncertainty, "models_dir", lambda: models)
    model = uncertainty.read_error_model()
    heavy = model.for_duty("HD")
    assert heavy.bias == 0.0 and heavy.shared
    rng = np.random.default_rng(1)
    share, z = rng.random(200_000), rng.standard_normal(200_000)
    sd_b, sd_a = 0.08 / 3.2897072539029444, 0.20 / 3.2897072539029444
    direct = (-0.01 + share * 0.31) + (sd_b + share * (sd_a - sd_b)) * z
    low, high = heavy.range90()
    assert low == pytest.approx(np.quantile(direct, 0.05), abs=0.002)
    assert high == pytest.approx(np.quantile(direct, 0.95), abs=0.002)
    assert high > 0.3 and low > -0.06          # the miss (+30 %) widens the upper side only
    # light duty keeps its own constants (models/fleet_error.toml); no fallback warning
    light = tomllib.loads((models / "fleet_error.toml").read_text())["LD"]
    assert model.for_duty("LD").tau == light["tau"] and not model.warnings


def _split_fleet(tmp_path, split, says="yes"):
    """A light-duty car and pickup (gasoline, diesel) and a heavy diesel truck; three scenarios."""
    heavy = vehicle("SEMI", vehicle_class="Heavy truck", duty_class="HD", configuration="HD_TANDEM",
                    fuel="diesel", transmission="manual", transmission_gear_ratios="12.8,9.3,6.8,4.9,3.6,2.6,1.9,1.4,1.0,0.73",
                    final_drive_ratio=3.55, test_weight_kg=29000, peak_engine_torque_Nm=2500, coastdown_A_lbf=240,
                    coastdown_B_lbf_per_mph=1.5, coastdown_C_lbf_per_mph2=0.12, tire_size="295/75R22.5", count=30,
                    annual_miles=80000)
    fleet = [vehicle("CAR", count=1000), vehicle("PICKUP", vehicle_class="Pickup", fuel="diesel", count=200), heavy]
    return write_fleet(tmp_path / "f.xlsx", fleet, [
        scenario("base", first_fiscal_year=2027, calibrate_to_observed=says, **split),
        scenario("hot", first_fiscal_year=2027, ambient_temp_C=38, cycle_mix_HD="HD-UDDS:1"),
        scenario("urban", first_fiscal_year=2027, cycle_mix="UDDS:1", vmt_growth_pct_per_year=3)])


def _group_totals(out):
    results = read_csv(out / "results.csv")
    group = ["HD" if v == "SEMI" else "LD" for v in results.vehicle_id]
    return {k: math.fsum(g.fuel_gal_total) for k, g in results.assign(group=group).groupby(["scenario_id", "fuel", "group"])}


def test_per_class_calibration_is_one_factor_per_fuel_and_group(tmp_path):
    """Diesel collections split into light and medium/heavy duty: each group's base year equals
    its collections, each group's factor is one number for every scenario (so every scenario-
    to-baseline ratio per fuel and group is the model's), gasoline keeps one factor."""
    split = {"observed_base_gallons_gasoline": 700_000.0, "observed_base_gallons_diesel_LD": 60_000.0,
             "observed_base_gallons_diesel_HD": 900_000.0}
    raw = _group_totals(run_to(tmp_path / "raw", _split_fleet(tmp_path / "raw", split, "no")))
    out = run_to(tmp_path / "cal", _split_fleet(tmp_path / "cal", split))
    calibrated = _group_totals(out)
    fiscal = read_csv(out / "fiscal_summary.csv")
    base = fiscal[(fiscal.scenario_id == "base") & (fiscal.fiscal_year == 2027) & (fiscal.fuel == "diesel")]
    assert math.fsum(base[base.vehicle_class == "Heavy truck"].fuel_gal) == pytest.approx(900_000.0, rel=1e-12)
    assert math.fsum(base[base.vehicle_class != "Heavy truck"].fuel_gal) == pytest.approx(60_000.0, rel=1e-12)
    factors = {key: calibrated[key] / raw[key] for key in raw}
    for (scenario_id, fuel, group), factor in factors.items():
        assert factor == pytest.approx(factors[("base", fuel, group)], rel=1e-12)
        assert calibrated[(scenario_id, fuel, group)] / calibrated[("base", fuel, group)] == pytest.approx(
            raw[(scenario_id, fuel, group)] / raw[("base", fuel, group)], rel=1e-12)
    assert factors[("base", "diesel", "LD")] != pytest.approx(factors[("base", "diesel", "HD")], rel=1e-3)
    import openpyxl

    ws = openpyxl.load_workbook(out / "report.xlsx")["Fiscal years"]
    cells = [c for row in ws.iter_rows(values_only=True) for c in row]
    assert "class_group" in cells and "HD" in cells and "LD" in cells


def test_per_class_calibration_needs_both_groups_and_an_agreeing_total(tmp_path):
    half = {"observed_base_gallons_diesel_LD": 60_000.0}
    result = fakes.invoke_run(_split_fleet(tmp_path, half), "--out", tmp_path / "o", "--no-cache", "-q")
    assert result.exit_code == 1 and "observed_base_gallons_diesel_HD: is empty, but" in result.stderr
    apart = {"observed_base_gallons_diesel": 1_000_000.0, "observed_base_gallons_diesel_LD": 60_000.0,
             "observed_base_gallons_diesel_HD": 900_000.0}
    result = fakes.invoke_run(_split_fleet(tmp_path, apart), "--out", tmp_path / "o", "--no-cache", "-q")
    assert result.exit_code == 1 and "observed_base_gallons_diesel: is 1,000,000, but" in result.stderr


def test_observed_gallons_of_a_group_without_rows_warn(tmp_path):
    import json

    path = _split_fleet(tmp_path, {"observed_base_gallons_gasoline_LD": 700_000.0,
                                   "observed_base_gallons_gasoline_HD": 5_000.0})    # no HD gasoline rows
    warnings = json.loads((run_to(tmp_path, path) / "manifest.json").read_text())["warnings"]
    assert any("gasoline (medium/heavy duty) gallons (5,000), but the fleet has no such gallons" in w for w in warnings)
