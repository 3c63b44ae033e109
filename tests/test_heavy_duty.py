"""Heavy-duty defaults (models/heavy_duty/): the FHWA class rows are valid Vehicles rows and
their road load is the one their GEM inputs give."""
from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from fleetrun.workbook.vehicle_file import vehicle_from_mapping
from fleetrun.resources import models_dir
from fleetrun.simulation.heavy_duty_road_load import gem_coastdown_lbf

LB_KG = 0.45359237
HD_DIR = models_dir() / "heavy_duty"
ROW_KEYS = {"duty_class", "configuration", "fuel", "peak_engine_torque_Nm", "transmission",
            "transmission_gear_ratios", "final_drive_ratio", "test_weight_kg", "coastdown_A_lbf",
            "coastdown_B_lbf_per_mph", "coastdown_C_lbf_per_mph2", "tire_size", "rated_power_kW",
            "engine_displacement_L", "annual_miles", "source"}


def _load(name):
    with open(HD_DIR / name, "rb") as fh:
        return tomllib.load(fh)


def test_fhwa_classes_have_the_stable_keys():
    classes = _load("fhwa_classes.toml")
    assert {"single_unit_truck", "combination_truck", "bus"} <= set(classes)
    for name, row in classes.items():
        assert set(row) == ROW_KEYS, name


@pytest.mark.parametrize("name", ["single_unit_truck", "combination_truck", "bus"])
def test_fhwa_class_is_a_valid_vehicles_row(name):
    row = dict(_load("fhwa_classes.toml")[name])
    row.pop("source")
    spec = vehicle_from_mapping({**row, "vehicle_id": name, "vehicle_class": name, "count": 1}, Path(name))
    assert spec.fuel == "diesel" and spec.duty_class in ("MD", "HD")


@pytest.mark.parametrize("name", ["single_unit_truck", "combination_truck", "bus"])
def test_fhwa_class_road_load_is_its_gem_inputs(name):
    """The row's A and C are the GEM inputs' (Crr m g, rho CdA / 2), to the 0.1 lbf / 1e-4
    lbf/mph^2 the file is rounded to; the weight is the basis weight to 1 kg."""
    row, basis = _load("fhwa_classes.toml")[name], _load("gem_basis.toml")[name]
    mass = basis["test_weight_lb"] * LB_KG
    a, b, c = gem_coastdown_lbf(mass, basis["crr_kg_per_t"] / 1000.0, basis["cda_m2"])
    assert row["test_weight_kg"] == pytest.approx(mass, abs=0.5)
    assert row["coastdown_A_lbf"] == pytest.approx(float(a), abs=0.01)
    assert row["coastdown_B_lbf_per_mph"] == float(b) == 0.0
    assert row["coastdown_C_lbf_per_mph2"] == pytest.approx(float(c), abs=5e-5)


# ----------------------------------------------------------------------------- engine, driveline, GEM
import sys  # noqa: E402

import numpy as np  # noqa: E402

from fleetrun.resources import model_file  # noqa: E402
from fleetrun.cycles import load_cycle  # noqa: E402
from fleetrun.simulation import simulate  # noqa: E402
from fleetrun.simulation.heavy_duty_engine import (bsfc_map_g_per_kWh, heavy_duty_constants,  # noqa: E402
                                                   reference_engine, set_co2_g_per_hp_hr, set_ramped_co2_g_per_hp_hr,
                                                   standard_for)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "validation"))
import heavy_duty as hd_validation  # noqa: E402


def _reference_engine(service="heavy", year=2021):
    hd_set = model_file("engines.toml")["diesel"]["HD"]
    shape = (hd_set["idle_speed_rpm"], hd_set["peak_torque_speed_fraction"], hd_set["idle_torque_fraction"])
    return reference_engine(service, *shape), heavy_duty_constants(service, year, *shape)


@pytest.mark.parametrize("year", [2017, 2021, 2027])
def test_reference_engine_meets_its_set_standard(year):
    """The Willans slope is solved so that the SET-weighted CO2 is the 40 CFR 1036.108
    standard; recomputing it with that slope must give the standard to rounding."""
    engine, constants = _reference_engine(year=year)
    co2 = set_co2_g_per_hp_hr(constants, engine)
    assert co2 == pytest.approx(standard_for("heavy", year), rel=1e-9)


@pytest.mark.parametrize("service", ["heavy", "medium"])
def test_reference_engine_meets_its_standard_on_the_ramped_set(service):
    """The SET is run as a ramped-modal cycle and rated as total CO2 over total work (40 CFR
    1036.510(a), (g); 1065.650). The slope is anchored on the 13 modes with their weights, which
    lump each 20 s ramp into a mode; run as the test runs it, ramps included, the engine must
    still meet its standard within 0.5 % (measured: -0.04 %), else the modes, their order or
    weights are wrong."""
    engine, constants = _reference_engine(service=service)
    co2 = set_ramped_co2_g_per_hp_hr(constants, engine)
    assert co2 == pytest.approx(standard_for(service, 2021), rel=0.005)


def test_set_weights_are_the_ramped_cycles_times_in_mode():
    """Each SET weight is (time in mode + one 20 s ramp) / 2,400 s of the ramped-modal cycle
    (1036.505 Table 1); idle holds the first and the last mode."""
    data = model_file("heavy_duty/engines.toml")
    ramped, weights = data["set_ramped"], [m["weight"] for m in data["set_modes"]]
    seconds = list(ramped["mode_seconds"])
    seconds[0] += ramped["final_idle_seconds"]
    total = sum(seconds) + ramped["ramp_seconds"] * len(seconds)
    assert total == 2400.0
    assert [(s + ramped["ramp_seconds"]) / total for s in seconds] == pytest.approx(weights, abs=1e-12)


def test_heavy_engine_peak_efficiency_is_a_current_heavy_diesels():
    """Peak brake efficiency of the MY2021 15 L map: production heavy-duty diesels of the
    Phase 2 years reach 44-47 % (DOE SuperTruck reports: 2009 baseline engines about 42 %,
    2020s production about 46 %); 43-48 % allows for the map's smooth shape."""
    engine, constants = _reference_engine()
    bsfc = bsfc_map_g_per_kWh(engine, constants, np.linspace(800, 1800, 41), np.linspace(0.1, 1.0, 37))
    peak = 3.6e6 / (np.nanmin(bsfc) * 42.8e3)
    assert 0.43 <= peak <= 0.48


@pytest.fixture(scope="module")
def typed_cruise():
    return {row["cycle"]: row for row in hd_validation.check_typed_tractor()}


@pytest.mark.parametrize("cycle", ["CRUISE-65", "CRUISE-55"])
def test_typed_class8_tractor_cruise_mpg(typed_cruise, cycle):
    """Issue 21's typed tractor: its road load, a 0.93 driveline and a 43-45 % brake
    efficiency give 6.5-7.5 mpg at a level 65 mph and 7.8-9.0 at 55 (was 5.81 / 6.47)."""
    row = typed_cruise[cycle]
    assert row["target_low"] <= row["mpg"] <= row["target_high"], row


def test_cruise_driveline_efficiency_no_longer_drops_at_55(typed_cruise):
    """The clutch no longer slips in top gear: 55 and 65 mph drivetrain efficiencies were
    0.89 and 0.94; a closed driveline of gearbox mesh and tandem axles is above 0.92 at both
    and differs by less than 0.01 between them."""
    e55, e65 = typed_cruise["CRUISE-55"]["drivetrain_efficiency"], typed_cruise["CRUISE-65"]["drivetrain_efficiency"]
    assert e55 > 0.92 and e65 > 0.92 and abs(e55 - e65) < 0.01


def test_heavy_diesel_shifts_near_peak_torque_speed():
    """Economy shifting: while accelerating on the HD-UDDS the typed tractor's engine turns on
    average below 1.4 x its peak-torque speed of 1,200 rpm (measured 1,553 rpm; the power
    reserve, not the shift speed, sets it on hard accelerations). With the light-duty
    accelerating shift speed of manual gearboxes (2,500 rpm, capped at the 2,000 rpm rated
    speed) the average was 1,835 rpm."""
    trace = simulate([hd_validation.typed_tractor()], "HD-UDDS", trace=True).trace_frame(0)
    v = trace["vehicle_speed_mps"].to_numpy()
    accelerating = (np.diff(v, prepend=v[0]) > 0.1) & (v > 3.0)
    speed = trace["engine_speed_rpm"].to_numpy()
    assert speed[accelerating].mean() < 1.4 * 1200.0


@pytest.fixture(scope="module")
def reference_rows():
    return hd_validation.check_reference_vehicles()


# Engine size per class in DOE's "LD MDHD Benefits Analysis Assumptions FY2021" as NREL T3CO's
# documentation lists it (docs/models/optimization.md at commit 85017ca6, BSD-3): (displacement
# [L] it gives, rated power [kW]). The vocational medium HD row is its "class 6,7" (7 L, 201 kW;
# the reference file's 6.7 L is the displacement of the 7 L-class engines sold), the heavy HD
# vocational rows its "class 8 urban" (11 L, 261 kW; it allows 11 or 15 L for regional and
# multi-purpose).
PUBLISHED_CLASS_ENGINES = {"sleeper_cab": (15.0, 339.0), "day_cab@class_8_tractor": (15.0, 339.0),
                           "day_cab@class_7_tractor": (11.0, 261.0),
                           "vocational@heavy_heavy_vocational": (11.0, 261.0),
                           "vocational@medium_heavy_vocational": (7.0, 201.0)}


def _published_engine(basis):
    for key, engine in PUBLISHED_CLASS_ENGINES.items():
        gem_type, _, reg_class = key.partition("@")
        if basis["gem_type"].startswith(gem_type) and reg_class in ("", basis["regulatory_class"]):
            return engine
    raise KeyError(basis["gem_type"])


def test_reference_engines_are_the_published_class_engine_sizes():
    """The reference vehicles' engines are the engine sizes DOE's MD/HD benefits analysis
    assumes for the class (rated power exact, displacement within 0.5 L): the engine is the
    one reference input a published source gives per class (models/heavy_duty/PROVENANCE.md)."""
    _, vehicles = hd_validation.reference_vehicles()
    for name, basis in vehicles.items():
        litres, kw = _published_engine(basis)
        assert basis["rated_power_kW"] == kw and abs(basis["engine_displacement_L"] - litres) <= 0.5, name


def test_doe_nrel_vehicles_carry_gems_standard_payload():
    """The DOE / NREL T3CO vehicles of the road-load sensitivity are GEM's subcategories: their
    payload is the standard payload of the reference vehicle's class (40 CFR 1037.801: 19 short
    tons for class 8 tractors, 5.6 for medium HD vocational), to 0.1 %."""
    from fleetrun.simulation.heavy_duty_gem import payload_short_tons

    doe = _load("reference_inputs_doe_nrel.toml")["vehicles"]
    _, vehicles = hd_validation.reference_vehicles()
    for name, v in doe.items():
        payload_kg = payload_short_tons(vehicles[name]["regulatory_class"]) * 907.18474
        assert abs(v["cargo_kg"] / payload_kg - 1.0) < 1e-3, name


# Issue 21's done-when, one vehicle at a time: each Phase 2 reference vehicle's GEM composite
# within 5 % of its MY2021 standard (40 CFR 1037.106 tractors, 1037.105 vocational). A vehicle
# that misses is a strict expected failure naming its measured miss (docs/validation-heavy-duty.md
# section 2), so it fails the suite the day it passes and the passing ones are asserted.
_CLASS8_MISS = ("EPA's MY2021 package (CdA, tyres, gearing, GEM's percentage inputs of 1037.520(j)) was not "
                "found; the engine meets its SET standard to -0.04 %, a single drive axle leaves +7.3 / +6.0 %, "
                "level cruise +5.3 / +5.8 %")
_VOCATIONAL_MISS = ("GEM's vocational vehicle inputs were not found (heavy HD CdA, gear sets and axle ratios are "
                    "estimates) and the engine's no-load idle is 40-67 % of measured trucks'; a 90 kPa no-load "
                    "intercept (pre-registered, not kept) gave heavy HD -8.7 / -2.7 / +0.9 %, medium HD "
                    "-14.6 / -5.9 / -2.8 %")
REFERENCE_MISSES = {
    "class8_sleeper_high_roof": "+10.8 % (graded cruise); " + _CLASS8_MISS,
    "class8_day_high_roof": "+9.4 % (graded cruise); " + _CLASS8_MISS,
    "hhd_vocational_regional": "-12.7 %; " + _VOCATIONAL_MISS,
    "hhd_vocational_multipurpose": "-10.6 %; " + _VOCATIONAL_MISS,
    "hhd_vocational_urban": "-9.1 %; " + _VOCATIONAL_MISS,
    "mhd_vocational_regional": "-17.8 %; " + _VOCATIONAL_MISS,
    "mhd_vocational_multipurpose": "-13.9 %; " + _VOCATIONAL_MISS,
    "mhd_vocational_urban": "-13.4 %; " + _VOCATIONAL_MISS,
}
REFERENCE_NAMES = ("class8_sleeper_high_roof", "class8_day_high_roof", "class7_day_high_roof",
                   "hhd_vocational_regional", "hhd_vocational_multipurpose", "hhd_vocational_urban",
                   "mhd_vocational_regional", "mhd_vocational_multipurpose", "mhd_vocational_urban")


def test_reference_names_are_the_reference_file():
    """The per-vehicle 5 % test below covers every vehicle of gem_reference_vehicles.toml."""
    _, vehicles = hd_validation.reference_vehicles()
    assert tuple(vehicles) == REFERENCE_NAMES


@pytest.mark.parametrize("name", [
    pytest.param(n, marks=pytest.mark.xfail(strict=True, reason="not reached: " + REFERENCE_MISSES[n]))
    if n in REFERENCE_MISSES else n for n in REFERENCE_NAMES])
def test_phase2_reference_vehicle_within_5pct_of_its_standard(reference_rows, name):
    """Issue 21's done-when for one reference vehicle: its GEM composite (GEM's cycles,
    weighting, payload and, for vocational vehicles, idle cycles) within 5 % of its MY2021
    standard. Passes now: the class 7 day cab (measured -0.9 %; -3.4 % on level cruise)."""
    row = next(r for r in reference_rows if r["vehicle"] == name)
    assert abs(row["co2_error"]) <= 0.05, row


def test_sleeper_standard_needs_more_than_an_engine_at_its_standard_gives():
    """Why the class 8 sleeper stays out (docs/validation-heavy-duty.md): with the reference road
    load and GEM's cycles, the fuel-to-wheel efficiency its MY2021 standard needs exceeds what a
    single-drive-axle driveline (1037.520(g)(2)) and an engine averaging its SET standard's
    efficiency (447 g/hp-hr, 40 CFR 1036.108) give together, so no sourced engine or driveline
    change can bring it within 5 %; the gap is the MY2021 package the standard was set with."""
    from fleetrun.physics.fuels import fuel_properties
    from fleetrun.simulation.heavy_duty_engine import HP_W, co2_g_per_g_fuel

    name = "class8_sleeper_high_roof"
    shipped = hd_validation.tractor_composite(name)
    single = hd_validation.tractor_composite(name, configuration="HD_RWD")
    driveline = single["wheel_kWh_per_mile"] / single["engine_kWh_per_mile"]
    fuel_g_per_kWh = standard_for("heavy", 2021) / (HP_W / 1000.0) / co2_g_per_g_fuel()
    engine_at_standard = 3.6e3 / (fuel_g_per_kWh * fuel_properties("diesel").lhv_MJ_per_kg)
    assert shipped["wheel_to_fuel_at_standard"] > engine_at_standard * driveline > shipped["wheel_to_fuel"]


def test_grade_by_distance_is_the_shipped_grade_for_a_truck_on_the_trace():
    """Appendix IV gives GEM's grade by distance; read at the distance driven it is the shipped
    per-time-stamp grade for a vehicle that holds the set speed, and it shifts later for one that
    falls behind (validation/heavy_duty.py's sensitivity)."""
    cycle = load_cycle("CRUISE-65-GRADE")
    same = hd_validation.grade_by_distance(cycle, cycle.speed_mps)
    assert np.allclose(same.grade_pct, cycle.grade_pct, atol=1e-9)
    slower = hd_validation.grade_by_distance(cycle, 0.9 * cycle.speed_mps)
    x = np.arange(cycle.time_s.size) * float(cycle.speed_mps[0])
    assert np.allclose(slower.grade_pct, np.interp(0.9 * x, x, cycle.grade_pct), atol=1e-9)


def test_vocational_idle_adds_gems_idle_cycles(reference_rows):
    """GEM's vocational composite charges drive and parked idle (40 CFR 1037.510(c)): the
    composite with idle is the one without plus the idle term; the term is largest for the
    urban type (40 % of the time idling, 16.2 mph) and smallest for the regional one (25 %,
    parked only, 38.4 mph); tractors have none. In drive an automatic's stalled converter loads
    the engine: drive idle burns more than parked idle."""
    without = {r["vehicle"]: r for r in hd_validation.check_reference_vehicles(with_idle=False)}
    for r in reference_rows:
        base = without[r["vehicle"]]["model_g_per_ton_mile"]
        assert r["model_g_per_ton_mile"] == pytest.approx(base + r["idle_g_per_ton_mile"], abs=0.02), r
        if r["gem_type"].startswith("vocational"):
            assert r["drive_idle_gal_per_h"] > r["parked_idle_gal_per_h"] > 0.1, r
        else:
            assert r["idle_g_per_ton_mile"] == 0.0
    for size in ("hhd", "mhd"):
        idle = {r["gem_type"]: r["idle_g_per_ton_mile"] for r in reference_rows if r["vehicle"].startswith(size)}
        assert idle["vocational_urban"] > idle["vocational_multipurpose"] > idle["vocational_regional"] > 0


def test_gem_nonidle_speeds_are_the_harmonic_mean_of_the_cycles():
    """1037.510(c)'s average speed of the non-idle cycles (38.41 / 23.18 / 16.21 mph for the
    regional / multi-purpose / urban types, gem_cycles.toml) is the distance-weighted harmonic
    mean of the three cycles' mean speeds: re-derived from the shipped ARB-TRANSIENT (from NREL
    T3CO) and cruise cycles within 0.1 mph, which checks the cycle, the weights and the speeds
    against one another."""
    from fleetrun.simulation.heavy_duty_gem import gem_cycle_mix, idle_shares

    def mean_mph(name):
        c = load_cycle(name)
        return float(np.trapezoid(c.speed_mps, c.time_s) / (c.time_s[-1] - c.time_s[0])) / 0.44704

    for gem_type in ("vocational_regional", "vocational_multipurpose", "vocational_urban"):
        hours_per_mile = sum(w / mean_mph(cycle) for cycle, w in gem_cycle_mix(gem_type).items())
        assert 1.0 / hours_per_mile == pytest.approx(idle_shares(gem_type)[2], abs=0.1), gem_type


def test_idle_per_mile_is_idle_time_over_the_miles_of_that_time():
    """Shares of operating time: an hour is s_d drive idle + s_p parked idle + the rest
    driving at v; idle fuel per mile = (s_d g_d + s_p g_p) / ((1 - s_d - s_p) v)."""
    from fleetrun.simulation.heavy_duty_gem import idle_gallons_per_mile

    assert idle_gallons_per_mile(1.2, 0.3, 0.15, 0.25, 16.21) == pytest.approx((0.18 + 0.075) / (0.6 * 16.21))
    assert idle_gallons_per_mile(1.2, 0.3, 0.0, 0.0, float("nan")) == 0.0


def test_heavy_duty_error_file_is_what_the_validation_measures(reference_rows):
    """models/heavy_duty/fuel_economy_error.toml holds the errors the validation measures now
    (re-run ``python validation/heavy_duty.py --write`` after a change that moves them)."""
    stored = _load("fuel_economy_error.toml")["tests"]
    for name, summary in hd_validation.error_groups(reference_rows).items():
        for key in ("n", "mean", "p05", "p95"):
            assert stored[name][key] == pytest.approx(summary[key], abs=1e-4), (name, key)


def test_model_year_chooses_the_engine_standard():
    """A MY2027 tractor burns less than a MY2014 one in proportion to their SET standards
    (432 / 475 g/hp-hr, 40 CFR 1036.108): at level cruise the Willans slope carries nearly all
    of the fuel, so the mpg ratio is within 1 % of 475 / 432; the engine_model_year column wins
    over model_year."""
    import dataclasses

    v = hd_validation.typed_tractor()
    old, new, engine_only = (dataclasses.replace(v, model_year=2014), dataclasses.replace(v, model_year=2027),
                             dataclasses.replace(v, model_year=2027, extra={"engine_model_year": 2014}))
    mpg = simulate([old, new, engine_only], "CRUISE-65").mpg
    assert mpg[1] / mpg[0] == pytest.approx(475.0 / 432.0, rel=0.01)
    assert mpg[2] == pytest.approx(mpg[0], rel=1e-12)
    assert old.physics_key() != new.physics_key()   # the run does not merge rows of different years


def test_set_speeds_follow_the_1065_610_definition():
    """n_lo / n_hi: lowest speed at 50 % and highest at 70 % of maximum power; A, B, C at
    25 / 50 / 75 % between them (40 CFR 1065.610). A triangular power curve peaking at 1,500
    rpm (0 at 500 and 2,500) has n_lo = 1,000 and n_hi = 1,800 exactly."""
    from fleetrun.simulation.heavy_duty_engine import set_speeds_rpm

    n = np.linspace(500.0, 2500.0, 2001)
    power = np.where(n <= 1500.0, n - 500.0, 2500.0 - n)
    speeds = set_speeds_rpm(n, power)
    assert speeds["A"] == pytest.approx(1200.0, abs=1.0)
    assert speeds["B"] == pytest.approx(1400.0, abs=1.0)
    assert speeds["C"] == pytest.approx(1600.0, abs=1.0)


def test_gem_composite_is_the_weighted_g_per_mile_over_payload():
    """40 CFR 1037.510(c) / 1037.705: sum of weight x g CO2/mile over the payload; with
    1/6 gal/mi on every cycle the composite is 10,180 / 6 / 19 g/ton-mile for a class-8 tractor
    (diesel CO2 per gallon, models/fuels.toml), whatever the weights, which sum to 1."""
    from fleetrun.simulation.heavy_duty_gem import composite_g_co2_per_ton_mile, gem_cycle_mix, payload_short_tons

    for gem_type in ("day_cab", "sleeper_cab", "vocational_urban"):
        mix = gem_cycle_mix(gem_type)
        assert sum(mix.values()) == pytest.approx(1.0, abs=1e-12)
        value = composite_g_co2_per_ton_mile({c: 1 / 6 for c in mix}, mix, payload_short_tons("class_8_tractor"))
        assert value == pytest.approx(10180.0 / 6 / 19.0, rel=1e-12)
    assert "CRUISE-65" not in gem_cycle_mix("vocational_urban")   # weight 0: left out


def test_unknown_gem_vehicle_type_names_the_valid_ones():
    from fleetrun.errors import FleetrunError
    from fleetrun.simulation.heavy_duty_gem import gem_cycle_mix

    with pytest.raises(FleetrunError) as e:
        gem_cycle_mix("sleeper")
    assert "sleeper_cab" in str(e.value)


def test_cruise_cycles_are_their_speed_for_600_s():
    """CRUISE-55 / CRUISE-65 (inputs/cycles/make_cruise.py): 600 s at exactly 55 / 65 mph,
    so 55 x 600 / 3600 = 9.1667 and 10.8333 miles, level."""
    from fleetrun.cycles import MPH_TO_MPS, load_cycle

    for mph in (55, 65):
        c = load_cycle(f"CRUISE-{mph}")
        assert c.duration_s == 600 and np.all(c.grade_pct == 0)
        assert np.allclose(c.speed_mps, mph * MPH_TO_MPS, atol=5e-6)
        assert c.miles == pytest.approx(mph * 600 / 3600, abs=1e-4)


def test_light_duty_and_gasoline_rows_keep_their_engine_and_shifting():
    """The heavy-duty hooks change medium- and heavy-duty diesel rows only."""
    import dataclasses

    from fleetrun.simulation.heavy_duty_engine import heavy_duty_fuel_constants
    from fleetrun.simulation.heavy_duty_shift import heavy_duty_shift_speeds

    v = hd_validation.typed_tractor()
    assert heavy_duty_fuel_constants(v, 15.0, 650.0, 0.6, 0.55) is not None
    assert heavy_duty_shift_speeds(v, 1200.0) is not None
    for other in (dataclasses.replace(v, fuel="gasoline"), dataclasses.replace(v, duty_class="LD")):
        assert heavy_duty_fuel_constants(other, 15.0, 650.0, 0.6, 0.55) is None
        assert heavy_duty_shift_speeds(other, 1200.0) is None


def test_force_table_once_per_drivetrain_is_bit_identical():
    """max_tractive_force_table computes each distinct drivetrain once and keeps it for the
    process (the re-drive of heavy trucks spent half its time there): the table of a fleet is
    the per-vehicle tables stacked, bit for bit, for rows that share drivetrains and rows that
    do not."""
    import dataclasses

    from fleetrun.simulation import core
    from fleetrun.simulation.params import vehicle_arrays

    v = hd_validation.typed_tractor()
    rows = [dataclasses.replace(v, vehicle_id=f"t{i}", test_weight_kg=v.test_weight_kg * (1 + 0.01 * i)) for i in range(4)]
    rows.append(dataclasses.replace(v, vehicle_id="axle", final_drive_ratio=3.08))
    va = vehicle_arrays(rows)
    core._FORCE_TABLE_ROWS.clear()
    together = core.max_tractive_force_table(va, 0.9)
    assert len(core._FORCE_TABLE_ROWS) == 2            # kept for the process, once per drivetrain
    alone = []
    for i in range(va.n):
        core._FORCE_TABLE_ROWS.clear()
        alone.append(core.max_tractive_force_table(va.subset([i]), 0.9))
    assert np.array_equal(together, np.vstack(alone))
    assert np.array_equal(core.max_tractive_force_table(va, 0.9), together)   # from the kept rows
    assert not np.array_equal(together[0], together[4])


def test_gem_aero_bins_are_the_1037_520_tables():
    """40 CFR 1037.520(b)(3): a high-roof sleeper measured at 5.8 m^2 is in Bin III (5.7-6.2)
    and runs GEM at 5.95 m^2; a day cab at 5.5 is Bin IV (5.5-5.9, input 5.70); 7.5 is Bin I
    of either; 4.0 is the last bin; from MY2027 a high-roof tractor loses 0.3 m^2 (the
    trailer's rear fairing, 1037.520(b)(4)), a low-roof one does not; unknown types are named."""
    from fleetrun.errors import FleetrunError
    from fleetrun.simulation.heavy_duty_road_load import gem_aero_bin, gem_cda_input_m2

    assert gem_aero_bin("high_roof_sleeper_cab", 5.8) == ("III", 5.95)
    assert gem_aero_bin("high_roof_day_cab", 5.5) == ("IV", 5.70)
    assert gem_aero_bin("high_roof_day_cab", 5.46) == ("IV", 5.70)      # rounds to 5.5 first
    assert gem_aero_bin("high_roof_sleeper_cab", 7.5)[0] == gem_aero_bin("high_roof_day_cab", 7.5)[0] == "I"
    assert gem_aero_bin("mid_roof", 4.0) == ("VII", 4.90)
    assert gem_cda_input_m2("high_roof_sleeper_cab", 5.8, 2027) == pytest.approx(5.65)
    assert gem_cda_input_m2("high_roof_sleeper_cab", 5.8, 2026) == pytest.approx(5.95)
    assert gem_cda_input_m2("low_roof", 4.6, 2027) == pytest.approx(5.15)
    with pytest.raises(FleetrunError, match="high_roof_sleeper_cab"):
        gem_aero_bin("sleeper", 5.8)


APPENDIX_IV_STRETCHES = (   # (distance [m], grade [%]) runs of the table's breakpoints
    ((2398, -0.69), (2478, -1.08), (2546, -1.53), (2698, -2.75), (2850, -1.53), (2918, -1.08)),
    ((6638, 2.57), (6710, 3.0), (6762, 3.27), (6800, 3.69), (6890, 5.01), (6980, 3.69), (7018, 3.27)),
    ((13738, -3.0), (13790, -3.27), (13828, -3.69), (13918, -5.01), (14008, -3.69)))


@pytest.mark.parametrize("cycle", ["CRUISE-55-GRADE", "CRUISE-65-GRADE"])
def test_graded_cruise_cycles_follow_appendix_iv(cycle):
    """GEM's cruise cycles over the grade profile of Appendix IV to 40 CFR part 1037 (2016
    text, https://ecfr.io/Title-40/Part-1037/Appendix-IV, breakpoints interpolated linearly):
    every 1 Hz sample inside three stretches of the table (the 2.75 % dip, the 5.01 % peak,
    the -5.01 % descent) has the table's grade at the distance driven at the set speed, within
    0.005 points; the speed is constant, the profile is 20.04 km long and climbs as much as it
    descends."""
    from fleetrun.cycles import MPH_TO_MPS

    c = load_cycle(cycle)
    speed = float(cycle.split("-")[1]) * MPH_TO_MPS
    assert np.allclose(c.speed_mps, speed, atol=1e-6)
    distance = (c.time_s - c.time_s[0]) * speed
    for stretch in APPENDIX_IV_STRETCHES:
        at, grade = np.array(stretch, float).T
        inside = (distance >= at[0]) & (distance <= at[-1])
        assert inside.sum() >= 4
        assert np.allclose(c.grade_pct[inside], np.interp(distance[inside], at, grade), atol=0.005), (cycle, at[0])
    climb_m = np.sum(c.grade_pct[1:] / 100.0 * np.diff(distance))
    assert abs(climb_m) < 1.0 and distance[-1] == pytest.approx(20040.0, abs=30.0)


# ----------------------------------------------------------------------------- the example's trucks
def test_example_truck_mixes_are_the_vm1_split_of_miles_over_road_categories():
    """The example's MD / HD mixes are FHWA VM-1 2010's single-unit / combination-truck miles by
    road category, summed per cycle of the file's rule (to the 4 decimals the workbook keeps)."""
    from fleetrun.resources import inputs_dir
    from fleetrun.workbook import read_fleet

    with open(inputs_dir() / "state_statistics" / "vm1_truck_travel.toml", "rb") as fh:
        data = tomllib.load(fh)
    fleet = read_fleet(inputs_dir() / "example_fleet.xlsx")
    for duty, vehicle_type in (("MD", "single_unit_trucks"), ("HD", "combination_trucks")):
        miles = data["vehicle_miles_million"][vehicle_type]
        expected: dict[str, float] = {}
        for road, cycle in data["cycle_for_road"].items():
            expected[cycle] = expected.get(cycle, 0.0) + miles[road] / sum(miles.values())
        for scenario in fleet.scenarios:
            mix = scenario.mix_for(duty)
            assert set(mix) == set(expected)
            assert all(mix[c] == pytest.approx(expected[c], abs=1.5e-4) for c in mix), (duty, scenario.scenario_id)


def test_example_combination_trucks_average_within_vm1_on_their_mixes():
    """Issue 21: the example's combination trucks, as a class (miles over gallons), land in the
    national combination-truck range of FHWA VM-1 (5.4-6.4 mpg) in every scenario, on the
    VM-1 split of their miles over road categories."""
    rows = hd_validation.check_example_combination_trucks()
    averages = {r["scenario"]: r["mpg"] for r in rows if r["vehicle"] == "class average"}
    assert len(averages) == 3
    low, high = hd_validation.VM1_COMBINATION_MPG
    assert all(low <= mpg <= high for mpg in averages.values()), averages


def test_medium_vocational_road_load_is_does_box_truck():
    """The medium HD vocational reference vehicles drive with the CdA and Crr of DOE's class 7
    box truck (NREL T3CO), the file that owns those numbers (no copy in the reference file); its
    9 m^2 frontal area is the box body 40 CFR 1037.520(m)(1) names for vocational aerodynamic
    devices (at least 8 m^2), not the 3.4 m^2 drag area the first reference file guessed."""
    doe = _load("reference_inputs_doe_nrel.toml")["vehicles"]
    raw = _load("gem_reference_vehicles.toml")["vehicles"]
    _, vehicles = hd_validation.reference_vehicles()
    for name in ("mhd_vocational_regional", "mhd_vocational_multipurpose", "mhd_vocational_urban"):
        assert "cda_m2" not in raw[name] and raw[name]["road_load_source"] == "reference_inputs_doe_nrel"
        assert vehicles[name]["cda_m2"] == pytest.approx(doe[name]["drag_coef"] * doe[name]["frontal_area_m2"])
        assert vehicles[name]["crr_kg_per_t"] == pytest.approx(doe[name]["wheel_rr_coef"] * 1000.0)
        assert doe[name]["frontal_area_m2"] >= 8.0


@pytest.mark.xfail(strict=True, reason=(
    "not reached: the heavy-duty fuel equation idles with no load on 0.18 gal/h (6.7 L at 750 r/min) and "
    "0.22 / 0.33 gal/h (11 / 15 L at 600 r/min), 40 / 45 / 67 % of the 0.44 gal/h of DOE Fact #861's medium "
    "heavy diesel truck and the 0.49 gal/h of its combination truck: the Willans line with friction is short "
    "at the light-load end of the map (docs/validation-heavy-duty.md, section 2)"))
def test_heavy_diesel_no_load_idle_within_25pct_of_measured_trucks():
    """Each reference engine's no-load idle fuel (idle speed, no torque, no accessories) against
    the measured no-load idle of its class (models/heavy_duty/idle_fuel_measured.toml, DOE VTO
    Fact #861): 25 % allows for the idle speeds and engine sizes the source does not give."""
    rows = hd_validation.check_idle_fuel()
    assert rows and all(abs(r["ratio"] - 1.0) <= 0.25 for r in rows), rows


def test_measured_idle_and_doe_accessory_sensitivities_only_add_fuel(reference_rows):
    """The two sensitivities of docs/validation-heavy-duty.md section 2 move the composites the
    way their physics says: idling as Fact #861's trucks adds fuel to the vocational idle
    cycles only (tractors have none in GEM, 1037.510(c)); DOE's larger accessory loads add fuel
    to every vehicle they are given for."""
    base = {r["vehicle"]: r["model_g_per_ton_mile"] for r in reference_rows}
    idle = hd_validation.check_reference_vehicles(idle_add_gal_per_h=hd_validation.measured_idle_additions())
    for r in idle:
        if r["gem_type"].startswith("vocational"):
            assert r["model_g_per_ton_mile"] > base[r["vehicle"]], r
        else:
            assert r["model_g_per_ton_mile"] == base[r["vehicle"]], r
    for r in hd_validation.check_reference_vehicles(columns=hd_validation.doe_nrel_accessories()):
        assert r["model_g_per_ton_mile"] > base[r["vehicle"]], r


def test_doe_accessory_sensitivity_covers_every_reference_vehicle():
    """DOE's accessory load (NREL T3CO ``aux_kw``, reference_inputs_doe_nrel.toml) for every
    reference vehicle: a vehicle T3CO has a class for keeps its own, the others (class 7 day
    cab, heavy HD vocational) take the DOE vehicle the file names for their engine's service
    class (heavy >= 10 L: the class 8 tractors' 3.5 kW; medium: the class 7 box truck's 3.23 kW)."""
    from fleetrun.simulation.heavy_duty_engine import service_class

    doe = _load("reference_inputs_doe_nrel.toml")
    _, vehicles = hd_validation.reference_vehicles()
    loads = hd_validation.doe_nrel_accessories()
    assert set(loads) == set(vehicles)
    for name, basis in vehicles.items():
        stand_in = doe["accessory_by_service_class"][service_class(basis["engine_displacement_L"])]
        expected = doe["vehicles"].get(name, doe["vehicles"][stand_in])["aux_kw"]
        assert loads[name]["accessory_power_W"] == pytest.approx(1000.0 * expected), name
    assert loads["hhd_vocational_urban"]["accessory_power_W"] == pytest.approx(3500.0)


def test_doe_accessories_lower_the_example_trucks_mpg_in_every_scenario():
    """DOE's accessory load (3.5 kW for the class 8 tractors' heavy engines, against the
    simulation's 1.4 kW) costs fuel on every truck in every scenario: the sensitivity of
    docs/validation-heavy-duty.md that took the hot-summer class average below VM-1's 5.4 mpg."""
    shipped = {(r["scenario"], r["vehicle"]): r["mpg"] for r in hd_validation.check_example_combination_trucks()}
    doe = hd_validation.check_example_combination_trucks(doe_accessories=True)
    assert {(r["scenario"], r["vehicle"]) for r in doe} == set(shipped)
    assert all(r["mpg"] < shipped[(r["scenario"], r["vehicle"])] for r in doe), doe


def test_idle_brackets_add_the_accessory_loads():
    """The idle comparison's brackets: the engine alone < with the simulation's accessory load
    < with DOE's larger one, the difference being the accessory power over the engine's
    Willans slope (Fact #861's trucks ran their engine-driven accessories, no A/C or fans)."""
    for r in hd_validation.check_idle_fuel():
        assert r["model_gal_per_h"] < r["with_accessories_gal_per_h"] < r["with_doe_accessories_gal_per_h"], r


def test_stops_in_drive_charge_the_converter_at_the_transient_cycles_stops(reference_rows):
    """The stops-in-drive sensitivity: an automatic stopped in gear burns its drive-idle rate at
    the drive cycles' stops (GEM's baseline; neutral idle is an improvement input, 40 CFR
    1037.520(h)(2)(ii)). The transient cycle's stops (37.6 s per mile of the ARB transient, none
    on the cruise cycles) add (drive - parked idle) x stopped time per mile to the automatics
    (the vocational vehicles) only; the tractors' manual clutch is open at a stop."""
    assert hd_validation.stopped_hours_per_mile("ARB-TRANSIENT") * 3600.0 == pytest.approx(37.6, abs=0.1)
    assert hd_validation.stopped_hours_per_mile("CRUISE-65-GRADE") == 0.0
    base = {r["vehicle"]: r for r in reference_rows}
    stopped_h = hd_validation.stopped_hours_per_mile("ARB-TRANSIENT")
    for r in hd_validation.check_reference_vehicles(stops_in_drive=True):
        b = base[r["vehicle"]]
        extra = (b["drive_idle_gal_per_h"] - b["parked_idle_gal_per_h"]) * stopped_h
        assert 1.0 / r["mpg_by_cycle"]["ARB-TRANSIENT"] == pytest.approx(
            1.0 / b["mpg_by_cycle"]["ARB-TRANSIENT"] + extra, rel=2e-3), r
        assert r["mpg_by_cycle"]["CRUISE-65-GRADE"] == b["mpg_by_cycle"]["CRUISE-65-GRADE"]
        assert (r["model_g_per_ton_mile"] > b["model_g_per_ton_mile"]) == r["gem_type"].startswith("vocational")
