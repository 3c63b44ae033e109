"""The fleet-wide fuel calibration and its held-out validation on the EPA 2022 Test Car List
(validation/epa_fuel_economy.py, docs/validation-epa.md)."""
from __future__ import annotations

import tomllib

import numpy as np
import pytest

from fleetrun.resources import models_dir
from fleetrun.simulation import simulate
from fleetrun.simulation.params import FUEL_CONSTANTS, engine_defaults, vehicle_arrays
from fleetrun.testing.vehicles import AWD, CAMRY, CIVIC, F150
from validation.epa_fuel_economy import EXTRA_SUMS, FUEL_TERMS, coefficients_of, trace_extras, trace_terms


def _toml(name):
    with open(models_dir() / name, "rb") as fh:
        return tomllib.load(fh)


def test_light_duty_defaults_are_the_fleet_calibration():
    """A basic Vehicles row runs on the fitted constants; MD/HD sets keep their own."""
    fitted = _toml("engine_calibration.toml")
    for fuel in ("gasoline", "diesel"):
        ld = engine_defaults(fuel, "LD")
        for key in FUEL_CONSTANTS:
            c = fitted[fuel]["LD"]["constants"][key]
            assert getattr(ld, key) == c["value"]
            assert c["fold_min"] <= c["value"] <= c["fold_max"]      # the folds bracket the full fit
    assert engine_defaults("diesel", "HD").eta_indicated == _toml("engines.toml")["diesel"]["HD"]["eta_indicated"]


def test_fuel_is_linear_in_the_constants():
    """What makes the fit exact and fast: the fuel terms summed over a trace, weighted by the
    constants, give the simulated fuel to rounding (1e-9 relative)."""
    cars = [F150, CAMRY, CIVIC, AWD]
    for cycle in ("UDDS", "US06"):
        r = simulate(cars, cycle, trace=True)
        va = vehicle_arrays(cars)
        S = trace_terms(va, r.trace).sum(axis=1)                        # (V, 8) [J]
        fuel_g = (S * coefficients_of(va.fuel_constants)).sum(axis=1) / (va.lhv * 1e3)
        np.testing.assert_allclose(fuel_g, r.fuel_g, rtol=1e-9)


def test_arrb_acceleration_sum_is_the_transient_term_times_the_acceleration():
    """The candidate acceleration term in ARRB's form (docs/validation-epa.md, issue 22 fourth
    round): per step max(a, 0) x P_acc+ x dt over the same steps as the fuel equation's transient
    term, i.e. that term weighted by the step's own acceleration from the trace's speeds."""
    cars = [F150, CAMRY, CIVIC, AWD]
    for cycle in ("UDDS", "US06"):
        r = simulate(cars, cycle, trace=True)
        va = vehicle_arrays(cars)
        per_step = trace_terms(va, r.trace)[..., FUEL_TERMS.index("transient")]       # P_acc+ dt [J]
        v = np.asarray(r.trace.vehicle_speed_mps, float)
        t = np.asarray(r.trace.time_s[0], float)
        accel = np.diff(v, axis=1, prepend=v[:, :1]) / np.diff(t, prepend=t[0] - 1.0)   # backward differences
        arrb = trace_extras(va, r.trace)[..., EXTRA_SUMS.index("transient_arrb")]
        np.testing.assert_allclose(arrb, per_step * np.maximum(accel, 0.0), rtol=1e-9, atol=1e-9)
        assert (arrb > 0).any() and (arrb >= 0).all()


def test_error_file_has_the_agreed_format():
    """models/fuel_economy_error.toml as PROTOCOL.md fixes it (h12's budget ranges read it), each
    test's distribution from at least 150 vehicles (the 2022 list has 190 measured US06 results,
    1,025 FTP and HWFE)."""
    doc = _toml("fuel_economy_error.toml")
    assert doc["source"].startswith("validation/epa_fuel_economy.py")
    for test in ("FTP", "HWFET", "US06"):
        t = doc["tests"][test]
        assert {"n", "mean", "median", "p05", "p95", "within_5pct"} <= set(t)
        assert t["n"] >= 150 and t["p05"] < t["median"] < t["p95"] and 0 <= t["within_5pct"] <= 1


@pytest.mark.slow
def test_heldout_validation_reproduces_the_stored_figures():
    """The script run from scratch gives the held-out distribution stored in models/ (to 1e-6),
    and its figures stay where docs/validation-epa.md reports them: mean error within +-2.5 %
    on every test, at least 40 % of vehicles within 5 % on the FTP and 55 % on HWFET and US06
    (the issue's targets, 80 % / 70 %, are not reached: this test guards the measured level)."""
    from validation.epa_fuel_economy import summaries
    from validation.epa_table import epa_fleet
    from validation.epa_fuel_economy import run

    specs, table = epa_fleet()
    s = summaries(run(specs, table)["err"])
    stored = _toml("fuel_economy_error.toml")["tests"]
    for test in ("FTP", "HWFET", "US06"):
        for key in ("mean", "median", "within_5pct"):
            assert s[test][key] == pytest.approx(stored[test][key], abs=1e-4)
        assert abs(s[test]["mean"]) < 0.025
    assert s["FTP"]["within_5pct"] >= 0.40
    assert s["HWFET"]["within_5pct"] >= 0.55 and s["US06"]["within_5pct"] >= 0.55


def test_speed_squared_friction_sum_is_the_piston_speed_term_times_the_piston_speed():
    """Chen & Flynn's c_m^2 friction candidate (docs/validation-epa.md, issue 22 fifth round):
    per step FMEP power x c_m^2 x dt over the fuel equation's steps, i.e. the piston-speed friction
    term weighted once more by c_m = (piston-speed term) / (friction term) of the same step."""
    cars = [F150, CAMRY, CIVIC, AWD]
    for cycle in ("UDDS", "US06"):
        r = simulate(cars, cycle, trace=True)
        va = vehicle_arrays(cars)
        S = trace_terms(va, r.trace)
        f, f_cm = S[..., FUEL_TERMS.index("friction")], S[..., FUEL_TERMS.index("friction_piston_speed")]
        cm2 = trace_extras(va, r.trace)[..., EXTRA_SUMS.index("friction_piston_speed2")]
        with np.errstate(divide="ignore", invalid="ignore"):
            expected = np.where(f > 0, f_cm ** 2 / f, 0.0)
        np.testing.assert_allclose(cm2, expected, rtol=1e-9, atol=1e-9)
        assert (cm2 > 0).any()
