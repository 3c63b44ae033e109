"""A fleet from registrations (docs/registrations.md): the sheet read, every row's choice
listed, turnover against its published sources, miles scaled to the state's VMT, budget
tables that reconcile, and extracts read in chunks.

Published values compared with (not re-typed from models/, read from the sources' numbers):
EPA OMEGA re-registration of sedans at ages 10 and 11 (0.799891, 0.755631; OMEGA
``reregistration_fixed_by_age_ice_bev_phev-body_style.csv``), EPA Automotive Trends 2022 edition new-vehicle
real-world mpg of cars and trucks of model years 2000 and 2022 (non-electric: the class's electric
share taken out at the all-electric manufacturer's mpg-equivalent, inputs/epa_trends/).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import openpyxl
import pandas as pd
import pytest

from fleetrun.errors import InputError
from fleetrun.registrations import expand
from fleetrun.registrations.expand import FleetYears
from fleetrun.registrations.extract import read_extract
from fleetrun.workbook import read_fleet
from fleetrun.workbook.reader import Fleet, Scenario

SCENARIO = ["scenario_id", "ambient_temp_C", "cycle_mix", "budget_years", "vmt_growth_pct_per_year",
            "state_tax_gasoline_usd_per_gal", "state_tax_diesel_usd_per_gal", "federal_tax_gasoline_usd_per_gal",
            "federal_tax_diesel_usd_per_gal", "first_fiscal_year", "base_year_vmt_million"]


def scenario(**kw) -> Scenario:
    fields = dict(scenario_id="s", description="", ambient_temp_C=20.0, cycle_mix={"UDDS": 1.0}, budget_years=3,
                  vmt_growth_pct_per_year=1.0, state_tax_gasoline_usd_per_gal=0.2, state_tax_diesel_usd_per_gal=0.2,
                  federal_tax_gasoline_usd_per_gal=0.184, federal_tax_diesel_usd_per_gal=0.244,
                  first_fiscal_year=2024)
    fields.update(kw)
    return Scenario(**fields)


def fleet_of(rows, vehicles=()) -> Fleet:
    return Fleet(Path("x.xlsx"), "", list(vehicles), [], registrations=[{**r, "_row": i + 2} for i, r in enumerate(rows)])


def registrations_workbook(path: Path, rows, scenario_row=None) -> Path:
    wb = openpyxl.Workbook()
    ws = wb.active
    ws.title = "Registrations"
    names = sorted({k for r in rows for k in r}, key=lambda k: ["vehicle_class", "count"].index(k)
                   if k in ("vehicle_class", "count") else 9)
    ws.append(names)
    for r in rows:
        ws.append([r.get(n) for n in names])
    sc = wb.create_sheet("Scenarios")
    sc.append(SCENARIO)
    sc.append(scenario_row or ["s", 20, "default", 2, 1.0, 0.2, 0.2, 0.184, 0.244, 2024, 1000])
    wb.save(path)
    return path


def test_a_workbook_with_only_registrations_reads_and_default_mixes_apply(tmp_path):
    fleet = read_fleet(registrations_workbook(tmp_path / "r.xlsx", [{"vehicle_class": "truck", "count": 1000}]))
    assert fleet.vehicles == [] and fleet.registrations[0]["vehicle_class"] == "truck"
    s = fleet.scenarios[0]
    # cycle_mix = default: light duty EPA 55/45; MD and HD EPA GEM's vocational multi-purpose and
    # day-cab weightings of 40 CFR 1037.510(c) on GEM's own cycles (ARB transient, 55 / 65 mph cruise)
    # (the cycles are whatever models/heavy_duty/gem_cycles.toml, their owner, names for GEM's parts)
    from fleetrun.simulation.heavy_duty_gem import gem_cycle_mix

    assert s.cycle_mix == {"UDDS": 0.55, "HWFET": 0.45}
    assert s.cycle_mix_MD == gem_cycle_mix("vocational_multipurpose") and s.cycle_mix_HD == gem_cycle_mix("day_cab")
    assert list(s.cycle_mix_MD.values()) == [0.54, 0.29, 0.17] and list(s.cycle_mix_HD.values()) == [0.19, 0.17, 0.64]
    assert next(iter(s.cycle_mix_HD)) == "ARB-TRANSIENT"
    assert s.base_year_vmt_million == 1000


def _with_shares(tmp_path, text):
    row = ["s", 20, "default", 2, 1.0, 0.2, 0.2, 0.184, 0.244, 2024, 1000, text]
    path = registrations_workbook(tmp_path / "r.xlsx", [{"vehicle_class": "truck", "count": 1000},
                                                        {"vehicle_class": "automobile", "count": 900}], row)
    wb = openpyxl.load_workbook(path)
    wb["Scenarios"].cell(1, len(SCENARIO) + 1).value = "base_year_vmt_share_pct"
    wb.save(path)
    return path


def test_class_shares_of_the_miles_hold_every_year(tmp_path):
    """base_year_vmt_share_pct (docs/registrations.md, "Miles by class"): each listed class
    drives its percent of the scenario's miles in every budget year, the others the rest."""
    fleet = read_fleet(_with_shares(tmp_path, "combination_truck:9.5, single_unit_truck: 4.25"))
    s = fleet.scenarios[0]
    assert s.base_year_vmt_share_pct == {"combination_truck": 9.5, "single_unit_truck": 4.25}
    e = expand(fleet, [s])
    miles = FleetYears([], e).year_miles(s)
    total = miles.sum(axis=0)
    assert total == pytest.approx([1e9, 1.01e9], rel=1e-12)
    for name, pct in s.base_year_vmt_share_pct.items():
        assert miles[e.fhwa_class == name].sum(axis=0) / total == pytest.approx(pct / 100, rel=1e-12)


@pytest.mark.parametrize("text, message", [
    ("combination_trucks:9", "did you mean combination_truck"),
    ("bus:60, combination_truck:50", "adds up to 110 %"),
    ("combination_truck", "has no ':percent'"),
])
def test_bad_class_shares_are_named(tmp_path, text, message):
    with pytest.raises(InputError) as info:
        read_fleet(_with_shares(tmp_path, text))
    assert "base_year_vmt_share_pct" in str(info.value) and message in str(info.value)


def test_shares_that_look_like_fractions_are_warned_and_a_percent_sign_is_read(tmp_path):
    fleet = read_fleet(_with_shares(tmp_path, "combination_truck:0.09, single_unit_truck:0.04"))
    assert any("these are percents" in w for w in fleet.warnings)
    fleet = read_fleet(_with_shares(tmp_path, "combination_truck:9%"))
    assert fleet.scenarios[0].base_year_vmt_share_pct == {"combination_truck": 9.0}
    assert not any("these are percents" in w for w in fleet.warnings)


def test_a_share_for_a_class_without_registrations_is_refused(tmp_path):
    with pytest.raises(InputError, match="Scenarios!L2 base_year_vmt_share_pct.*share of the miles to bus"):
        read_fleet(_with_shares(tmp_path, "bus:0.5"))


def test_bad_registration_cells_are_named(tmp_path):
    path = registrations_workbook(tmp_path / "r.xlsx", [{"vehicle_class": "lorry", "count": -5},
                                                        {"vehicle_class": "bus", "count": 3, "vehicle_id": "nope"}])
    with pytest.raises(InputError) as info:
        read_fleet(path)
    text = str(info.value)
    assert "Registrations!A2 vehicle_class" in text and "lorry" in text
    assert "Registrations!B2 count" in text
    assert "'nope' is not a vehicle_id of the Vehicles sheet" in text


def test_every_row_is_listed_and_counts_are_kept():
    rows = [{"vehicle_class": "truck", "count": 1_000_000}, {"vehicle_class": "automobile", "count": 500,
             "model_year": 2010, "fuel": "gasoline", "make": "Toyota", "model": "Camry"},
            {"vehicle_class": "automobile", "count": 7, "fuel": "electric"}]
    e = expand(fleet_of(rows), [scenario()])
    listed = e.choices[e.choices.registration_row != "new sales"]
    assert set(listed.registration_row) == {"Registrations!row 2", "Registrations!row 3", "Registrations!row 4"}
    assert math.isclose(listed["count"].sum(), 1_000_507, rel_tol=1e-12)
    # the base year holds every registered vehicle that has a representing vehicle
    assert math.isclose(e.counts[:, 0].sum(), 1_000_500, rel_tol=1e-9)
    camry = listed[listed.registration_row == "Registrations!row 3"].iloc[0]
    assert camry.matched_on.startswith("make + model") and camry.vehicle.startswith("EPA:")
    ev = listed[listed.registration_row == "Registrations!row 4"].iloc[0]
    assert ev.vehicle == "not modelled" and any("7 vehicles have no representing vehicle" in w for w in e.warnings)


def test_survival_follows_omega_and_new_sales_keep_the_stock():
    rows = [{"vehicle_class": "automobile", "count": 1000, "model_year": 2014, "fuel": "gasoline"}]
    e = expand(fleet_of(rows), [scenario()])
    mine = [i for i, v in enumerate(e.vehicles) if v.model_year == 2014]
    kept = e.counts[mine].sum(axis=0)
    assert kept[0] == pytest.approx(1000)
    assert kept[1] / kept[0] == pytest.approx(0.755631 / 0.799891, rel=1e-5)   # OMEGA sedan ages 10 -> 11
    assert e.counts.sum(axis=0) == pytest.approx([1000, 1000, 1000])         # scrapped ones replaced
    assert set(v.model_year for v in e.vehicles) == {2014, 2025, 2026}


def non_electric(mpg: float, ev_share: float, ev_mpg: float) -> float:
    """A Trends class mean with its electric vehicles taken out of the harmonic mean [mpg]."""
    return (1 - ev_share) / (1 / mpg - ev_share / ev_mpg)


@pytest.mark.parametrize("fhwa_class, mpg_2000, mpg_2022", [
    # Trends 2022 edition: car 22.5144 (MY2000), 33.26706 with 13.3 % electric at 123.18596 mpge
    # (MY2022, preliminary); truck 16.83964, 23.40912 with 3.4 % at 115.43159
    ("automobile", 22.5144, non_electric(33.26706, 0.133, 123.18596)),
    ("light_truck", 16.83964, non_electric(23.40912, 0.034, 115.43159))])
def test_model_year_fuel_per_mile_follows_epa_trends_of_its_class(fhwa_class, mpg_2000, mpg_2022):
    """A MY2000 automobile burns the MY2022 library car's fuel x Trends' car mpg ratio (light
    trucks: the truck ratio); tolerance 5e-4: models/turnover.toml keeps two decimals."""
    rows = [{"vehicle_class": fhwa_class, "count": 10, "model_year": my, "fuel": "gasoline"} for my in (2000, 2022)]
    e = expand(fleet_of(rows), [scenario(budget_years=1)])
    factor = e.fuel_factor(scenario(budget_years=1))
    by_year = {v.model_year: f for v, f in zip(e.vehicles, factor)}
    assert by_year[2000] / by_year[2022] == pytest.approx(mpg_2022 / mpg_2000, rel=5e-4)


def test_base_year_vmt_scales_all_miles_and_growth_follows():
    s = scenario(base_year_vmt_million=2500.0, vmt_growth_pct_per_year=2.0)
    e = expand(fleet_of([{"vehicle_class": "truck", "count": 100_000}, {"vehicle_class": "automobile",
                                                                        "count": 90_000}]), [s])
    miles = FleetYears([], e).year_miles(s).sum(axis=0)
    assert miles == pytest.approx([2.5e9, 2.55e9, 2.601e9], rel=1e-12)


def test_budget_tables_reconcile_and_the_change_splits_exactly(tmp_path):
    from tests.test_fleet_fakes import fake_simulate
    from fleetrun.run.runner import run_fleet

    path = registrations_workbook(tmp_path / "r.xlsx", [{"vehicle_class": "truck", "count": 50_000},
                                                        {"vehicle_class": "automobile", "count": 60_000},
                                                        {"vehicle_class": "bus", "count": 300}],
                                  ["s", 20, "default", 3, 1.5, 0.2, 0.2, 0.184, 0.244, 2024, 1500])
    result = run_fleet(read_fleet(path), simulate=fake_simulate, error_model=None)
    fiscal = result.fiscal
    assert math.fsum(fiscal.miles) == pytest.approx(math.fsum(result.results.miles_total), rel=1e-12)
    year1 = fiscal[fiscal.fiscal_year == 2024]
    assert math.fsum(year1.miles) == pytest.approx(1.5e9, rel=1e-9)
    for column in ("miles", "fuel_gal"):
        for cls, group in result.results.groupby("vehicle_class"):
            assert math.fsum(fiscal[fiscal.vehicle_class == cls][column]) == \
                pytest.approx(math.fsum(group[column if column == "miles" else "fuel_gal_total"]
                                        if column != "miles" else group.miles_total), rel=1e-12)
    t = result.turnover.dropna()
    assert (t.change_from_vmt_gal + t.change_from_gal_per_mile_gal).to_numpy() == pytest.approx(t.change_gal.to_numpy())
    assert (t.change_from_gal_per_mile_gal < 0).all()     # newer model years use less fuel per mile
    assert result.results.model_year.notna().all()
    assert len(result.registrations) >= 3


def test_extract_is_read_in_chunks_to_the_same_counts(tmp_path):
    rng = np.random.default_rng(3)
    n = 5000
    frame = pd.DataFrame({"vehicle_class": rng.choice(["automobile", "light_truck", "bus"], n),
                          "make": rng.choice(["Toyota", "Ford", ""], n), "model": rng.choice(["Camry", "F150"], n),
                          "model_year": rng.integers(1990, 2025, n), "other": 1})
    path = tmp_path / "x.csv"
    frame.to_csv(path, index=False)
    whole = read_extract(path, chunk_rows=10**6)
    chunked = read_extract(path, chunk_rows=333)
    key = ["vehicle_class", "make", "model", "model_year"]
    a = whole.sort_values(key, na_position="first").reset_index(drop=True)
    b = chunked.sort_values(key, na_position="first").reset_index(drop=True)
    pd.testing.assert_frame_equal(a, b, check_dtype=False)
    assert a["count"].sum() == n
    assert len(a) == frame.assign(make=frame.make.replace("", None)).groupby(key, dropna=False).ngroups


def test_extract_errors_name_the_line(tmp_path):
    path = tmp_path / "x.csv"
    path.write_text("vehicle_class,count\nautomobile,3\nspaceship,1\n", encoding="utf-8")
    with pytest.raises(InputError, match="line 3: vehicle_class 'spaceship'"):
        read_extract(path)


def test_import_registrations_then_run_lists_every_row(tmp_path):
    """The analyst's path end to end with the stand-in simulation: extract -> workbook -> run;
    registrations.csv and turnover.csv beside the usual outputs, the report's Registrations sheet."""
    from click.testing import CliRunner

    from fleetrun.cli import cli
    from tests import test_fleet_fakes as fakes

    extract = tmp_path / "dmv.csv"
    extract.write_text("VIN,vehicle_class,make,model,model_year,fuel\n"
                       "1,automobile,Toyota,Camry,2015,gasoline\n2,automobile,Toyota,Camry,2015,gasoline\n"
                       "3,light_truck,Nomake,X,2008,\n4,combination_truck,,,2019,diesel\n5,truck,,,,\n",
                       encoding="utf-8")
    workbook = tmp_path / "fleet.xlsx"
    done = CliRunner().invoke(cli, ["import-registrations", str(extract), "-o", str(workbook),
                                    "--first-fiscal-year", "2027", "--base-year-vmt-million", "0.05",
                                    "--base-year-vmt-share-pct", "combination_truck:10"])
    assert done.exit_code == 0, done.output
    fleet = read_fleet(workbook)
    assert sorted(r["count"] for r in fleet.registrations) == [1, 1, 1, 2]
    out = tmp_path / "out"
    result = fakes.invoke_run(workbook, "--out", out, "--no-cache", "-q")
    assert result.exit_code == 0, result.stderr
    choices = pd.read_csv(out / "registrations.csv")
    rows = choices[choices.registration_row != "new sales"]
    assert rows["count"].sum() == pytest.approx(5)
    assert set(pd.read_csv(out / "turnover.csv").fiscal_year) == {2027, 2028}
    assert "Registrations" in openpyxl.load_workbook(out / "report.xlsx", read_only=True).sheetnames
    fiscal = pd.read_csv(out / "fiscal_summary.csv")
    assert fiscal[fiscal.fiscal_year == 2027].miles.sum() == pytest.approx(0.05e6, rel=1e-9)
    first = fiscal[(fiscal.fiscal_year == 2027) & (fiscal.vehicle_class == "combination_truck")]
    assert first.miles.sum() == pytest.approx(0.1 * 0.05e6, rel=1e-9)


def test_a_user_set_rate_replaces_the_trend_after_its_last_model_year():
    """Beyond EPA Trends' last model year (2022) new model years improve by the scenario's
    rate: MY2026 at 5 %/yr uses the MY2022 car mpg x 1.05^4; MY2022 keeps the table's value."""
    s = scenario(first_fiscal_year=2026, budget_years=1, new_vehicle_mpg_change_pct_per_year=5.0)
    rows = [{"vehicle_class": "automobile", "count": 10, "model_year": my, "fuel": "gasoline"} for my in (2022, 2026)]
    e = expand(fleet_of(rows), [s])
    by_year = {v.model_year: f for v, f in zip(e.vehicles, e.fuel_factor(s))}
    assert by_year[2022] == pytest.approx(1.0, rel=1e-12)
    assert by_year[2026] == pytest.approx(1 / 1.05 ** 4, rel=1e-12)


def test_a_typed_truck_mix_beside_cycle_mix_default_is_warned(tmp_path):
    """The template's example scenario rows type cycle_mix_MD / cycle_mix_HD; an analyst who
    sets cycle_mix = default and keeps them gets those mixes, and is told (validate warns)."""
    path = registrations_workbook(tmp_path / "r.xlsx", [{"vehicle_class": "truck", "count": 1000}])
    wb = openpyxl.load_workbook(path)
    sc = wb["Scenarios"]
    sc.cell(1, len(SCENARIO) + 1).value = "cycle_mix_HD"
    sc.cell(2, len(SCENARIO) + 1).value = "HD-UDDS:0.6,HWFET:0.4"
    wb.save(path)
    fleet = read_fleet(path)
    assert fleet.scenarios[0].cycle_mix_HD == {"HD-UDDS": 0.6, "HWFET": 0.4}
    assert any("cycle_mix_HD" in w and "instead of their default mix" in w for w in fleet.warnings)
