"""Drive-cycle simulation: component physics against hand-computed values, energy balance,
shortfall, two-speed axle rule and input errors (issue 3)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fleetrun.cycles import DriveCycle, load_cycle
from fleetrun.errors import InputError
from fleetrun.simulation import TRACE_COLUMNS, simulate
from fleetrun.simulation.core import trace_kinematics
from fleetrun.simulation.engine import (fuel_coefficients, fuel_power_terms_W, fuel_rate_g_per_s, full_load_torque_Nm,
                                        motoring_torque_Nm, stroke_m)
from fleetrun.simulation.params import vehicle_arrays
from fleetrun.simulation.road_load import coastdown_to_si, road_load_N, tractive_force_N
from fleetrun.simulation.transmission import (converter_speed_ratio, converter_unlocked, cvt_ratio, input_torque_Nm,
                                              spin_loss_Nm, torque_ratio)
from fleetrun.simulation.tyre import rolling_radius_m, tire_diameter_m
from fleetrun.testing.vehicles import ALL, CAMRY, CIVIC, F150, HD_DUAL

DOCUMENTED_TRACE = ("time_s", "vehicle_speed_mps", "wheel_torque_Nm", "diff_input_torque_Nm",
                  "diff_input_speed_rpm", "diff_efficiency", "gear", "engine_speed_rpm",
                  "engine_torque_Nm", "fuel_rate_g_per_s")


# ----------------------------------------------------------------------------- components
@pytest.mark.parametrize("size, mm", [
    ("P235/75R15", 15 * 25.4 + 2 * 235 * 0.75),      # thesis Table 7.1, F-150
    ("195/65VR16", 16 * 25.4 + 2 * 195 * 0.65),      # speed-rated code (300E)
    ("P175/70R13", 13 * 25.4 + 2 * 175 * 0.70),      # Civic
    ("225/45ZR17 94W", 17 * 25.4 + 2 * 225 * 0.45),  # load index / speed symbol after the size
    ("LT245/75R16", 16 * 25.4 + 2 * 245 * 0.75),
    ("295/75R22.5", 22.5 * 25.4 + 2 * 295 * 0.75),
    ("31x10.50R15", 31 * 25.4),                      # flotation: diameter in inches
    ("11R22.5", (22.5 + 2 * 11 * 0.88) * 25.4),      # inch truck size, 88 % section height
])
def test_tyre_diameter_from_size_code(size, mm):
    # exact arithmetic of the size code (ISO 4000 / TRA): 1e-12 relative
    assert tire_diameter_m(size) == pytest.approx(mm / 1000, rel=1e-12)
    assert rolling_radius_m(size) == pytest.approx(mm / 2000, rel=1e-12)  # thesis 7.2.1: half the diameter


@pytest.mark.parametrize("bad", ["banana", "", "235/75", "P235/75X15x"])
def test_tyre_size_that_does_not_parse(bad):
    with pytest.raises(InputError, match="does not parse"):
        tire_diameter_m(bad)


def test_road_load_conversion_hand_computed():
    # A=30 lbf, B=0.5 lbf/mph, C=0.02 lbf/mph^2 at 50 mph: 30 + 25 + 50 = 105 lbf = 467.063 N
    A, B, C = coastdown_to_si(30.0, 0.5, 0.02)
    assert road_load_N(50 * 0.44704, A, B, C) == pytest.approx(105 * 4.4482216152605, rel=1e-12)
    assert road_load_N(0.0, A, B, C) == 0.0  # nothing rolls at standstill
    # 5 % grade, 1000 kg, 1.5 % rotating mass, 1 m/s^2, at rest: m(1+f)a + m g sin(atan 0.05)
    F = tractive_force_N(0.0, 1.0, 5.0, 1000.0, 0.015, A, B, C)
    assert F == pytest.approx(1015.0 + 1000 * 9.80665 * 0.05 / np.sqrt(1 + 0.05**2), rel=1e-12)


def test_fuel_equation_hand_computed():
    # engine.py: m_dot LHV = [P_b (1 + k L) + (f0 + fcm c_m + fpk bmep_max + pth (1 - L)) V_d w / 4pi
    #                         + P_acc + k_tr P_inertia+] / eta, written out by hand for one point:
    # 100 N m of 200 N m full load at 2000 rpm, 2.0 L in 4 square cylinders, T_peak 250 N m
    S = stroke_m(2.0, 4)
    assert np.pi / 4 * S**3 * 4 == pytest.approx(2.0e-3, rel=1e-12)          # V_d = 4 x pi/4 B^2 S, B = S
    w = 2000 * 2 * np.pi / 60
    cm = 2 * S * 2000 / 60
    consts = dict(eta_indicated=0.4, high_load_factor=0.2, fmep_0_kPa=50.0, fmep_piston_speed_kPa_s_per_m=5.0,
                  fmep_peak_fraction=0.05, pmep_throttle_kPa=80.0, accessory_power_W=300.0, transient_factor=0.7)
    terms = fuel_power_terms_W(100.0, 2000.0, 200.0, 2.0, S, 250.0, True, 5000.0)
    rate = fuel_rate_g_per_s(terms, fuel_coefficients(*consts.values()), True, 42.9)
    mep_W = 2.0e-3 * w / (4 * np.pi) * 1e3                                    # W per kPa
    by_hand = (100 * w * (1 + 0.2 * 0.5) + (50 + 5 * cm + 80 * 0.5) * mep_W + 0.05 * 250 * w + 300 + 0.7 * 5000) / 0.4
    assert rate == pytest.approx(by_hand / 42.9e3, rel=1e-12)
    # diesel (unthrottled): no pumping term; fuel cut-off: nothing
    terms_d = fuel_power_terms_W(100.0, 2000.0, 200.0, 2.0, S, 250.0, False, 5000.0)
    assert fuel_rate_g_per_s(terms_d, fuel_coefficients(*consts.values()), True, 42.9) == pytest.approx(
        (by_hand - 80 * 0.5 * mep_W / 0.4) / 42.9e3, rel=1e-12)
    assert fuel_rate_g_per_s(terms, fuel_coefficients(*consts.values()), False, 42.9) == 0.0
    # motoring torque: friction + closed-throttle pumping
    T_m = motoring_torque_Nm(2000.0, 2.0, S, 250.0, 50.0, 5.0, 0.05, 80.0, True)
    assert T_m == pytest.approx((50 + 5 * cm + 80) * 1e3 * 2e-3 / (4 * np.pi) + 0.05 * 250, rel=1e-12)


def test_full_load_curve_shape():
    n = np.array([700.0, 4200.0, 6000.0, 6600.0])
    T = full_load_torque_Nm(n, 250.0, 140.0, 6000.0, 700.0, 4200.0, 0.7)
    assert T[0] == pytest.approx(0.7 * 250)                      # idle: 70 % of peak
    assert T[1] == pytest.approx(250.0)                          # peak-torque speed
    assert T[2] == pytest.approx(140e3 / (6000 * 2 * np.pi / 60))  # rated power cap
    assert T[3] == pytest.approx(0.0, abs=1e-9)                  # governor 10 % above rated


def test_converter_closed_form_solves_its_equation():
    # the speed ratio must satisfy TR(SR) (n_t / (SR K))^2 = T_t in both ranges
    nt = np.array([100.0, 800.0, 1500.0, 2500.0])
    Tt = np.array([400.0, 300.0, 100.0, 50.0])
    K, TRs = 2200 / np.sqrt(250.0), 2.0
    sr = converter_speed_ratio(nt, Tt, K, TRs)
    unclipped = sr < 0.98
    lhs = torque_ratio(sr, TRs) * (nt / (sr * K)) ** 2
    assert np.allclose(lhs[unclipped], Tt[unclipped], rtol=1e-10)
    assert torque_ratio(0.0, TRs) == TRs and torque_ratio(0.9, TRs) == 1.0


def test_gearbox_loss_same_magnitude_on_overrun():
    drive = input_torque_Nm(100.0, 2.0, 0.95)
    overrun = input_torque_Nm(-100.0, 2.0, 0.95)
    assert drive == pytest.approx(100 / (2 * 0.95))
    assert drive - 50.0 == pytest.approx(overrun + 50.0)  # same loss, either direction
    # the spin loss drags in either direction: a + b n / 1000, none at standstill
    spin = spin_loss_Nm(np.array([0.0, 2000.0]), 2.0, 1.0)
    assert list(spin) == [0.0, 4.0]
    assert input_torque_Nm(-100.0, 2.0, 0.95, 4.0) == pytest.approx(overrun + 4.0)


def test_cvt_meets_the_schedule_within_its_range():
    r = cvt_ratio(np.array([0.0, 500.0, 1000.0, 4000.0]), 1500.0, 2.6, 0.4)
    np.testing.assert_allclose(r, [2.6, 2.6, 1.5, 0.4])


def test_converter_without_lockup_clutch_never_locks():
    first = np.array([True, False, False])
    n = np.array([3000.0, 3000.0, 800.0])
    assert list(converter_unlocked(first, n, 1200.0, True)) == [True, False, True]
    assert list(converter_unlocked(first, n, 1200.0, False)) == [True, True, True]


# ----------------------------------------------------------------------------- whole cycle
@pytest.fixture(scope="module")
def udds_traces():
    return simulate(ALL, load_cycle("UDDS"), mode="direct", trace=True)


def test_trace_has_contract_columns(udds_traces):
    frame = udds_traces.trace_frame(0)
    assert list(frame.columns[:len(DOCUMENTED_TRACE)]) == list(DOCUMENTED_TRACE)
    assert set(DOCUMENTED_TRACE) <= set(TRACE_COLUMNS)
    assert len(frame) == load_cycle("UDDS").time_s.size


def test_energy_balance_per_step(udds_traces):
    """Engine output = losses + wheel work in every driving step, each loss from its own model."""
    tr = udds_traces.trace
    va = vehicle_arrays(ALL)
    driving = trace_kinematics(tr).moving & (tr.wheel_torque_Nm > 0)
    lhs = tr.engine_power_W[driving]
    rhs = (tr.wheel_power_W + tr.diff_loss_W + tr.transmission_loss_W + tr.converter_loss_W)[driving]
    # pure bookkeeping of the same floats: 1e-9 relative
    np.testing.assert_allclose(lhs, rhs, rtol=1e-9)
    # differential loss from the reported efficiency: P_in - P_out = P_out (1/eta - 1)
    eta = tr.diff_efficiency[driving]
    np.testing.assert_allclose(tr.diff_loss_W[driving], tr.wheel_power_W[driving] * (1 / eta - 1),
                               rtol=1e-9, atol=1e-6)
    # gearbox loss from the mesh efficiency of the gear in use plus the spin loss a + b n / 1000
    rows = np.broadcast_to(np.arange(va.n)[:, None], driving.shape)[driving]
    P_d = tr.diff_input_torque_Nm[driving] * tr.diff_input_speed_rpm[driving] * 2 * np.pi / 60
    gear = tr.gear[driving]
    eff = np.array([va.combo_gear_eff[r][np.flatnonzero(va.combo_gear[r] == g)[0]] for r, g in zip(rows, gear)])
    n_in = tr.transmission_input_speed_rpm[driving]
    spin_W = (va.spin_loss[rows, 0] + va.spin_loss[rows, 1] * n_in / 1000) * n_in * 2 * np.pi / 60
    np.testing.assert_allclose(tr.transmission_loss_W[driving], P_d * (1 / eff - 1) + spin_W, rtol=1e-9, atol=1e-6)
    # locked converter / engaged clutch: no slip loss; slipping: never a gain
    locked = driving & ~tr.converter_unlocked & (tr.engine_speed_rpm == tr.transmission_input_speed_rpm)
    assert np.all(np.abs(tr.converter_loss_W[locked]) < 1e-6)
    assert np.all(tr.converter_loss_W[driving] > -1e-6)


def test_wheel_work_equals_road_load_work(udds_traces):
    """Over a level cycle from rest to rest, wheel work = road-load work exactly: the inertia
    term telescopes, sum m (v_i - v_(i-1)) (v_i + v_(i-1)) / 2 = 0 (trapezoidal steps)."""
    tr = udds_traces.trace
    va = vehicle_arrays(ALL)
    k = trace_kinematics(tr)
    v, dt = k.v_avg, k.dt
    wheel = (tr.wheel_power_W * dt).sum(axis=1)
    road = (road_load_N(v, va.A_N[:, None], va.B_N[:, None], va.C_N[:, None]) * v * dt).sum(axis=1)
    followed = udds_traces.shortfall_distance_m < 1e-9
    assert followed[:4].all()
    np.testing.assert_allclose(wheel[followed], road[followed], rtol=1e-9)


def test_results_consistent(udds_traces):
    r = udds_traces
    assert np.allclose(r.miles[:4], load_cycle("UDDS").miles, rtol=1e-12)
    assert np.allclose(r.mpg, r.miles / r.fuel_gal)
    assert np.all((r.diff_efficiency > 0.8) & (r.diff_efficiency < 1.0))
    assert np.all(r.drivetrain_efficiency < r.diff_efficiency)
    # plausible city fuel economy (EPA unadjusted city values of such cars: 15-50 mpg)
    assert 15 < r.mpg[0] < 30 and 25 < r.mpg[1] < 50 and 30 < r.mpg[2] < 60


def test_energies_add_over_cycles():
    a = simulate([CAMRY], load_cycle("UDDS"), mode="direct")
    b = simulate([CAMRY], load_cycle("HWFET"), mode="direct")
    joined = simulate([CAMRY], DriveCycle("both", np.r_[load_cycle("UDDS").time_s, load_cycle("HWFET").time_s + 2000],
                                          np.r_[load_cycle("UDDS").speed_mps, load_cycle("HWFET").speed_mps],
                                          np.zeros(load_cycle("UDDS").time_s.size + load_cycle("HWFET").time_s.size)),
                      mode="direct")
    # the 2000 s gap between the cycles is idling: only the fuel differs, by idle fuel
    for name in ("wheel_energy_J", "diff_input_energy_J", "diff_output_energy_J", "drivetrain_input_energy_J"):
        assert getattr(joined, name)[0] == pytest.approx(getattr(a, name)[0] + getattr(b, name)[0], rel=1e-9)


def test_idle_fuel_override_and_standstill():
    cyc = DriveCycle("idle", np.arange(0.0, 61.0), np.zeros(61), np.zeros(61))
    r = simulate([dataclasses.replace(CAMRY, extra={"idle_fuel_g_per_s": 0.25})], cyc, mode="direct", trace=True)
    assert r.fuel_g[0] == pytest.approx(0.25 * 60)
    assert r.miles[0] == 0 and r.mpg[0] == 0
    assert np.all(r.trace.gear == 0) and np.all(r.trace.diff_efficiency == 0)


def test_deceleration_fuel_cut():
    r = simulate([CIVIC], load_cycle("UDDS"), mode="direct", trace=True)
    tr = r.trace
    overrun = (tr.engine_torque_Nm[0] < 0) & (tr.engine_speed_rpm[0] > 1100)
    assert overrun.sum() > 50
    assert np.all(tr.fuel_rate_g_per_s[0][overrun] == 0)


def test_vehicle_that_cannot_follow_reports_shortfall():
    weak = dataclasses.replace(CIVIC, vehicle_id="weak", peak_engine_torque_Nm=60.0, rated_power_kW=20.0)
    r = simulate([weak, CIVIC], load_cycle("US06"), mode="direct", trace=True)
    target = r.trace.target_speed_mps
    achieved = r.trace.vehicle_speed_mps
    assert r.shortfall_time_s[0] > 100 and r.shortfall_distance_m[0] > 500
    assert r.shortfall_time_s[1] == 0 and r.shortfall_distance_m[1] == pytest.approx(0, abs=1e-9)
    assert np.all(achieved[0] <= target + 1e-12)      # never ahead of the trace
    assert r.miles[0] < r.miles[1]
    # it follows as closely as it can: full load in most steps where it is behind
    behind = r.trace.not_followed[0] & (achieved[0] > 1)
    at_full = r.trace.engine_torque_Nm[0] > 0.8 * r.trace.engine_max_torque_Nm[0]
    assert at_full[behind].mean() > 0.6


def test_dual_axle_uses_low_range_only_when_high_lugs():
    r = simulate([HD_DUAL], load_cycle("HWFET"), mode="direct", trace=True)
    tr = r.trace
    low = (tr.axle_range[0] == "low") & (tr.vehicle_speed_mps[0] > 0)
    high = (tr.axle_range[0] == "high") & (tr.vehicle_speed_mps[0] > 0)
    assert low.any() and high.any()
    # cruise at highway speed is in the high range (fuel economy, thesis Sec. 2.2.6)
    assert np.all(tr.axle_range[0][tr.vehicle_speed_mps[0] > 25] == "high")
    # low range multiplies the diff input speed by the low ratio relative to the high one
    with np.errstate(invalid="ignore"):
        ratio = tr.diff_input_speed_rpm[0] / tr.wheel_speed_rpm[0]
    assert np.allclose(ratio[low], HD_DUAL.final_drive_ratio * HD_DUAL.low_gear_ratio)
    assert np.allclose(ratio[high], HD_DUAL.final_drive_ratio)


def test_ambient_temperature_reaches_the_differential():
    cold = simulate([F150], load_cycle("UDDS"), mode="direct", ambient_temp_C=-10.0)
    warm = simulate([F150], load_cycle("UDDS"), mode="direct", ambient_temp_C=20.0)
    # colder (thicker) oil, lower efficiency: the thesis model's viscosity terms
    assert cold.diff_efficiency[0] < warm.diff_efficiency[0]


@pytest.mark.parametrize("change, message", [
    (dict(transmission_gear_ratios=()), "transmission_gear_ratios is empty"),
    (dict(tire_size="big"), "tire size 'big' does not parse"),
    (dict(final_drive_ratio=0.0), "final_drive_ratio must be a positive number"),
])
def test_bad_vehicle(change, message):
    with pytest.raises(InputError, match=message):
        simulate([dataclasses.replace(CAMRY, **change)], load_cycle("UDDS"))


def test_bad_cycle_arrays():
    with pytest.raises(InputError, match="not strictly increasing"):
        simulate([CAMRY], DriveCycle("x", [0, 1, 1, 2], [0, 1, 1, 0], [0, 0, 0, 0]))
    with pytest.raises(InputError, match="negative speed"):
        simulate([CAMRY], DriveCycle("x", [0, 1, 2], [0, -1, 0], [0, 0, 0]))
    with pytest.raises(InputError, match="unknown mode"):
        simulate([CAMRY], load_cycle("UDDS"), mode="fast")


def test_empty_fleet():
    r = simulate([], load_cycle("UDDS"))
    assert r.miles.shape == (0,)


@pytest.mark.parametrize("cycle", ["UDDS", "US06"])
def test_trace_and_summary_paths_agree(cycle):
    # without a trace, standstill steps are skipped and charged idle fuel: same numbers
    weak = dataclasses.replace(CIVIC, vehicle_id="weak", peak_engine_torque_Nm=80.0, rated_power_kW=30.0)
    vehicles = ALL + [weak, dataclasses.replace(CAMRY, vehicle_id="idle-given", extra={"idle_fuel_g_per_s": 0.3})]
    a = simulate(vehicles, load_cycle(cycle), mode="map3d", trace=True)
    b = simulate(vehicles, load_cycle(cycle), mode="map3d", trace=False)
    for name in ("fuel_g", "miles", "wheel_energy_J", "diff_input_energy_J", "drivetrain_input_energy_J",
                 "shortfall_time_s", "shortfall_distance_m", "shortfall_steps"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-12, atol=1e-9, err_msg=name)


def _plain_redrive_loop(va, cyc, margin):
    """The re-drive as docs/simulation.md states it, one step after the other for each
    vehicle on Python floats: v(i) = min(trace(i), v(i-1) + a dt) clipped at 0, a from the
    force table at the step's mean speed (one predictor-corrector pass)."""
    from fleetrun.simulation import core
    from fleetrun.simulation.road_load import coastdown_force_N, grade_force_N

    table = core.max_tractive_force_table(va, 1.0) * margin
    dv = float(core.REDRIVE_SPEED_GRID[1] - core.REDRIVE_SPEED_GRID[0])
    top = core.REDRIVE_SPEED_GRID.size - 1 - 1e-9
    t, cap, g = (np.asarray(x, float).tolist() for x in (cyc.time_s, cyc.speed_mps, cyc.grade_pct))
    out = np.empty((va.n, len(t)))
    for k in range(va.n):
        inv_m = 1.0 / float(va.mass_kg[k] * (1.0 + va.rot_frac[k]))
        f = table[k].tolist()

        def accel(v, i):
            x = min(v / dv, top)
            j = int(x)
            w = x - j
            force = f[j] * (1.0 - w) + f[j + 1] * w
            grade = float(grade_force_N(va.mass_kg[k], 0.5 * (g[i] + g[i - 1])))
            coast = coastdown_force_N(max(v, 1e-3), float(va.A_N[k]), float(va.B_N[k]), float(va.C_N[k]))
            return (force - coast - grade) * inv_m

        v = out[k, 0] = cap[0]
        for i in range(1, len(t)):
            dt = t[i] - t[i - 1]
            guess = max(min(cap[i], v + accel(v, i) * dt), 0.0)
            v = out[k, i] = max(min(cap[i], v + accel(0.5 * (v + guess), i) * dt), 0.0)
    return out


def test_redrive_is_the_plain_step_loop_bit_for_bit():
    # forward_redrive computes every step from the trace for all vehicles at once and walks
    # only the steps a vehicle starts behind: it must give the plain loop's speeds exactly
    # (the same IEEE operations), for a fleet and for each vehicle alone
    from fleetrun.simulation import core
    from fleetrun.simulation.params import vehicle_arrays as arrays

    weak = [dataclasses.replace(CIVIC, vehicle_id=f"w{i}", peak_engine_torque_Nm=60.0 + 10 * i, rated_power_kW=20.0 + 5 * i)
            for i in range(6)]
    va = arrays(weak + [CAMRY])
    us06 = load_cycle("US06")
    # and on grades (up and down, a level stretch) from a moving start: the steps the trace does
    # not speed up are not computed for vehicles that accelerate everywhere (core._trial_speeds)
    n = us06.time_s.size
    graded = DriveCycle("graded", us06.time_s, np.maximum(us06.speed_mps, 8.0),
                        np.where(np.arange(n) % 300 < 100, 0.0, 10.0 * np.sin(np.arange(n) / 40.0)))
    for cyc in (us06, graded):
        vector = core.forward_redrive(va, cyc.time_s, cyc.speed_mps, cyc.grade_pct, 0.9)
        alone = np.vstack([core.forward_redrive(va.subset([i]), cyc.time_s, cyc.speed_mps, cyc.grade_pct, 0.9)
                           for i in range(va.n)])
        plain = _plain_redrive_loop(va, cyc, 0.9)
        assert (vector < cyc.speed_mps - 1.0).any(axis=1)[:6].all()    # the weak cars fall behind
        np.testing.assert_array_equal(vector, plain)
        np.testing.assert_array_equal(alone, plain)


@pytest.mark.parametrize("variant", ["numpy_bounds", "grid_below_the_trace", "grid_step_not_a_power_of_two"])
def test_redrive_paths_of_the_step_walk_are_the_plain_step_loop_bit_for_bit(monkeypatch, variant):
    # the walk (core._stepper, core._lanes, core._bounds) takes other paths when an input is
    # not a plain number (numpy's minimum / maximum instead of fmin / fmax / clip), when the
    # trace passes the force table's top speed (the cell position clipped) and when the grid
    # step is not a power of two (v / dv divided, not multiplied): each must still give the
    # plain loop's speeds exactly
    from fleetrun.simulation import core
    from fleetrun.simulation.params import vehicle_arrays as arrays

    if variant == "numpy_bounds":
        monkeypatch.setattr(core, "_plain_numbers", lambda *a: False)
    elif variant == "grid_below_the_trace":    # US06 reaches 35.9 m/s
        monkeypatch.setattr(core, "REDRIVE_SPEED_GRID", np.linspace(0.0, 30.0, 121))
    else:
        monkeypatch.setattr(core, "REDRIVE_SPEED_GRID", np.linspace(0.0, 70.0, 301))
    weak = [dataclasses.replace(CIVIC, vehicle_id=f"w{i}", peak_engine_torque_Nm=60.0 + 10 * i, rated_power_kW=20.0 + 5 * i)
            for i in range(6)]
    va = arrays(weak + [CAMRY])
    cyc = load_cycle("US06")
    n = cyc.time_s.size
    graded = DriveCycle("graded", cyc.time_s, cyc.speed_mps, np.where(np.arange(n) % 300 < 100, 0.0, 4.0))
    for c in (cyc, graded):
        vector = core.forward_redrive(va, c.time_s, c.speed_mps, c.grade_pct, 0.9)
        assert (vector < c.speed_mps - 1.0).any(axis=1)[:6].all()    # the weak cars fall behind
        np.testing.assert_array_equal(vector, _plain_redrive_loop(va, c, 0.9))


def test_a_vehicles_results_do_not_depend_on_who_falls_behind_with_it():
    # vehicles that fall behind are not summed before the re-drive (their fuel would be
    # replaced): a block of them not at all, on the trace those above full load in one of the
    # hardest steps not, the car beside them in a part of its block. Either way each
    # vehicle's figures are the same, bit for bit (the same element-wise arithmetic)
    weak = [dataclasses.replace(CIVIC, vehicle_id=f"w{i}", peak_engine_torque_Nm=50.0 + 5 * i, rated_power_kW=15.0 + 2 * i)
            for i in range(4)]
    for cycle in ("US06", "FTP"):
        alone = simulate(weak, cycle)
        together = simulate(weak + [CAMRY], cycle)
        assert (alone.shortfall_time_s > 0).all()
        for name in ("fuel_g", "miles", "mpg", "wheel_energy_J", "drivetrain_input_energy_J", "shortfall_time_s",
                     "shortfall_steps"):
            a, b = getattr(alone, name), getattr(together, name)[:4]
            assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), (cycle, name)
            # the car that follows, simulated without them beside one that follows too
            a, b = getattr(simulate([CAMRY, F150], cycle), name)[:1], getattr(together, name)[4:]
            assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), (cycle, name)


@pytest.mark.parametrize("trace", [False, True])
def test_vehicles_above_full_load_at_the_start_skip_to_the_last_round_bit_for_bit(monkeypatch, trace):
    # a vehicle above full load in the cycle's first two steps (step 0 at the trace's first
    # speed is the same in every round) stays behind in every round but the last: it is not
    # re-driven before it (simulation/__init__.py, _redrive_until_feasible). Its figures, and
    # those beside it, must be those of re-driving it every round, bit for bit; also where
    # leaving it out would leave the other vehicle behind alone in its block (a block of one
    # sums its steps in another order: then it is re-driven with it)
    import fleetrun.simulation as sim

    weak = dataclasses.replace(CIVIC, vehicle_id="weak", peak_engine_torque_Nm=40.0, rated_power_kW=8.0)
    speed = np.r_[np.full(30, 30.0), np.linspace(30.0, 10.0, 20), np.linspace(10.0, 35.0, 12), np.linspace(35.0, 0.0, 59)]
    hill = DriveCycle("hill", np.arange(float(speed.size)), speed, np.full(speed.size, 4.0))
    real = sim.above_full_load_at_start
    for fleet in ([weak, CIVIC], [weak, CIVIC, CAMRY], [weak, F150, CIVIC, CAMRY]):
        calls = []
        monkeypatch.setattr(sim, "above_full_load_at_start", lambda *a: calls.append(r := real(*a)) or r)
        skipped = simulate(fleet, hill, trace=trace)
        # the first call answers for the rounds but the last at once (one row per vehicle and margin)
        first_margin = calls[0].reshape(len(sim.REDRIVE_MARGINS) - 1, -1)[0] if calls else None
        assert calls and first_margin[0] and not first_margin[1:].any()   # the weak car stuck, the others not
        monkeypatch.setattr(sim, "above_full_load_at_start", lambda va, *a: np.zeros(va.n, bool))
        every_round = simulate(fleet, hill, trace=trace)
        assert (every_round.shortfall_time_s[:3] > 0).all()
        for name in ("fuel_g", "miles", "mpg", "wheel_energy_J", "drivetrain_input_energy_J", "shortfall_time_s",
                     "shortfall_steps", "shortfall_distance_m"):
            a, b = getattr(skipped, name), getattr(every_round, name)
            assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), (len(fleet), name)
        if trace:
            for name in TRACE_COLUMNS:
                assert np.array_equal(getattr(skipped.trace, name), getattr(every_round.trace, name)), name


def test_step_sums_of_a_pass_on_own_speeds_add_in_the_gathered_columns_order():
    # a pass over several vehicles' own speeds lays its arrays out row by row; the per-vehicle
    # distance is summed step after step, the order numpy used when the gathered steps'
    # columns laid them out column by column (core.step_sums): the same bits as that layout
    from fleetrun.simulation import core

    rng = np.random.default_rng(7)
    t = np.arange(400.0)
    speed = rng.uniform(0.0, 30.0, (9, t.size))
    columns = np.sort(rng.choice(np.arange(1, t.size), 300, replace=False))   # steps with gaps
    k = core.kinematics(t, speed, np.zeros(t.size), columns)
    assert k.sequential and k.v_avg.flags.c_contiguous
    gathered = 0.5 * (speed[:, columns] + speed[:, columns - 1])              # column by column
    assert not gathered.flags.c_contiguous
    assert core.step_sums(k.v_avg * k.dt, k).tobytes() == (gathered * k.dt).sum(axis=1).tobytes()
    assert not np.array_equal(core.step_sums(k.v_avg * k.dt, k), (k.v_avg * k.dt).sum(axis=1))   # the order matters
    one = core.kinematics(t, speed[:1], np.zeros(t.size), columns)            # one vehicle: numpy's row sum
    assert not one.sequential
