"""``--with`` effects inside ``simulate`` and ``run`` (issue 5): differential-level effects as an
extra pinion torque on top of every running mode, vehicle-level effects as extra fuel.

Energies are checked against numbers derived from the trace itself: the backward simulation
drives the same speeds with and without an effect (the trace is followed; the vehicles here
have no shortfall), so an effect's extra pinion torque is exactly the difference of the two
runs' differential input torques.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from fleetrun.cli import cli
from fleetrun.cycles import load_cycle
from fleetrun.effects import efficiency_with_effects, parse_with
from fleetrun.workbook.reader import read_fleet
from fleetrun.resources import inputs_dir
from fleetrun.simulation import SUM_FIELDS, diffmodes, simulate
from fleetrun.simulation.core import trace_kinematics
from fleetrun.testing.vehicles import ALL, CAMRY, F150, HD_DUAL, HD_TRUCK
from test_fleet_fakes import read_csv, scenario, vehicle, write_fleet

RAD_PER_RPM = 2 * np.pi / 60
FLEET = inputs_dir() / "example_fleet.xlsx"
UDDS = load_cycle("UDDS")
# every differential-level effect with a non-default size (cornering is 0 on straight cycles)
ALL_DIFFERENTIAL = ("bearing_preload:drag_torque_Nm=3,inertia:J_kg_m2=0.2,oil_warmup:c_w_Nm=2,"
                    "bearing_drag:drag_1000rpm_Nm=1,mixed_lubrication:mu_b=0.1,cornering:k_c=0.3")


def _pinion(trace, i=0):
    """Per-step pinion speed [rad/s], pinion acceleration [rad/s^2], step length, driving mask,
    time since start at the step's middle, from a trace."""
    w = trace.diff_input_speed_rpm[i] * RAD_PER_RPM
    k = trace_kinematics(trace)
    v, a, dt = k.v_avg[i], k.accel[i], k.dt[0]
    moving = v > 1e-6
    alpha = np.where(moving, a * w / np.where(moving, v, 1.0), 0.0)  # G_tot/r x the vehicle's
    t = trace.time_s[i]
    return w, alpha, dt, moving & (trace.wheel_torque_Nm[i] > 0), t - dt / 2 - t[0], moving


# ----------------------------------------------------------------------------- regression
# Inverse of the thesis chain (LD_RWD, G 3.55) by the direct mode, captured before the model
# shims were removed: the differential layer gives the same numbers.
INVERT_BEFORE = [0.00023636191283826674, 0.0003460080767837519, 0.01045507386300369,
                 0.10183044661461525, 0.5069754965280675]


def test_differential_layer_unchanged():
    x = diffmodes.invert_direct("LD_RWD", np.array([1e-8, 1e-4, 0.01, 0.1, 0.5]),
                                np.array([500.0, 1000.0, 2000.0, 3000.0, 4000.0]), 3.55, None, False, "thesis")
    np.testing.assert_allclose(x, INVERT_BEFORE, rtol=1e-12)


@pytest.mark.parametrize("mode", ["direct", "map3d"])
def test_no_effect_and_zero_sized_effects_give_identical_numbers(mode, tmp_path):
    vehicles = [CAMRY, F150, HD_DUAL]
    plain = simulate(vehicles, UDDS, mode=mode, cache_dir=tmp_path, trace=True)
    zero = simulate(vehicles, UDDS, mode=mode, cache_dir=tmp_path, trace=True,
                    effects="bearing_preload:drag_torque_Nm=0,inertia:J_kg_m2=0,warmup:extra_fuel_g_per_s=0,"
                            "accessory_load:power_kW=0,road_grade:grade_pct=0")
    for key in SUM_FIELDS:
        np.testing.assert_array_equal(getattr(zero, key), getattr(plain, key), err_msg=key)
    for key, values in plain.trace.columns().items():
        np.testing.assert_array_equal(np.asarray(getattr(zero.trace, key)), np.asarray(values), err_msg=key)
    assert plain.effects == [] and plain.summary()["with"] == []


# ----------------------------------------------------------------------------- differential level
def test_bearing_preload_adds_drag_times_angular_travel():
    X = 5.0
    base = simulate([CAMRY], UDDS, mode="direct", trace=True)
    pre = simulate([CAMRY], UDDS, mode="direct", trace=True, effects=f"bearing_preload:drag_torque_Nm={X}")
    assert base.shortfall_time_s[0] == pre.shortfall_time_s[0] == 0.0  # the same speeds driven
    w, _, dt, driving, _, _ = _pinion(base.trace)
    travel_rad = float((w * dt)[driving].sum())            # pinion angle turned while driving
    rise_J = float(pre.diff_input_energy_J[0] - base.diff_input_energy_J[0])
    # the drag is X tanh(w / 1 rad/s) (no drag at rest): exactly its work while driving ...
    np.testing.assert_allclose(rise_J, X * float((np.tanh(w) * w * dt)[driving].sum()), rtol=1e-9)
    # ... which is X x travel but for the slow steps: X sum (1 - tanh w) w dt, and
    # w (1 - tanh w) <= 0.2785 rad/s for every w, so the gap is at most X 0.2785 x driving time
    # (0.29 % here; measured 0.0014 %: the pinion turns slower than 3 rad/s only 10 s of 759 s)
    bound_J = X * 0.2785 * float(dt[driving].sum())
    assert travel_rad > 7e4 and abs(rise_J - X * travel_rad) <= bound_J
    assert pre.fuel_g[0] > base.fuel_g[0] and pre.diff_efficiency[0] < base.diff_efficiency[0]


def test_inertia_stores_and_returns_exactly_what_J_dw_dt_says():
    J = 0.5
    base = simulate([CAMRY], UDDS, mode="direct", trace=True)
    ine = simulate([CAMRY], UDDS, mode="direct", trace=True, effects=f"inertia:J_kg_m2={J}")
    w, alpha, dt, driving, _, moving = _pinion(base.trace)
    extra = ine.trace.diff_input_torque_Nm[0] - base.trace.diff_input_torque_Nm[0]
    np.testing.assert_allclose(extra, J * alpha, rtol=0, atol=1e-9)
    accel = trace_kinematics(base.trace).accel[0]
    # torque only while the pinion speeds up (+) or slows down (-); none cruising or at rest
    assert np.array_equal(extra > 0, moving & (accel > 0)) and np.array_equal(extra < 0, moving & (accel < 0))
    assert np.all(extra[~moving | (accel == 0)] == 0)
    # its work telescopes to 1/2 J (w_end^2 - w_start^2) (step speed = mean of the ends, G fixed):
    # zero over UDDS, which starts and ends at rest, to rounding of the 1.5e5 J moved each way
    work = extra * w * dt
    assert UDDS.speed_mps[0] == UDDS.speed_mps[-1] == 0.0
    assert abs(work.sum()) < 1e-12 * np.abs(work).sum() and work[work > 0].sum() > 7e4
    # the report's energy counts driving steps only: it rises by what accelerating (and the few
    # decelerating-while-driving) steps store; the brakes take it back later, so fuel rises too
    np.testing.assert_allclose(ine.diff_input_energy_J[0] - base.diff_input_energy_J[0],
                               (J * alpha * w * dt)[driving].sum(), rtol=1e-9)
    assert ine.fuel_g[0] > base.fuel_g[0]


@pytest.mark.parametrize("vehicle_spec", [CAMRY, HD_DUAL], ids=["LD_FWD", "HD_DUAL"])
def test_each_step_meets_efficiency_with_effects(vehicle_spec):
    """The simulation's pinion torque is what the library's definition,
    T_out = G_tot eta(T_in - dT) (T_in - dT), asks for, with the step's channels."""
    ambient = 0.0
    effects = parse_with(ALL_DIFFERENTIAL)
    r = simulate([vehicle_spec], UDDS if vehicle_spec is CAMRY else load_cycle("HD-UDDS"), mode="direct",
                 trace=True, effects=effects, ambient_temp_C=ambient)
    tr = r.trace
    _, alpha, _, driving, since_start, _ = _pinion(tr)
    t_in = tr.diff_input_torque_Nm[0]
    n = tr.diff_input_speed_rpm[0]
    low = tr.axle_range[0] == "low"
    kim = vehicle_spec.kim_torque_scale_Nm
    checked = 0
    for axle_gear in ("high", "low"):
        sel = driving & (t_in > 0) & (low == (axle_gear == "low"))
        if not sel.any():
            continue
        eta = efficiency_with_effects(
            vehicle_spec.configuration, t_in[sel] / kim, n[sel], vehicle_spec.final_drive_ratio, effects,
            kim_torque_scale_Nm=kim, low_gear_ratio=vehicle_spec.low_gear_ratio, axle_gear=axle_gear,
            oil_temp_C=ambient + 50.0,
            channels={"input_accel_rad_s2": alpha[sel], "time_s": since_start[sel], "ambient_temp_C": ambient})
        ratio = vehicle_spec.final_drive_ratio * (vehicle_spec.low_gear_ratio if axle_gear == "low" else 1.0)
        # direct inversion to 1e-10 of the Kim scale
        np.testing.assert_allclose(eta * t_in[sel] * ratio, tr.wheel_torque_Nm[0][sel],
                                   rtol=0, atol=1e-8 * kim * ratio)
        checked += int(sel.sum())
    assert checked > 300
    if vehicle_spec is HD_DUAL:
        assert low[driving].any() and (~low[driving]).any()


@pytest.mark.parametrize("cycle", ["UDDS", "US06"])
def test_maps_with_effects_agree_with_direct_within_0p2_percent(cycle, tmp_path):
    """The maps hold the thesis chain only and the effects act per step on top, in every mode:
    cycle fuel within 0.2 % of direct (the requirement of the modes, CONTRACT.md)."""
    vehicles = read_fleet(FLEET).vehicles + ALL
    cyc = load_cycle(cycle)
    effects = ALL_DIFFERENTIAL + ",warmup,accessory_load:power_kW=0.5"
    direct = simulate(vehicles, cyc, mode="direct", effects=effects, ambient_temp_C=5.0)
    plain = simulate(vehicles, cyc, mode="direct", ambient_temp_C=5.0)
    assert np.all(direct.fuel_g > plain.fuel_g)
    for mode in ("map2d", "map3d"):
        other = simulate(vehicles, cyc, mode=mode, effects=effects, ambient_temp_C=5.0, cache_dir=tmp_path)
        assert other.mode == mode  # effects no longer force the direct mode
        err = other.fuel_g / direct.fuel_g - 1.0
        worst = int(np.argmax(np.abs(err)))
        assert abs(err[worst]) < 0.002, f"{mode} {cycle} {vehicles[worst].vehicle_id}: {err[worst]:+.4%}"
        assert np.allclose(other.diff_efficiency, direct.diff_efficiency, rtol=0.002)


def test_vecto_baseline_gets_the_vehicles_kim_scale(tmp_path):
    """vecto-generic works in absolute torque: every driving step meets its loss map at the
    pinion torque the simulation reports (not at the reference axle's capacity)."""
    from fleetrun.differential.baselines import vecto_generic_output_torque_Nm

    r = simulate([HD_TRUCK], load_cycle("HD-UDDS"), mode="direct", physics="vecto-generic", trace=True)
    tr = r.trace
    G = HD_TRUCK.final_drive_ratio
    sel = trace_kinematics(tr).moving[0] & (tr.wheel_torque_Nm[0] > 0)
    t_out = vecto_generic_output_torque_Nm(tr.diff_input_torque_Nm[0][sel],
                                           tr.diff_input_speed_rpm[0][sel] / G, G)
    np.testing.assert_allclose(t_out, tr.wheel_torque_Nm[0][sel], rtol=0, atol=1e-8 * HD_TRUCK.kim_torque_scale_Nm * G)
    for mode in ("map2d", "map3d"):
        other = simulate([HD_TRUCK], load_cycle("HD-UDDS"), mode=mode, physics="vecto-generic", cache_dir=tmp_path)
        assert other.fuel_g[0] == pytest.approx(r.fuel_g[0], rel=0.002)


# ----------------------------------------------------------------------------- vehicle level
def test_warmup_raises_fuel_only_in_the_first_minutes():
    a_g_s, tau_s = 0.3, 200.0
    base = simulate([CAMRY], UDDS, mode="direct", trace=True)
    warm = simulate([CAMRY], UDDS, mode="direct", trace=True,
                    effects=f"warmup:extra_fuel_g_per_s={a_g_s}:tau_s={tau_s}")
    _, _, dt, _, since_start, _ = _pinion(base.trace)
    t = base.trace.time_s[0]
    extra = warm.trace.fuel_rate_g_per_s[0] - base.trace.fuel_rate_g_per_s[0]
    # a exp(-t/tau) wherever the engine burns fuel; nothing during deceleration fuel cut-off
    cut = base.trace.fuel_rate_g_per_s[0] == 0
    assert cut.sum() > 100
    np.testing.assert_allclose(extra[~cut], a_g_s * np.exp(-since_start[~cut] / tau_s), rtol=1e-9, atol=1e-12)
    assert np.all(extra[cut] == 0)
    extra_g = extra * dt
    # 95 % of it within the first 10 minutes (1 - exp(-3) for a fuelled engine); after 5 tau
    # the rate is below a exp(-5) = 0.7 % of its start
    assert extra_g[t <= 600].sum() > 0.95 * extra_g.sum()
    assert extra[t > 5 * tau_s].max() < a_g_s * np.exp(-5)
    # without a trace the standstill steps are not simulated but still get their extra fuel
    quick = simulate([CAMRY], UDDS, mode="direct", effects=f"warmup:extra_fuel_g_per_s={a_g_s}:tau_s={tau_s}")
    assert quick.fuel_g[0] == pytest.approx(warm.fuel_g[0], rel=1e-12)
    assert warm.fuel_g[0] - base.fuel_g[0] == pytest.approx(extra_g.sum(), rel=1e-9)
    assert warm.diff_input_energy_J[0] == base.diff_input_energy_J[0]   # fuel only


# ----------------------------------------------------------------------------- command line
def _cli(*args):
    return CliRunner().invoke(cli, [*map(str, args)], catch_exceptions=False)


def _one_error_line(result, *words):
    assert result.exit_code == 1, result.output
    err = result.stderr.strip()
    assert err.startswith("Error:") and len(err.splitlines()) == 1 and "Traceback" not in result.output, err
    for word in words:
        assert word in err, err


def test_simulate_with_records_effects_in_the_json_line():
    r = _cli("simulate", FLEET, "--vehicle", "LD-CAMRY-25", "--cycle", "UDDS", "--mode", "direct",
             "--with", "bearing_preload:drag_torque_Nm=3,warmup")
    assert r.exit_code == 0, r.output
    line = json.loads(r.stdout)
    assert line["with"] == [
        {"effect": "bearing_preload", "level": "differential", "parameters": {"drag_torque_Nm": 3.0}},
        {"effect": "warmup", "level": "vehicle", "parameters": {"extra_fuel_g_per_s": 0.3, "tau_s": 200.0}}]
    plain = json.loads(_cli("simulate", FLEET, "--vehicle", "LD-CAMRY-25", "--cycle", "UDDS", "--mode",
                            "direct").stdout)
    assert plain["with"] == [] and line["fuel_g"] > plain["fuel_g"]


def test_unknown_effect_exits_1_listing_valid_names(tmp_path):
    valid = ("accessory_load", "bearing_drag", "bearing_preload", "cornering", "inertia", "mixed_lubrication",
             "oil_warmup", "road_grade", "warmup")
    _one_error_line(_cli("simulate", FLEET, "--vehicle", "LD-CAMRY-25", "--cycle", "UDDS", "--with", "bearing_prelaod"),
                    "unknown effect 'bearing_prelaod'", "did you mean 'bearing_preload'", *valid)
    out = tmp_path / "out"
    _one_error_line(_cli("run", FLEET, "--out", out, "-q", "--with", "inertia,warmpu"),
                    "unknown effect 'warmpu'", "did you mean 'warmup'", *valid)
    assert not out.exists()
    _one_error_line(_cli("simulate", FLEET, "--vehicle", "LD-CAMRY-25", "--cycle", "UDDS",
                         "--with", "inertia:J=1"), "unknown parameter of inertia 'J'", "J_kg_m2")


@pytest.fixture(scope="module")
def small_fleet_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("fleet") / "fleet.xlsx"
    return write_fleet(path, [vehicle("CAR-1"), vehicle("CAR-2", configuration="LD_RWD", test_weight_kg=1800)],
                       [scenario("baseline", cycle_mix="UDDS:0.6,HWFET:0.4")])


def test_run_with_changes_results_and_the_manifest_lists_it(small_fleet_path, tmp_path):
    cache = tmp_path / "cache"
    plain, with_ = tmp_path / "plain", tmp_path / "with"
    assert _cli("run", small_fleet_path, "--out", plain, "--cache-dir", cache, "-q").exit_code == 0
    r = _cli("run", small_fleet_path, "--out", with_, "--cache-dir", cache, "-q",
             "--with", "bearing_preload:drag_torque_Nm=4,accessory_load")
    assert r.exit_code == 0, r.output
    before, after = read_csv(plain / "results.csv"), read_csv(with_ / "results.csv")
    assert np.all(after.fuel_gal_total > before.fuel_gal_total)
    assert np.all(after.diff_efficiency < before.diff_efficiency)
    assert np.array_equal(after.miles_total, before.miles_total)
    manifest = json.loads((with_ / "manifest.json").read_text())
    assert manifest["physics"] == "thesis" and manifest["with"] == [
        {"effect": "bearing_preload", "level": "differential", "parameters": {"drag_torque_Nm": 4.0}},
        {"effect": "accessory_load", "level": "vehicle", "parameters": {"power_kW": 1.0}}]
    assert json.loads((plain / "manifest.json").read_text())["with"] == []
    # the manager's summary and the workbook's RunInfo say which physics was added
    label = "thesis with bearing_preload (drag_torque_Nm=4); accessory_load (power_kW=1)"
    assert label in (with_ / "summary.html").read_text()
    assert "thesis with" not in (plain / "summary.html").read_text()
    import openpyxl

    run_info = {r[0]: r[1] for r in openpyxl.load_workbook(with_ / "report.xlsx")["RunInfo"].iter_rows(values_only=True)}
    assert run_info["with (effects)"] == label
    # the batch config's `with` key gives the same numbers
    config = tmp_path / "batch.toml"
    config.write_text(f'inputs = ["{small_fleet_path.as_posix()}"]\nout = "batch"\ncache_dir = "{cache.as_posix()}"\n'
                      'with = ["bearing_preload:drag_torque_Nm=4", "accessory_load"]\n')
    assert _cli("run", "--config", config, "-q").exit_code == 0
    batch = read_csv(tmp_path / "batch" / small_fleet_path.stem / "results.csv")
    assert np.array_equal(batch.fuel_gal_total, after.fuel_gal_total)
    config.write_text(f'inputs = ["{small_fleet_path.as_posix()}"]\nwith = "oil_warmpu"\n')
    _one_error_line(_cli("run", "--config", config, "-q"), "batch.toml", "did you mean 'oil_warmup'")
