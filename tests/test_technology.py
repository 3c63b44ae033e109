"""Technology classes as physics (fleetrun/simulation/technology.py), the OMEGA join
(fleetrun/epa/technology.py) and one measured number (fleetrun/simulation/measured.py).

Expected values are derived independently here (closed-form thermodynamics, the definition of
bmep, EPA's label formulas, energy bookkeeping over the cycle), not read from the code."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest

from fleetrun.cycles import load_cycle
from fleetrun.epa.technology import join_rules, match_configuration, omega_vehicles, technology_of_class
from fleetrun.errors import InputError
from fleetrun.resources import inputs_dir
from fleetrun.physics import epa_label
from fleetrun.simulation import measured, simulate
from fleetrun.simulation import technology as tech
from fleetrun.simulation.core import idle_fuel_rate_g_per_s, trace_kinematics
from fleetrun.simulation.params import vehicle_arrays
from fleetrun.testing.vehicles import CAMRY


def test_expansion_ratio_gain_is_the_otto_cycle_ratio():
    # Heywood Eq. 5.31: eta = 1 - r^(1 - gamma); 10.5:1 -> 13:1 at gamma 1.3
    base, high = 1 - 10.5 ** -0.3, 1 - 13.0 ** -0.3
    assert tech.expansion_ratio_gain(13.0, 10.5, 1.3) == pytest.approx(base / high, rel=1e-12)
    assert 0.93 < base / high < 0.95          # about 6 % less fuel per unit brake work


def test_boosted_engine_is_unthrottled_above_the_naturally_aspirated_bmep():
    # bmep = 4 pi T / V_d: a 2.0 L engine at 151.2 N m is at 950 kPa
    torque = 950.0 * 2.0 / (4 * math.pi)
    share = tech.boosted_pumping_share(np.array([0.0, torque / 2, torque, 2 * torque]), 2.0, 950.0)
    assert share == pytest.approx([1.0, 0.5, 0.0, 0.0], abs=1e-12)


def test_deactivation_runs_half_the_engine_at_twice_the_load_inside_its_window():
    load = np.array([0.2, 0.2, 0.2, 0.5])
    rpm = np.array([1500.0, 800.0, 1500.0, 1500.0])
    moving = np.array([True, True, False, True])
    share = tech.deactivated_pumping_share(1 - load, load, rpm, moving, 0.3, 1000.0, 3000.0)
    # in the window: 0.5 (1 - 2 x 0.2) = 0.3; below min rpm, standing, or above max load: 1 - L
    assert share == pytest.approx([0.3, 0.8, 0.8, 0.5])


def test_unknown_technology_names_the_closest():
    assert tech.parse_technology("Start-Stop, turbo") == tuple(t in ("start_stop", "turbo") for t in tech.TECHNOLOGIES)
    assert tech.parse_technology("none") == (False,) * len(tech.TECHNOLOGIES)
    with pytest.raises(InputError, match="did you mean 'start_stop'"):
        tech.parse_technology("startstop")
    with pytest.raises(InputError, match="vehicle 'camry'.*technology"):
        vehicle_arrays([dataclasses.replace(CAMRY, technology="warp_drive")])


def _warm_stop_seconds(cycle, inhibit_s):
    c = load_cycle(cycle)
    t, v = np.asarray(c.time_s, float), np.asarray(c.speed_mps, float)
    still = (0.5 * (v[1:] + v[:-1]) <= 1e-6) & (t[1:] >= t[0] + inhibit_s)
    return float(np.diff(t)[still].sum())


def test_start_stop_saves_exactly_the_idle_fuel_of_the_warm_stops():
    # with the fitted stop power, the saving is (idle rate - stop power / LHV) x warm standstill time
    ss = dataclasses.replace(CAMRY, technology="start_stop")
    c = tech.technology_constants()
    base, with_ss = simulate([CAMRY], "UDDS").fuel_g[0], simulate([ss], "UDDS").fuel_g[0]
    va = vehicle_arrays([CAMRY])
    rate = idle_fuel_rate_g_per_s(va)[0] - c.stop_fuel_power_W / (va.lhv[0] * 1e3)
    assert base - with_ss == pytest.approx(rate * _warm_stop_seconds("UDDS", c.inhibit_after_cold_start_s), rel=1e-9)
    traced = simulate([ss], "UDDS", trace=True)
    assert traced.fuel_g[0] == pytest.approx(with_ss, rel=1e-12)    # the traced and the fast path agree


def test_mild_hybrid_returns_no_more_than_the_braking_energy_it_could_take():
    mh = dataclasses.replace(CAMRY, technology="mild_hybrid_48v")
    r0, r1 = simulate([CAMRY], "UDDS", trace=True), simulate([mh], "UDDS", trace=True)
    c = tech.technology_constants()
    dt, wheel = np.broadcast_to(trace_kinematics(r0.trace).dt, r0.trace.wheel_power_W.shape)[0], r0.trace.wheel_power_W[0]
    ceiling = c.round_trip_efficiency * (np.clip(-wheel, 0, c.motor_power_48v_W) * dt).sum()
    work = lambda r: (np.maximum(r.trace.engine_power_W[0], 0) * dt).sum()  # noqa: E731
    saved = work(r0) - work(r1)
    assert 0 < saved <= ceiling * (1 + 1e-9)
    assert saved <= c.max_assist_share * work(r0) * (1 + 1e-9)
    assert r1.fuel_g[0] < r0.fuel_g[0]


def test_join_finds_the_omega_vehicle_of_its_own_road_load_and_refuses_a_far_one():
    row = omega_vehicles()[lambda t: t.cost_curve_class.str.contains("_SS1")].iloc[0]
    assert len(pd.read_csv(inputs_dir() / "epa" / "omega_vehicles_my2022.csv")) == len(omega_vehicles())
    # the Test Car List's name of the OMEGA manufacturer (models/epa_technology.toml [manufacturers])
    test_name = next(k for k, v in join_rules()["manufacturers"].items() if v == row.manufacturer_id)
    m = match_configuration(test_name, row.engine_displacement_liters, row.target_coef_a, row.target_coef_b,
                            row.target_coef_c)
    assert m.road_load_difference == 0.0 and "start_stop" in m.technology.split(",")
    assert m.join == "road_load"
    # 10 % off every OMEGA road load: the engine's classes, the most-sold technology of the
    # manufacturer's OMEGA vehicles of that displacement (models/epa_technology.toml [engine_join])
    far = match_configuration(test_name, row.engine_displacement_liters, 1.1 * row.target_coef_a,
                              1.1 * row.target_coef_b, 1.1 * row.target_coef_c)
    table = omega_vehicles()
    same_engine = table[(table.manufacturer_id == row.manufacturer_id)
                        & ((table.engine_displacement_liters - row.engine_displacement_liters).abs() <= 0.1)]
    assert far.join == "engine" and far.technology == same_engine.groupby("technology").sales.sum().idxmax()
    assert "the engine's classes" in far.note and "differs by" in far.note
    nothing = match_configuration(test_name, 99.0, row.target_coef_a, row.target_coef_b, row.target_coef_c)
    assert nothing.join == "" and nothing.technology == "" and nothing.note.startswith("no technology class")
    assert technology_of_class("P0_SLA_AWD_TDS_TRX21R_SS1") == "mild_hybrid_48v,start_stop,turbo"


def test_import_epa_attaches_classes_to_most_of_the_list():
    # the re-analysis joined about 63 % of the list's configurations to OMEGA
    from fleetrun.epa import import_test_car_list

    result = import_test_car_list(inputs_dir() / "epa" / "22-tstcar.csv")
    notes = [d for d in result.derived if d["column"] == "technology"]
    assert len(notes) == len(result.vehicles)        # every row says what matched or why not
    by_road_load = [n for n in notes if "target road load within" in n["rule"]]
    assert 0.6 <= len(by_road_load) / len(result.vehicles) <= 0.8
    # the others have an OMEGA vehicle of their manufacturer and displacement: their engine's classes
    assert all(v.get("technology") for v in result.vehicles)


@pytest.mark.parametrize(("model_year", "city_ab", "highway_ab"), [
    (2016, (0.003259, 1.1805), (0.001376, 1.3466)),     # 2008 label rule set (models/budget.toml)
    (2022, (0.004091, 1.1601), (0.003191, 1.2945)),     # MY2017+ set
    (None, (0.004091, 1.1601), (0.003191, 1.2945)),     # no model year: a current vehicle
])
def test_label_scale_reproduces_the_label_through_epas_formulas(model_year, city_ab, highway_ab):
    """The label is inverted with the derived 5-cycle set of the vehicle's model year (40 CFR
    600.210-12(a)(2); the sets' sources in models/budget.toml)."""
    ftp, hwy, label = np.array([30.0]), np.array([45.0]), np.array([27.0])
    k = measured.label_scale(label, ftp, hwy, model_years=[model_year])
    city = 1 / (city_ab[0] + city_ab[1] * k / ftp)
    highway = 1 / (highway_ab[0] + highway_ab[1] * k / hwy)
    assert 1 / (0.55 / city + 0.45 / highway) == pytest.approx(label, rel=1e-12)


@pytest.mark.parametrize("highway_share", [0.0, 0.55, 1.3])
def test_label_scale_with_a_split_still_gives_the_label(highway_share):
    """With FTP / k and HWFET / k^h (models/technology.toml [label_split]) the derived formulas
    (MY2017 set, 40 CFR 600.210-12) give the label back; alone and for a label group (the mean
    of the group's label fuel per mile is the label's)."""
    ftp, hwy, label = np.array([30.0, 25.0, 40.0]), np.array([45.0, 35.0, 55.0]), np.array([27.0, 20.0, 30.0])
    (ac, bc), (ah, bh) = (0.004091, 1.1601), (0.003191, 1.2945)

    def label_gpm(k):
        return 0.55 * (ac + bc * k / ftp) + 0.45 * (ah + bh * k ** highway_share / hwy)

    k = measured.label_scale(label, ftp, hwy, model_years=[2022] * 3, highway_share=highway_share)
    assert label_gpm(k) == pytest.approx(1.0 / label, rel=1e-12)
    g = measured.label_scale(label, ftp, hwy, model_years=[2022] * 3, groups=["a", "a", None],
                             highway_share=highway_share)
    assert g[0] == g[1] and g[2] == pytest.approx(k[2], rel=1e-12)
    assert label_gpm(g)[:2].mean() == pytest.approx((1.0 / label[:2]).mean(), rel=1e-12)


def test_a_label_takes_k_on_the_ftp_k_to_h_on_the_hwfet_and_k_to_s_elsewhere():
    """`simulate` with `label_combined_mpg`: the FTP and HWFET at 25 C meet the label through
    EPA's formulas with the HWFET scaled by k^h; US06 and other ambients take k^s'
    (models/technology.toml [label_split]; docs/validation-epa.md, F2)."""
    split = measured.label_split()
    cal = dataclasses.replace(CAMRY, label_combined_mpg=27.0, model_year=2022)
    raw = {c: simulate([CAMRY], c, ambient_temp_C=25.0).mpg[0] for c in ("FTP", "HWFET", "US06")}
    new = {c: simulate([cal], c, ambient_temp_C=25.0).mpg[0] for c in ("FTP", "HWFET", "US06")}
    k = raw["FTP"] / new["FTP"]
    assert new["HWFET"] == pytest.approx(raw["HWFET"] / k ** split.highway_share, rel=1e-12)
    assert new["US06"] == pytest.approx(raw["US06"] / k ** split.transfer_share, rel=1e-12)
    assert epa_label.combined_label_mpg(new["FTP"], new["HWFET"], epa_label.set_for_model_year(2022)) == \
        pytest.approx(27.0, rel=1e-9)
    cold = simulate([CAMRY], "FTP", ambient_temp_C=-7.0).mpg[0] / simulate([cal], "FTP", ambient_temp_C=-7.0).mpg[0]
    assert cold == pytest.approx(k ** split.transfer_share, rel=1e-12)


def test_a_label_with_city_and_highway_figures_takes_the_blend():
    """`label_city_mpg` and `label_highway_mpg` (F5, docs/validation-epa.md): the FTP at 25 C meets
    the city figure through EPA's city formula (MY2017 set, 40 CFR 600.210-12); the HWFET takes
    exp(w log k_H + (1 - w) h' log k), k_H the highway formula's scale, k the combined figure's
    (their 55/45 mean when no combined figure is given); other cycles k^s''."""
    blend = measured.label_blend()
    cal = dataclasses.replace(CAMRY, label_city_mpg=24.0, label_highway_mpg=33.0, model_year=2022)
    raw = {c: simulate([CAMRY], c, ambient_temp_C=25.0).mpg[0] for c in ("FTP", "HWFET", "US06")}
    new = {c: simulate([cal], c, ambient_temp_C=25.0).mpg[0] for c in ("FTP", "HWFET", "US06")}
    (ac, bc), (ah, bh) = (0.004091, 1.1601), (0.003191, 1.2945)
    assert 1.0 / (ac + bc / new["FTP"]) == pytest.approx(24.0, rel=1e-12)
    combined = 1.0 / (0.55 / 24.0 + 0.45 / 33.0)
    k = measured.label_scale(combined, raw["FTP"], raw["HWFET"], model_years=[2022],
                             highway_share=blend.highway_share)[0]
    k_highway = (1.0 / 33.0 - ah) * raw["HWFET"] / bh
    hw = math.exp(blend.weight * math.log(k_highway) + (1 - blend.weight) * blend.highway_share * math.log(k))
    assert new["HWFET"] == pytest.approx(raw["HWFET"] / hw, rel=1e-12)
    assert new["US06"] == pytest.approx(raw["US06"] / k ** blend.transfer_share, rel=1e-12)
    only_city = dataclasses.replace(CAMRY, label_city_mpg=24.0, model_year=2022)     # one of the two: not used
    assert simulate([only_city], "FTP", ambient_temp_C=25.0).mpg[0] == raw["FTP"]


def test_measured_ftp_is_met_exactly_and_carried_with_the_share_elsewhere():
    cal = dataclasses.replace(CAMRY, measured_ftp_mpg=30.0)
    ftp = simulate([CAMRY], "FTP", ambient_temp_C=25.0).mpg[0]
    assert simulate([cal], "FTP", ambient_temp_C=25.0).mpg[0] == pytest.approx(30.0, rel=1e-12)
    k = ftp / 30.0
    hw0, hw1 = simulate([CAMRY], "HWFET").mpg[0], simulate([cal], "HWFET").mpg[0]
    assert hw1 == pytest.approx(hw0 / k ** measured.transfer_share(), rel=1e-12)


def test_rows_of_one_label_group_share_one_scale():
    """Two configurations of one model type (the Camry and a 10 % heavier one) carry one label
    and one `label_group`: one fuel scale k for both, so that the mean of their label fuel per
    mile is the label's (40 CFR 600.208-12: a label is the configurations' mean; equal weights;
    pre-registered G1, docs/validation-epa.md), and the simulation keeps their difference. Alone,
    each would meet the label itself."""
    heavy = dataclasses.replace(CAMRY, vehicle_id="heavy", test_weight_kg=CAMRY.test_weight_kg * 1.1)
    pair = [dataclasses.replace(v, label_combined_mpg=28.0, label_group="camry", model_year=2022)
            for v in (CAMRY, heavy)]
    label_set = epa_label.set_for_model_year(2022)

    def labels(fleet):
        ftp = simulate(fleet, "FTP", ambient_temp_C=25.0).mpg
        hwy = simulate(fleet, "HWFET", ambient_temp_C=25.0).mpg
        return epa_label.combined_label_mpg(ftp, hwy, label_set), ftp

    grouped, ftp = labels(pair)
    assert np.mean(1.0 / grouped) == pytest.approx(1.0 / 28.0, rel=1e-12)
    raw = simulate([dataclasses.replace(v, label_combined_mpg=None) for v in pair], "FTP", ambient_temp_C=25.0).mpg
    assert ftp[0] / ftp[1] == pytest.approx(raw[0] / raw[1], rel=1e-12)      # one k for both
    alone, _ = labels([dataclasses.replace(v, label_group=None) for v in pair])
    assert alone == pytest.approx([28.0, 28.0], rel=1e-12)
    assert abs(grouped[0] - grouped[1]) > 0.1                                # the heavier one burns more
