"""The FTP-75 cycle (bags, soak, EPA's composite) and the cold-start model in the simulation.

Measured references:
- EPA 2022 Test Car List (inputs/epa/22-tstcar.csv), gasoline FTP rows: bag 1 and bag 3 fuel
  economy and the composite (RND_ADJ_FE), and the 20 F "Cold CO" FTP rows;
- Argonne 2018 Camry (inputs/dyno, PROVENANCE.md): cold-start UDDS 392.6 cm^3 in the first
  505 s against 336.0 hot (+16.8 %); 505-1369 s 393.4 against 395.0 (-0.4 %).
"""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from fleetrun.cli import cli
from fleetrun.cycles import composite_per_mile, ftp_weighted_per_mile, load_cycle, shipped_cycles
from fleetrun.resources import inputs_dir
from fleetrun.simulation import MODES, simulate
from fleetrun.simulation import thermal
from fleetrun.testing.vehicles import ALL, CAMRY
from test_fleet_fakes import read_csv, scenario, vehicle, write_fleet

EPA = inputs_dir() / "epa" / "22-tstcar.csv"
FTP_PROCEDURES = ("Federal fuel 2-day exhaust (w/can load)", "Federal fuel 3-day exhaust",
                  "CVS 75 and later (w/o can. load)")
LD_GASOLINE = [v for v in ALL if v.duty_class == "LD"]


@pytest.fixture(scope="module")
def epa_gasoline():
    d = pd.read_csv(EPA, low_memory=False)
    gas = ~d["Test Fuel Type Description"].str.contains("Diesel|E85|Electricity|Hydrogen", na=True)
    bags = (d["FE Bag 1"] > 0) & (d["FE Bag 2"] > 0) & (d["FE Bag 3"] > 0)
    return d[gas & bags]


# ----------------------------------------------------------------------------- the cycle

def test_ftp_is_listed_and_composed_of_the_udds():
    assert "FTP" in shipped_cycles()[5:]
    ftp, udds = load_cycle("ftp"), load_cycle("UDDS")
    assert [p.name for p in ftp.phases] == ["bag1", "bag2", "bag3"] and ftp.composite == "ftp"
    phase = ftp.step_phase()
    # 40 CFR 86.135-12(a): bag 1 = 505 s, bag 2 = the rest of the UDDS (864 s), a 10-minute
    # soak, bag 3 = the first 505 s again
    assert [(phase == k).sum() for k in range(3)] == [506, 864, 505]   # bag 1 also holds step 0
    (soak,) = np.flatnonzero(phase < 0)
    assert ftp.time_s[soak] - ftp.time_s[soak - 1] == 600.0
    assert ftp.duration_s == 1369 + 600 + 505
    # EPA FTP-75: 11.04 mi (17.77 km); bags 1 + 2 are the whole UDDS
    assert ftp.miles == pytest.approx(udds.miles + _miles(udds, 0, 505), abs=1e-9)
    assert round(ftp.miles, 2) == 11.04


def _miles(cycle, start_s, end_s):
    sel = (cycle.time_s >= start_s) & (cycle.time_s <= end_s)
    t, v = cycle.time_s[sel], cycle.speed_mps[sel]
    return float(np.sum(0.5 * (v[1:] + v[:-1]) * np.diff(t))) / 1609.344


def test_weighting_reproduces_epa_composites(epa_gasoline):
    """EPA's composite (RND_ADJ_FE of the FTP rows) from its own bag fuel economies with the
    nominal bag distances: the median relative difference is measured at -0.03 %, the
    quartiles at +-0.17 %; bounds 0.1 % and 0.5 % cover the rounding of the published bag
    values and each test's measured distances (86.144 uses the measured D, not the nominal)."""
    d = epa_gasoline[epa_gasoline["Test Procedure Description"].isin(FTP_PROCEDURES)]
    assert len(d) > 1000
    udds = load_cycle("UDDS")
    d1, d2 = _miles(udds, 0, 505), _miles(udds, 505, 1369)
    f1, f2, f3 = (d1 / d["FE Bag 1"], d2 / d["FE Bag 2"], d1 / d["FE Bag 3"])   # gallons per bag
    composite = 1.0 / ftp_weighted_per_mile(f1, f2, f3, d1, d2, d1)
    err = composite / d["RND_ADJ_FE"] - 1.0
    assert abs(err.median()) < 0.001
    assert err.abs().quantile(0.75) < 0.005


def test_weighting_by_hand():
    # equal fuel per mile in every bag: the composite is that value; the weights are 0.43 / 0.57
    assert ftp_weighted_per_mile(2.0, 4.0, 2.0, 1.0, 2.0, 1.0) == pytest.approx(2.0)
    assert ftp_weighted_per_mile(4.0, 0.0, 0.0, 1.0, 1.0, 1.0) == pytest.approx(0.43 * 2.0)
    assert composite_per_mile("", {"a": 1.0, "b": 3.0}, {"a": 1.0, "b": 1.0}) == 2.0


# ----------------------------------------------------------------------------- the thermal model

def test_thermal_pieces():
    k = thermal.thermal_constants()
    # the Walther fit goes through the oil's two points; viscosity ratio 1 at the thermostat
    A, B = k.oil_walther["gasoline"]
    assert thermal.oil_viscosity_ratio(100.0, 40.0, A, B) == pytest.approx(8.5 / 45.0, rel=1e-9)
    assert thermal.oil_viscosity_ratio(k.thermostat_temp_C, k.thermostat_temp_C, A, B) == 1.0
    # Newton cooling: 0 s keeps the temperature, inf reaches ambient, one tau leaves 1/e
    assert thermal.soaked_temperature_C(90.0, 20.0, 0.0, 100.0) == 90.0
    assert thermal.soaked_temperature_C(90.0, 20.0, math.inf, 100.0) == 20.0
    assert thermal.soaked_temperature_C(90.0, 20.0, 100.0, 100.0) == pytest.approx(20 + 70 / math.e)
    # first law until the thermostat holds the temperature
    assert thermal.warmed_temperature_C(20.0, 1e6, 1e5, 90.0) == pytest.approx(30.0)
    assert thermal.warmed_temperature_C(20.0, 1e8, 1e5, 90.0) == 90.0
    assert thermal.enrichment_fraction(25.0, 90.0, 0.1) == pytest.approx(0.1)
    assert thermal.enrichment_fraction(95.0, 90.0, 0.1) == 0.0


def test_engine_temperature_is_the_heat_released_so_far():
    """The forward pass: T before step i = T0 + f LHV (fuel of steps < i) / C, Newton cooling
    in the engine-off step."""
    k = thermal.thermal_constants()
    fuel_g = np.array([[0.0, 1.0, 2.0, 0.0, 3.0]])
    soak = np.array([0.0, 0.0, 0.0, 600.0, 0.0])
    C, lhv = 1e5, np.array([42.9])
    T = thermal.engine_temperature_C(fuel_g, np.array([C]), lhv, 20.0, soak, 20.0, k)
    per_g = k.heat_fraction * 42.9e3 / C
    np.testing.assert_allclose(T[0, :3], [20.0, 20.0, 20.0 + per_g])
    end = 20.0 + 3.0 * per_g
    cooled = 20.0 + (end - 20.0) * math.exp(-600.0 / k.soak_time_constant_s)
    np.testing.assert_allclose(T[0, 3:], [cooled, cooled])


# ----------------------------------------------------------------------------- in the simulation

@pytest.fixture(scope="module")
def ftp_runs():
    return {mode: simulate(ALL, "FTP", mode=mode, ambient_temp_C=25.0) for mode in MODES}


def test_three_modes_agree_on_ftp_fuel(ftp_runs):
    """docs/interface.md: the three modes agree within 0.2 % on cycle fuel; also per bag."""
    direct = ftp_runs["direct"]
    for mode in ("map2d", "map3d"):
        np.testing.assert_allclose(ftp_runs[mode].fuel_gal, direct.fuel_gal, rtol=0.002)
        for bag in ("bag1", "bag2", "bag3"):
            np.testing.assert_allclose(ftp_runs[mode].phases[bag].fuel_g, direct.phases[bag].fuel_g, rtol=0.002)


def test_composite_and_bags_are_consistent(ftp_runs):
    r = ftp_runs["map3d"]
    bags = r.phases
    gal = {b: bags[b].fuel_gal for b in bags}
    miles = {b: bags[b].miles for b in bags}
    np.testing.assert_allclose(r.miles, sum(miles.values()), rtol=1e-12)
    np.testing.assert_allclose(r.fuel_gal / r.miles, ftp_weighted_per_mile(gal["bag1"], gal["bag2"], gal["bag3"],
                                                                            miles["bag1"], miles["bag2"], miles["bag3"]),
                               rtol=1e-12)
    np.testing.assert_allclose(r.mpg, r.miles / r.fuel_gal, rtol=1e-12)
    for b in bags:
        np.testing.assert_allclose(bags[b].mpg, miles[b] / gal[b], rtol=1e-12)
    # a cold bag 1 burns more than the same driving hot (bag 3) in every vehicle
    assert np.all(bags["bag1"].fuel_g > bags["bag3"].fuel_g)


def _warm_udds_bags(spec, ambient_temp_C):
    """Fuel [g] of the first 505 s and of the rest of a UDDS driven with a warm engine (a plain
    cycle) at the same ambient (which also sets the axle oil's temperature)."""
    udds = simulate([spec], "UDDS", ambient_temp_C=ambient_temp_C, trace=True).trace_frame(0)
    step_fuel = udds.fuel_rate_g_per_s * np.diff(udds.time_s, prepend=0.0)
    return step_fuel[:506].sum(), step_fuel[506:].sum()


def test_a_warm_ftp_is_the_warm_udds():
    """At an ambient at the thermostat temperature the engine is never cold: the bags are the
    warm UDDS's parts exactly (the cold-start pass adds nothing to a warm engine)."""
    ambient = thermal.thermal_constants().thermostat_temp_C
    hot = simulate([CAMRY], "FTP", ambient_temp_C=ambient, trace=True)
    first, rest = _warm_udds_bags(CAMRY, ambient)
    assert hot.phases["bag1"].fuel_g[0] == pytest.approx(first, rel=1e-12)
    assert hot.phases["bag2"].fuel_g[0] == pytest.approx(rest, rel=1e-12)
    assert hot.phases["bag3"].fuel_g[0] == pytest.approx(first, rel=1e-12)  # step 0 has no time
    assert (hot.trace.cold_start_fuel_g_per_s == 0).all()


def test_camry_cold_start_against_argonne():
    """The 2018 Camry's measured cold start (inputs/dyno): +16.8 % fuel in the first 505 s of
    a cold UDDS over the hot one, and the stabilised phase the same (-0.4 %). The model (no
    fit uses these recordings) is compared at the FTP's nominal 25 C: its bag 1 penalty must
    lie within 5 points of the measured one (about the EPA list's spread between vehicles:
    bag 1 / bag 3 interquartile range 1.121-1.184), its bag 2 penalty below 1 %. History:
    issue 10's constants gave +15.7 %; issue 22's refit of the fuel constants (constant
    friction in place of throttle pumping) without a thermal refit gave +22.7 % and the bound
    was widened to 6.4 points; the thermal constants refitted on the new fuel constants
    (heat capacity 15 kJ/K per L, enrichment 0.3; models/thermal.toml, docs/simulation.md)
    give +17.8 %, so the bound is back at 5 points."""
    cold = simulate([CAMRY], "FTP", ambient_temp_C=25.0)
    first, rest = _warm_udds_bags(CAMRY, 25.0)
    penalty = {"bag1": cold.phases["bag1"].fuel_g[0] / first - 1.0,
               "bag2": cold.phases["bag2"].fuel_g[0] / rest - 1.0}
    assert abs(penalty["bag1"] - (392.6 / 336.0 - 1.0)) <= 0.05
    assert 0.0 <= penalty["bag2"] < 0.01


def test_bag_ratio_against_the_epa_list(epa_gasoline):
    """Bag 1 / bag 3 fuel of the example cars against the EPA list's gasoline vehicles: at the
    FTP's 25 C inside the list's 5-95 % range (1.082-1.253), and at 20 F (-6.7 C, the "Cold CO"
    FTP, which no fit uses) inside its 5-95 % range (1.207-1.618). The example cars are not the
    list's vehicles, so the bound is the spread between vehicles; the per-vehicle comparison
    is validation/ftp_coldstart.py (docs/simulation.md)."""
    d = epa_gasoline
    warm = d[d["Test Procedure Description"].isin(FTP_PROCEDURES)]
    cold = d[d["Test Procedure Description"] == "Cold CO"]
    ratio_warm = (warm["FE Bag 3"] / warm["FE Bag 1"]).quantile([0.05, 0.95]).to_numpy()
    ratio_cold = (cold["FE Bag 3"] / cold["FE Bag 1"]).quantile([0.05, 0.95]).to_numpy()
    for temp, (lo, hi) in ((25.0, ratio_warm), (-6.7, ratio_cold)):
        r = simulate(LD_GASOLINE, "FTP", ambient_temp_C=temp).phases
        model = r["bag1"].fuel_g / r["bag3"].fuel_g
        assert lo <= np.median(model) <= hi, (temp, model, lo, hi)


def test_trace_has_phases_soak_and_temperature():
    r = simulate([CAMRY], "FTP", ambient_temp_C=10.0, trace=True)
    df = r.trace_frame(0)
    assert list(df.columns[-3:]) == ["phase", "engine_temp_C", "cold_start_fuel_g_per_s"]
    assert df.phase.iloc[0] == "bag1" and df.phase.iloc[-1] == "bag3"
    soak = df[df.phase == ""]
    assert len(soak) == 1 and soak.fuel_rate_g_per_s.iloc[0] == 0 and soak.engine_speed_rpm.iloc[0] == 0
    assert df.engine_temp_C.iloc[0] == 10.0 and df.engine_temp_C.max() == thermal.thermal_constants().thermostat_temp_C
    # the trace's fuel (cold-start fuel included) sums to the bags
    dt = np.diff(df.time_s, prepend=0.0)
    for bag in ("bag1", "bag2", "bag3"):
        sel = df.phase == bag
        assert (df.fuel_rate_g_per_s[sel] * dt[sel]).sum() == pytest.approx(r.phases[bag].fuel_g[0], rel=1e-9)
    # the same numbers without the trace (standstill steps skipped)
    fast = simulate([CAMRY], "FTP", ambient_temp_C=10.0)
    assert fast.mpg[0] == pytest.approx(r.mpg[0], rel=1e-9)


def test_simulate_cli_prints_bags(tmp_path):
    out = tmp_path / "trace.csv"
    r = CliRunner().invoke(cli, ["simulate", "--vehicle-file", str(inputs_dir() / "dyno" / "camry2018_udds_hot.toml"),
                                 "--cycle", "FTP", "--ambient-temp-C", "25", "-o", str(out)])
    assert r.exit_code == 0, r.output
    line = json.loads(r.output.strip().splitlines()[-1])
    assert line["composite"] == "ftp" and set(line["phases"]) == {"bag1", "bag2", "bag3"}
    assert line["mpg"] == pytest.approx(line["miles"] / line["fuel_gal"])
    assert line["phases"]["bag1"]["mpg"] < line["mpg"] < line["phases"]["bag3"]["mpg"]
    trace = pd.read_csv(out, keep_default_na=False)
    assert set(trace.phase) == {"bag1", "bag2", "bag3", ""}


def test_run_uses_the_composite(tmp_path):
    """In `fleetrun run` a vehicle's FTP share is driven at the composite fuel per mile."""
    path = write_fleet(tmp_path / "fleet.xlsx", [vehicle("CAR-1")],
                       [scenario("city", cycle_mix="FTP:1", ambient_temp_C=5, budget_years=1,
                                 vmt_growth_pct_per_year=0, onroad_adjustment="none")])
    out = tmp_path / "out"
    r = CliRunner().invoke(cli, ["run", str(path), "--out", str(out), "--cache-dir", str(tmp_path / "c"), "-q"])
    assert r.exit_code == 0, r.output
    row = read_csv(out / "results.csv").iloc[0]
    from fleetrun.workbook.reader import read_fleet
    spec = read_fleet(path).vehicles[0]
    direct = simulate([spec], "FTP", ambient_temp_C=5.0)
    # the run's centre carries the known fleet bias correction (docs/budget.md): gallons x (1 + bias)
    from fleetrun.budget.uncertainty import read_error_model

    bias = read_error_model().for_duty("LD").bias
    assert row.mpg == pytest.approx(direct.mpg[0] / (1.0 + bias), rel=1e-9)


def test_thermal_constants_can_be_varied_per_call():
    """The calibration's handle (simulate(..., thermal=...)): without enrichment and with
    friction independent of viscosity (n = 0) a cold start costs nothing; a larger heat capacity
    (slower warm-up) costs more."""
    import dataclasses

    k = thermal.thermal_constants()
    free = dataclasses.replace(k, viscosity_exponent=0.0, enrichment_at_25C={"gasoline": 0.0, "diesel": 0.0})
    r = simulate([CAMRY], "FTP", ambient_temp_C=0.0, thermal=free).phases
    first, _ = _warm_udds_bags(CAMRY, 0.0)
    assert r["bag1"].fuel_g[0] == pytest.approx(first, rel=1e-12)
    base = simulate([CAMRY], "FTP", ambient_temp_C=0.0).phases["bag1"].fuel_g[0]
    slow = dataclasses.replace(k, heat_capacity_J_per_K_per_L=2 * k.heat_capacity_J_per_K_per_L)
    assert simulate([CAMRY], "FTP", ambient_temp_C=0.0, thermal=slow).phases["bag1"].fuel_g[0] > base


def test_heat_capacity_by_engine_mass():
    """The cold start's optional engine-mass basis (docs/validation-epa.md, issue 22 fourth round,
    measured and not adopted): FASTSim 2's fuel-converter mass 61 kg + P / 2.13 kW/kg (150 kW:
    131.4 kg by hand); the stored constants keep the displacement basis; on the mass basis with
    the capacity per kg that gives a 2.5 L, 150 kW engine the same node as 15 kJ/K per litre, an
    engine of twice the displacement and 1.4 times the power warms faster than c_L V_d says, so
    its cold bag 1 costs less."""
    import dataclasses

    from fleetrun.simulation.params import vehicle_arrays

    assert thermal.engine_mass_kg(150.0, 61.0, 2.13) == pytest.approx(61.0 + 150.0 / 2.13, rel=1e-12)
    k = thermal.thermal_constants()
    assert k.heat_capacity_basis == "displacement"
    va = vehicle_arrays([CAMRY])
    assert thermal.node_heat_capacity_J_per_K(va, k)[0] == pytest.approx(2.487 * k.heat_capacity_J_per_K_per_L)
    per_kg = 2.5 * k.heat_capacity_J_per_K_per_L / thermal.engine_mass_kg(150.0, 61.0, 2.13)
    mass = dataclasses.replace(k, heat_capacity_basis="engine_mass", heat_capacity_J_per_K_per_kg=per_kg)
    camry_kg = 61.0 + 151.4 / 2.13                                  # the Camry's 151.4 kW
    assert thermal.node_heat_capacity_J_per_K(va, mass)[0] == pytest.approx(per_kg * camry_kg, rel=1e-12)
    big = dataclasses.replace(CAMRY, vehicle_id="big", engine_displacement_L=5.0, rated_power_kW=210.0,
                              peak_engine_torque_Nm=500.0)
    warm, _ = _warm_udds_bags(big, 25.0)
    cold = {name: simulate([big], "FTP", ambient_temp_C=25.0, thermal=kk).phases["bag1"].fuel_g[0] - warm
            for name, kk in (("displacement", k), ("mass", mass))}
    assert 0.0 < cold["mass"] < cold["displacement"]


def test_composed_cycle_errors_name_the_file(tmp_path):
    from fleetrun.errors import InputError

    empty = tmp_path / "none.toml"
    empty.write_text('composite = "ftp"\n')
    with pytest.raises(InputError, match="at least one \\[\\[phase\\]\\]") as e:
        load_cycle(empty)
    assert "none.toml" in str(e.value)
    rule = tmp_path / "rule.toml"
    rule.write_text('composite = "ftpp"\n[[phase]]\nname = "a"\ncycle = "UDDS"\nstart_s = 0\nend_s = 505\n')
    with pytest.raises(InputError, match="did you mean 'ftp'"):
        load_cycle(rule)
    moving = tmp_path / "moving.toml"
    moving.write_text('[[phase]]\nname = "a"\ncycle = "UDDS"\nstart_s = 0\nend_s = 100\n'
                      '[[phase]]\nname = "b"\ncycle = "UDDS"\nstart_s = 100\nend_s = 505\nsoak_before_s = 60\n')
    with pytest.raises(InputError, match="does not start at rest"):
        load_cycle(moving)


def test_resampled_ftp_keeps_its_bags():
    from fleetrun.cycles import resample

    ftp = load_cycle("FTP")
    again = resample(ftp, 1.0)
    assert again.phases == ftp.phases and again.composite == "ftp"
    # the soak is filled with engine-off steps at rest; the bags are unchanged
    assert (again.step_phase() < 0).sum() == 600
    a, b = (simulate([CAMRY], c, ambient_temp_C=10.0) for c in (ftp, again))
    for bag in ("bag1", "bag2", "bag3"):
        assert b.phases[bag].fuel_g[0] == pytest.approx(a.phases[bag].fuel_g[0], rel=1e-9)


def test_a_vehicles_ftp_does_not_depend_on_its_companions():
    """The cold start's fixed-point iteration converges per vehicle: a vehicle simulated alone,
    with one other vehicle or among many (other blocks, other companions) gets the same FTP fuel.
    Iterating until the whole block converged made results move by up to 2.5e-9 with the
    block's make-up (a fleet's numbers must not depend on which other rows it holds). What is
    left is rounding: the steps the iteration works on are those where some engine of the block
    is cold, so the same heat sums are grouped differently (measured 2e-15): rtol 1e-13."""
    # engines of 1-6 L warm up at different rates, so they converge after different passes
    # (with the block-wide stop the 1.0 and 1.5 L cars moved by 1.4e-9 and 2.0e-9 at -7 C)
    cars = [dataclasses.replace(CAMRY, vehicle_id=f"camry_{d}L", engine_displacement_L=d)
            for d in (1.0, 1.5, 2.5, 4.0, 6.0)]
    alone = [simulate([v], "FTP", ambient_temp_C=-7.0).fuel_gal[0] for v in cars]
    pair = simulate([cars[0], cars[-1]], "FTP", ambient_temp_C=-7.0).fuel_gal
    many = simulate(cars * 20, "FTP", ambient_temp_C=-7.0).fuel_gal
    np.testing.assert_allclose(pair, [alone[0], alone[-1]], rtol=1e-13, atol=0)
    np.testing.assert_allclose(many, alone * 20, rtol=1e-13, atol=0)
