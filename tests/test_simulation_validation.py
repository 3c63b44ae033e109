"""Validation of the simulation (issue 3; docs/validation-simulation.md).

Thesis Sec. 7.2 proof of concept against Matthews' Eq. C.19, and the Argonne 2018 Camry
dynamometer tests after a calibration on the hot-start UDDS only.
"""
from __future__ import annotations

import numpy as np
import pytest

from fleetrun.simulation.validation import TABLE_7_1, camry_validation, matthews_c19, proof_of_concept


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
    assert tests["UDDS (hot)"]["error"] == pytest.approx(0.0, abs=1e-9)
    # the fitted Willans slope is that of an efficient modern SI engine (A25A-FKS: ~40 %
    # peak brake efficiency), not an outlier
    assert 0.40 < camry["eta_indicated_calibrated"] < 0.48


def test_camry_prediction_errors(camry):
    """Measured results (docs/validation-simulation.md): US06 within the 5 % target, HWFET
    over-predicted by about 7.6 % (outside the target; reported, not tuned away)."""
    tests = {t["test"]: t for t in camry["tests"]}
    assert abs(tests["US06"]["error"]) < 0.05
    assert tests["HWFET"]["error"] == pytest.approx(0.076, abs=0.01)
    # measured fuel economies as PROVENANCE.md states them (1 Hz sums)
    assert tests["UDDS (hot)"]["measured_mpg"] == pytest.approx(38.7, abs=0.1)
    assert tests["HWFET"]["measured_mpg"] == pytest.approx(57.4, abs=0.1)
    assert tests["US06"]["measured_mpg"] == pytest.approx(34.0, abs=0.1)
