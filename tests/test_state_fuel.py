"""The registrations validation on states no fit used (docs/validation-state-fuel.md).

Connecticut 2014 from its FHWA MV-1 counts and VM-2 miles only, uncalibrated, against MF-27
highway gasoline (the issue's 5 % target, met there as the page reports: +3.9 %; Colorado's
+4.4 % of the earlier turnover default is +7.0 % since the per-class Trends tables); Colorado
calibrated on 2014, 2016 gasoline from 2016's VMT (VM-3M) closer to MF-21 than gallons
proportional to VMT; the light-duty fleet's mpg change inside the published range (FHWA VM-1
all vehicles 1990-2002 to EPA Trends new vehicles 2004-2022). Special fuels within the issue's 10 % of MF-27 in the two
state-years the page reports as hits: Arkansas from registrations only, Arizona with its VM-4
2010 class shares of the miles (``base_year_vmt_share_pct``); the VM-4 shares weighted over the
states equal VM-1 2010's national combination-truck share of travel (5.9 %, 175,911 of 2,966,494
million vehicle-miles, Freight Facts and Figures 2012 Table 3-9) to 0.1 point. Both fuels within
target from registrations only in the three state-years the page reports (Arizona 2000,
Connecticut 2006, Virginia 2010), the issue's count; no state-year comes from the states whose
registrations the truck split was fitted on. The same workbook for the whole nation
(validation/national_fuel.py) in years no state-year here uses.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]


def _state_fuel():
    sys.path.insert(0, str(ROOT / "validation"))
    import state_fuel

    return state_fuel


def test_vm4_class_shares_add_up_to_the_national_vm1_share():
    state_fuel = _state_fuel()
    shares = state_fuel.vm4_class_shares()
    assert shares.sum(axis=1).to_numpy() == pytest.approx(100.0, abs=1e-9)
    miles = sum(pd.read_csv(state_fuel.VM4 / f"functional_class_vmt_split_{a}.csv").set_index("State")["Total"]
                for a in ("rural", "urban")).drop("PR")
    national = (shares.drop("PR")["combination_truck"] * miles).sum() / miles.sum()
    assert national == pytest.approx(100 * 175911 / 2966494, abs=0.1)


@pytest.mark.slow
def test_2014_from_registrations_only():
    state_fuel = _state_fuel()
    table = state_fuel.main(["--states", "Colorado,Arkansas,Arizona,Connecticut", "--years", "2014"])
    mv1 = table[table.inputs == "mv1"].set_index("state")
    data = pd.read_csv(state_fuel.DATA)
    hit = mv1.loc["Connecticut"]
    observed = data[(data.state == "Connecticut") & (data.year == 2014)].iloc[0]
    assert hit.gasoline_observed_Mgal == pytest.approx(observed.highway_gasoline_kgal / 1e3)
    assert abs(hit.gasoline_error_pct) <= 100 * state_fuel.GASOLINE_TOLERANCE
    row = mv1.loc["Colorado"]
    assert abs(row.gasoline_forecast_error_pct) < abs(row.gasoline_naive_error_pct)
    low, high = state_fuel.PUBLISHED_MPG_CHANGE_PCT
    assert low <= row.ld_mpg_change_pct_per_year <= high
    arkansas = mv1.loc["Arkansas"]
    assert arkansas.diesel_observed_Mgal == pytest.approx(
        data[(data.state == "Arkansas") & (data.year == 2014)].iloc[0].special_fuels_kgal / 1e3)
    assert abs(arkansas.diesel_error_pct) <= 100 * state_fuel.DIESEL_TOLERANCE
    arizona = table[table.inputs == "mv1+vm4"].set_index("state").loc["Arizona"]
    assert abs(arizona.diesel_error_pct) <= 100 * state_fuel.DIESEL_TOLERANCE


def test_a_forecast_year_is_the_same_statistics_later_year():
    """2014 forecasts 2016 (VM-3M, MF-21); a 2000 base year has no forecast year (2014 is another
    series' base year, not a forecast target)."""
    state_fuel = _state_fuel()
    data = pd.read_csv(state_fuel.DATA)
    bases = data[data.mv1_automobiles.notna()].set_index(["state", "year"], drop=False)
    assert int(state_fuel.later_year(data, bases.loc[("Alabama", 2014)]).year) == 2016
    assert state_fuel.later_year(data, bases.loc[("Alabama", 2000)]) is None
    assert state_fuel.vmt_million_mi(bases.loc[("Alabama", 2000)]) == 56534
    assert state_fuel.vmt_million_mi(bases.loc[("Alabama", 2014)]) == pytest.approx(105680 / 1.609344)


def test_no_state_year_from_the_truck_split_states():
    """The MV-1 truck split (models/turnover.toml) is fitted on 2008 registrations of Hawaii to
    Pennsylvania (models/vehicle_library/PROVENANCE.md), so the validation holds those states out:
    every state-year is from Alabama-Georgia or Rhode Island-Wyoming."""
    data = pd.read_csv(_state_fuel().DATA)
    assert len(data) > 0
    assert not data.state.between("Hawaii", "Pennsylvania").any()


@pytest.mark.slow
def test_three_state_years_both_fuels_within_target():
    """Registrations and VMT only (MV-1 only), uncalibrated, both fuels within the issue's 5 % and
    10 % in three state-years (the issue's count), measured 2026-11-25 with the per-class Trends
    tables: Arizona 2000 (FHWA 2000 State Briefing sheet) -0.8 % and -9.3 %; Connecticut 2006
    (MV-1, VM-2, MF-21 through BTS State Transportation Statistics 2007) +0.3 % and +3.3 %;
    Virginia 2010 (MV-1 2010, VM-2, State Statistical Abstract 2010) -0.9 % and -1.2 %. Of the state-years with both fuels only these
    three hit both (docs/validation-state-fuel.md)."""
    state_fuel = _state_fuel()
    table = state_fuel.main(["--states", "Arizona,Connecticut,Virginia", "--years", "2000,2006,2010",
                             "--variants", "mv1"]).set_index(["state", "year"])
    for key in (("Arizona", 2000), ("Connecticut", 2006), ("Virginia", 2010)):
        row = table.loc[key]
        assert abs(row.gasoline_error_pct) <= 100 * state_fuel.GASOLINE_TOLERANCE, key
        assert abs(row.diesel_error_pct) <= 100 * state_fuel.DIESEL_TOLERANCE, key


@pytest.mark.slow
def test_national_fuel_in_years_no_state_year_uses():
    """The nation in 2000 and 2009 from its registrations and VMT: highway gasoline within the
    issue's 5 % of FHWA's national totals (measured +3.5 % and +3.8 %), special fuels 2009 within
    10 % (+1.4 %); the light-duty classes' mpg within 5 % of FHWA VM-1's passenger-car and other
    2-axle 4-tire mpg (2000: +0.4 %, -1.2 %; 2008: -0.9 %, -5.0 %, the light trucks at the limit
    since the per-class Trends tables; measured 2026-11-25: gasoline +3.5 % in 2000, +3.8 % in
    2009 against the rounded 137 billion gallons)."""
    sys.path.insert(0, str(ROOT / "validation"))
    import national_fuel

    table = national_fuel.main().set_index("year")
    assert abs(table.loc[2000, "gasoline_error_pct"]) <= 5.0
    assert abs(table.loc[2009, "gasoline_error_pct"]) <= 5.0
    assert abs(table.loc[2009, "diesel_error_pct"]) <= 10.0
    for year in (2000, 2008):
        assert abs(table.loc[year, "automobile_mpg_error_pct"]) <= 5.0
        assert abs(table.loc[year, "light_truck_mpg_error_pct"]) <= 5.0
