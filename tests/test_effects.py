"""Effects registry, --with parsing and the physics of each effect (docs/effects.md)."""
import numpy as np
import pytest

from fleetrun.effects import EFFECTS, efficiency_with_effects, parse_with
from fleetrun.effects import differential as d
from fleetrun.errors import InputError

DOCUMENTED_IDS = {"bearing_preload", "cornering", "inertia", "oil_warmup", "bearing_drag",
                "mixed_lubrication", "warmup", "road_grade", "accessory_load"}


def test_registry_has_contract_ids_and_fixed_parameters():
    assert DOCUMENTED_IDS <= set(EFFECTS)
    # docs/interface.md fixes these names
    assert [p.name for p in EFFECTS["bearing_preload"].parameters] == ["drag_torque_Nm"]
    assert [p.name for p in EFFECTS["cornering"].parameters] == ["k_c"]
    assert [p.name for p in EFFECTS["inertia"].parameters] == ["J_kg_m2"]
    assert [p.name for p in EFFECTS["oil_warmup"].parameters] == ["c_w_Nm", "tau_s"]
    for e in EFFECTS.values():
        assert e.seed and e.signature and e.steady_state
        for p in e.parameters:
            assert p.lower <= p.default <= p.upper


def test_parse_with_defaults_overrides_and_errors():
    got = parse_with("inertia, cornering:k_c=0.1, oil-warmup:tau_s=300:c_w_Nm=2")
    assert [e.id for e, _ in got] == ["inertia", "cornering", "oil_warmup"]
    assert got[0][1] == {"J_kg_m2": EFFECTS["inertia"].parameter("J_kg_m2").default}
    assert got[1][1] == {"k_c": 0.1}
    assert got[2][1] == {"c_w_Nm": 2.0, "tau_s": 300.0}
    with pytest.raises(InputError, match="did you mean 'cornering'"):
        parse_with("cornerin")
    with pytest.raises(InputError, match="outside"):
        parse_with("cornering:k_c=-1")
    with pytest.raises(InputError, match="parameter of cornering"):
        parse_with("cornering:kc=0.1")
    with pytest.raises(InputError, match="number"):
        parse_with("cornering:k_c=abc")
    assert parse_with("") == [] and parse_with(None) == []


def test_cornering_power_balance():
    # docs/interface.md: P_loss = k_c * T_c * |w_L - w_R|, T_c = G * T_in; dT_in * w_in must equal P_loss
    t_in, w_in, dw, g = 300.0, 200.0, 3.0, 3.55
    dt = 0.2 * d.cornering_extra_torque_Nm(t_in, w_in, dw, g)
    assert dt * w_in == pytest.approx(0.2 * g * t_in * dw)
    assert d.cornering_extra_torque_Nm(t_in, 0.0, dw, g) == 0.0   # stopped: no power balance


def test_greenwood_tripp_and_boundary_share():
    # seed 004 Eq. 17: F2(0) = 0.5; the fit is clipped at 0 where it goes negative
    assert d.greenwood_tripp_F2(0.0) == pytest.approx(0.5)
    assert d.greenwood_tripp_F2(2.5) == 0.0 and d.greenwood_tripp_F2(4.0) == 0.0
    lam = np.linspace(0, 1.9, 50)
    assert np.all(np.diff(d.greenwood_tripp_F2(lam)) <= 1e-12)   # film grows: less asperity area
    w_ref = 300 * 2 * np.pi / 60
    assert d.boundary_share(1e-6, 300.0) == pytest.approx(1.0, abs=1e-3)
    # lambda = 1 at the reference speed: F2(1)/F2(0)
    assert d.boundary_share(w_ref, 300.0) == pytest.approx(d.greenwood_tripp_F2(1.0) / 0.5)


def test_oil_warmup_temperature_and_viscosity():
    # thesis 3.1.2: T_op = T_amb + 50 K; first-order approach from ambient
    assert d.oil_temperature_C(0.0, 10.0, 600.0) == pytest.approx(10.0)
    assert d.oil_temperature_C(1e7, 10.0, 600.0) == pytest.approx(60.0)
    assert d.oil_temperature_C(600.0, 10.0, 600.0) == pytest.approx(60 - 50 * np.exp(-1))
    assert d.warmup_viscosity_excess(60.0, 10.0, "75W90") == pytest.approx(0.0, abs=1e-12)
    # Walther (B.7): 75W90 at 20 C is several times thicker than at 70 C
    assert d.warmup_viscosity_excess(20.0, 20.0, "75W90") > 5


def test_bearing_drag_and_preload_shapes():
    w1000 = 1000 * 2 * np.pi / 60
    assert d.bearing_viscous_drag_Nm(w1000) == pytest.approx(1.0, rel=1e-6)
    assert d.bearing_viscous_drag_Nm(8 * w1000) == pytest.approx(4.0, rel=1e-6)   # n^(2/3)
    assert d.preload_drag_torque_Nm(0.0) == 0.0
    assert d.preload_drag_torque_Nm(100.0) == pytest.approx(1.0)


def test_efficiency_with_effects_steady_state():
    from fleetrun.differential import efficiency

    tf = np.array([0.02, 0.1, 0.5])
    n = 1500.0
    kim = 3600.0
    base = efficiency("LD_RWD", tf, n, 3.55)
    same = efficiency_with_effects("LD_RWD", tf, n, 3.55, None, kim_torque_scale_Nm=kim)
    np.testing.assert_allclose(same, base)
    # inertia and cornering contribute nothing at steady, straight running
    steady = efficiency_with_effects("LD_RWD", tf, n, 3.55, "inertia,cornering", kim_torque_scale_Nm=kim)
    np.testing.assert_allclose(steady, base, rtol=1e-12)
    pre = efficiency_with_effects("LD_RWD", tf, n, 3.55, "bearing_preload:drag_torque_Nm=5",
                                  kim_torque_scale_Nm=kim)
    loss = base - pre
    assert np.all(loss > 0) and loss[0] > loss[1] > loss[2]     # a fixed drag hurts light loads most
    # eta' = eta(T - dT) (T - dT) / T
    t = tf * kim
    expect = efficiency("LD_RWD", (t - 5) / kim, n, 3.55) * (t - 5) / t
    np.testing.assert_allclose(pre, expect, rtol=1e-12)
    cold = efficiency_with_effects("LD_RWD", tf, n, 3.55, "oil_warmup", kim_torque_scale_Nm=kim,
                                   channels={"oil_temp_C": 0.0, "ambient_temp_C": 20.0})
    assert np.all(cold < base)
    warm = efficiency_with_effects("LD_RWD", tf, n, 3.55, "oil_warmup", kim_torque_scale_Nm=kim)
    np.testing.assert_allclose(warm, base, rtol=1e-12)
    turning = efficiency_with_effects("LD_RWD", tf, n, 3.55, "cornering:k_c=0.2", kim_torque_scale_Nm=kim,
                                      channels={"wheel_speed_difference_rad_s": 3.0})
    assert np.all(turning < base)
    # drag larger than the input torque: nothing reaches the wheels (B.6 floor)
    assert efficiency_with_effects("LD_RWD", 0.001, n, 3.55, "bearing_preload:drag_torque_Nm=10",
                                   kim_torque_scale_Nm=kim) == 0.0


def test_vehicle_extra_fuel():
    from fleetrun.effects import vehicle_extra_fuel_g_per_s
    from fleetrun.effects.vehicle import marginal_fuel_g_per_J

    t = np.array([0.0, 100.0, 1e6])
    v = np.array([10.0, 10.0, 10.0])
    eta = 0.5   # any Willans slope: the caller passes the engine's own
    warm = vehicle_extra_fuel_g_per_s("warmup:extra_fuel_g_per_s=1:tau_s=100", time_s=t,
                                      vehicle_speed_mps=v, vehicle_mass_kg=1500, fuel="gasoline", eta_indicated=eta)
    np.testing.assert_allclose(warm, [1.0, np.exp(-1), 0.0], atol=1e-12)
    gpj = marginal_fuel_g_per_J("gasoline", eta)
    # 1 J at the crank at a 50 % Willans slope burns 2 J of gasoline; published gasoline LHVs
    # are 42-44 MJ/kg (E10 to E0)
    assert gpj == pytest.approx(2.0 / 43.0e3, rel=0.025)
    grade = vehicle_extra_fuel_g_per_s("road_grade:grade_pct=2", time_s=t, vehicle_speed_mps=v,
                                       vehicle_mass_kg=1500, fuel="gasoline", eta_indicated=eta,
                                       wheel_power_W=np.array([1.0, -1.0, 1.0]))
    # m g v grade/100 of extra work while driving the wheels, none while braking
    np.testing.assert_allclose(grade, [1500 * 9.80665 * 10 * 0.02 * gpj, 0.0, 1500 * 9.80665 * 10 * 0.02 * gpj])
    acc = vehicle_extra_fuel_g_per_s("accessory_load:power_kW=2", time_s=t, vehicle_speed_mps=v,
                                     vehicle_mass_kg=1500, fuel="gasoline", eta_indicated=eta,
                                     engine_on=np.array([1, 0, 1]))
    np.testing.assert_allclose(acc, [2000 * gpj, 0.0, 2000 * gpj])
    # differential effects do not add fuel here
    assert np.all(vehicle_extra_fuel_g_per_s("inertia", time_s=t, vehicle_speed_mps=v,
                                             vehicle_mass_kg=1500, fuel="gasoline", eta_indicated=eta) == 0)


def test_extra_work_costs_the_fuel_equations_willans_slope():
    """One owner of the Willans slope: a vehicle-level accessory load of 1 kW in the simulation
    costs 1 kW / (eta_indicated x LHV) with the vehicle's own eta_indicated (calibrated, or
    overridden per vehicle), as the engine's accessory_power_W term does (models/engines.toml)."""
    import dataclasses

    from fleetrun.cycles import load_cycle
    from fleetrun.physics.fuels import fuel_properties
    from fleetrun.simulation import simulate
    from fleetrun.simulation.params import willans_slope
    from fleetrun.testing.vehicles import CAMRY as base

    cycle = load_cycle("HWFET")
    for spec in (base, dataclasses.replace(base, extra={**(base.extra or {}), "eta_indicated": 0.3})):
        plain = simulate([spec], cycle, mode="direct")
        loaded = simulate([spec], cycle, mode="direct", effects="accessory_load:power_kW=1")
        eta = willans_slope([spec])[0]
        lhv_J_per_g = fuel_properties(spec.fuel).lhv_MJ_per_kg * 1e3
        burning_s = cycle.time_s[-1] - cycle.time_s[0]   # HWFET: the engine never stops
        extra_g = loaded.fuel_g[0] - plain.fuel_g[0]
        # fuel cut-off on overrun adds none: the extra is at most the whole cycle's, and most of it
        assert 0.8 * 1000 * burning_s / (eta * lhv_J_per_g) < extra_g <= 1.0001 * 1000 * burning_s / (eta * lhv_J_per_g)
    assert willans_slope([dataclasses.replace(base, extra={"eta_indicated": 0.3})])[0] == 0.3


def test_map_with_effects_cli():
    from click.testing import CliRunner

    from fleetrun.cli import cli

    args = ["map", "LD_RWD", "--gear-ratio", "3.55", "--torque-fractions", "0.02,0.2",
            "--speeds-rpm", "100,2000"]
    base = CliRunner().invoke(cli, args)
    more = CliRunner().invoke(cli, args + ["--with", "bearing_preload:drag_torque_Nm=5"])
    assert base.exit_code == 0 and more.exit_code == 0, more.output
    eta0 = [float(r.split(",")[2]) for r in base.output.strip().splitlines()[1:]]
    eta1 = [float(r.split(",")[2]) for r in more.output.strip().splitlines()[1:]]
    assert all(b < a for a, b in zip(eta0, eta1))
    bad = CliRunner().invoke(cli, args + ["--with", "preload"])
    assert bad.exit_code == 1 and "bearing_preload" in bad.output
