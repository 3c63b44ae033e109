"""Validation of the simulation (issue 3; docs/validation-simulation.md).

Thesis Sec. 7.2 proof of concept against Matthews' Eq. C.19, and the Argonne 2018 Camry
dynamometer tests after a calibration on the hot-start UDDS only.
"""
from __future__ import annotations

import numpy as np
import pytest

from validation.simulation import (DYNO_TESTS, TABLE_7_1, camry_modes, camry_validation, camry_vehicle,
                                            dyno_segment, engine_on_rows, matthews_c19, proof_of_concept)


def test_matthews_c19_values():
    # Eq. C.19 evaluated by hand: 0.6652 + 3.732e-3 S - 1.061e-5 S^2, 0.987 above 150 km/h
    assert matthews_c19(0) == pytest.approx(0.6652)
    assert matthews_c19(100) == pytest.approx(0.6652 + 0.3732 - 0.1061)
    assert matthews_c19(150) == pytest.approx(0.6652 + 0.5598 - 0.238725)
    assert matthews_c19(151) == 0.987


@pytest.fixture(scope="module")
def poc():
    return proof_of_concept()


def test_proof_of_concept_covers_table_7_1(poc):
    assert list(poc.vehicle.unique()) == [row[0] for row in TABLE_7_1]
    # the output torque the model delivers is the road-load torque (Sec. 7.2 iterates for it)
    assert np.allclose(poc.model_efficiency * poc.diff_input_torque_Nm * 3.0, poc.wheel_torque_Nm, rtol=1e-8)


def test_thesis_gap_reproduced(poc):
    """Sec. 7.2: the C.19 curve "is clearly separated from the rest of the curves, especially at
    low vehicle speeds"; the model sits above it, and the trends are "mimicked slightly"."""
    low = poc[poc.speed_kph == 20]
    high = poc[poc.speed_kph == 140]
    # at 20 km/h the model is 0.15-0.25 above C.19 (0.736) for every vehicle
    assert np.all(low.model_efficiency - low.c19_efficiency > 0.15)
    # near 140 km/h the gap has closed to within 0.02
    assert np.all(np.abs(high.model_efficiency - high.c19_efficiency) < 0.02)
    # the model's efficiency also rises with speed (the trend C.19 shows)
    for _, g in poc.groupby("vehicle"):
        assert g.model_efficiency.iloc[-1] > g.model_efficiency.iloc[0]
    # Fig. 7.3: the torque loss C.19 implies is several times the model's at low speed
    assert np.all(low.c19_loss_Nm > 2 * low.model_loss_Nm)


@pytest.fixture(scope="module")
def camry():
    return camry_validation()


def test_camry_calibration_on_hot_udds_only(camry):
    tests = {t["test"]: t for t in camry["tests"]}
    assert tests["UDDS (hot)"]["calibration"] and not tests["HWFET"]["calibration"]
    assert not tests["US06"]["calibration"]
    assert tests["UDDS (hot)"]["error"] == pytest.approx(0.0, abs=1e-9)
    # the default is the fleet-wide calibration (models/engine_calibration.toml); the Camry's own
    # slope comes out 14 % above it: its engine (A25A-FKS, ~40 % peak brake efficiency) is more
    # efficient than the fleet's average, as Toyota's vehicles are in docs/validation-epa.md
    from fleetrun.simulation.params import engine_defaults

    assert camry["eta_indicated_default"] == engine_defaults("gasoline", "LD").eta_indicated
    # (bands, here and below, wide enough for a refit of the fleet constants: their spread over
    # the manufacturer folds is a few per cent, docs/validation-epa.md)
    assert 1.10 < camry["eta_indicated_calibrated"] / camry["eta_indicated_default"] < 1.18


def test_camry_prediction_errors(camry):
    """Fuel vs Argonne's measurement (docs/validation-simulation.md gives the figures). With the
    fleet-wide constants alone (nothing fitted to this car) the fuel is over-predicted by
    10-18 % (hot UDDS), 5-13 % (HWFET), 0-8 % (US06): this engine beats the fleet's average.
    After the one-constant calibration on its hot UDDS: HWFET within the 5 % target (+8.4 %
    with the earlier generic engine); US06 5-12 % low, outside it (-1.3 % before): the fleet's
    acceleration term prices this car's accelerations too high."""
    tests = {t["test"]: t for t in camry["tests"]}
    assert abs(tests["HWFET"]["error"]) < 0.05
    assert -0.12 < tests["US06"]["error"] < -0.05          # the target is missed; this must not go unnoticed
    assert 0.10 < tests["UDDS (hot)"]["error_uncalibrated"] < 0.18
    assert 0.05 < tests["HWFET"]["error_uncalibrated"] < 0.13
    assert 0.0 < tests["US06"]["error_uncalibrated"] < 0.08
    # measured fuel economies as PROVENANCE.md states them (1 Hz sums)
    assert tests["UDDS (hot)"]["measured_mpg"] == pytest.approx(38.7, abs=0.1)
    assert tests["HWFET"]["measured_mpg"] == pytest.approx(57.4, abs=0.1)
    assert tests["US06"]["measured_mpg"] == pytest.approx(34.0, abs=0.1)


def test_camry_segments_end_at_engine_off():
    """Every recording ends with 26 s standing with the fuel flow exactly 0 (engine off): the
    compared segment stops before them, and the measured sum is unchanged."""
    import pandas as pd

    from fleetrun.resources import inputs_dir

    assert engine_on_rows([0, 3, 0, 0], [0.2, 1.0, 0.1, 0.0]) == 3
    assert engine_on_rows([0, 0], [0, 0]) == 0
    for name, (rec, start) in DYNO_TESTS.items():
        df = pd.read_csv(inputs_dir() / "dyno" / f"{rec}.csv")
        d = df[df.time_s >= start]
        cycle, measured = dyno_segment(rec, start)
        assert len(d) - len(cycle.time_s) == 26, name
        assert measured == pytest.approx(float(d.fuel_rate_cc_per_s.iloc[1:].sum()), rel=1e-12)


def test_camry_tyre_radius_from_epa_n_over_v():
    """The sidecar's radius factor reproduces EPA's N/V of 24.7 rpm/mph in top gear."""
    from fleetrun.simulation.tyre import rolling_radius_m

    v = camry_vehicle()
    r = rolling_radius_m(v.tire_size, v.extra["tire_rolling_radius_factor"])
    n_per_mph = v.transmission_gear_ratios[-1] * v.final_drive_ratio * 0.44704 / r * 60 / (2 * np.pi)
    assert n_per_mph == pytest.approx(24.7, abs=0.01)


def test_camry_hwfet_gap_is_steady_cruise(camry):
    """After the hot-UDDS calibration the HWFET gap sits in cruise (3-10 % low; +12.3 % with the
    earlier generic engine), less in accelerations (within 5 % with issue 10's constants, +5.0 %
    with the refit of issue 22's technology classes: within 7 % and below the cruise gap)."""
    modes = camry_modes(camry)
    hw = modes["HWFET"]
    cruise = hw["cruise"]["predicted_cc"] / hw["cruise"]["measured_cc"] - 1
    accel = hw["acceleration"]["predicted_cc"] / hw["acceleration"]["measured_cc"] - 1
    assert -0.10 < cruise < -0.03
    assert abs(accel) < 0.07 and abs(accel) < abs(cruise)
    # on the UDDS, standstill and overrun are under-predicted (what hides its cruise excess)
    udds = modes["UDDS (hot)"]
    for m in ("standstill", "overrun"):
        assert udds[m]["predicted_cc"] < 0.8 * udds[m]["measured_cc"]
    # the totals by mode add up to the cycle totals
    for k, t in {t["test"]: t for t in camry["tests"]}.items():
        assert sum(m["measured_cc"] for m in modes[k].values()) == pytest.approx(t["measured_cc"], rel=1e-9)
        assert sum(m["predicted_cc"] for m in modes[k].values()) == pytest.approx(t["predicted_cc"], rel=1e-6)
