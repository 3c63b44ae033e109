"""The information bound of the EPA Test Car List (validation/epa_information_bound.py,
docs/validation-epa.md "How far can a model of these inputs get?"): the rows it analyses are
the importer's, twins really share every simulation input, and the nested cross-validation
never lets the held-out manufacturer into a fit."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from fleetrun.simulation import simulate
from validation import epa_information_bound as eib
from validation.epa_table import epa_fleet


@pytest.fixture(scope="module")
def fleet():
    specs, table = epa_fleet()
    vehicles = eib.import_test_car_list(eib.TSTCAR).vehicles
    return specs, table, vehicles


def test_rows_are_the_rows_the_measured_values_average(fleet):
    """Repeatability and features come from the rows behind each measured value: their
    harmonic mean is the importer's value (rounded to 4 digits there) for every vehicle and test."""
    _, table, _ = fleet
    rows = eib.own_fuel_rows(eib.test_rows(), table)
    hm = rows.groupby(["vehicle_id", "test"]).mpg.agg(lambda v: len(v) / np.sum(1.0 / v)).unstack()
    for test in eib.TESTS:
        measured = table.set_index("vehicle_id")[test].dropna()
        np.testing.assert_allclose(hm.loc[measured.index, test], measured, rtol=0, atol=6e-5)


def test_twins_share_every_simulation_input(fleet):
    """Twins (an identical Vehicles row) simulate to the same fuel, so no model of the row can
    tell them apart; and the twin figures are the ones docs/validation-epa.md reports (60
    groups with an FTP; a group's mean puts 75 % of the FTP twins and 83 % of the HWFET twins
    within 5 %)."""
    specs, table, vehicles = fleet
    groups = eib.twin_groups(vehicles)
    by_id = {s.vehicle_id: s for s in specs}
    members = [by_id[i] for ids in groups.values() for i in ids]
    fuel = dict(zip([s.vehicle_id for s in members], simulate(members, "HWFET").fuel_g))
    for ids in groups.values():
        assert len({fuel[i] for i in ids}) == 1, ids
    # distinct inputs do not simulate alike: the key is not coarser than the model
    assert len({round(f, 9) for f in fuel.values()}) == len(groups)
    bound = eib.twin_bound(groups, table)
    assert bound["FTP"]["groups"] == 60
    assert round(100 * bound["FTP"]["within_5pct"]) == 75
    assert round(100 * bound["HWFET"]["within_5pct"]) == 83


def test_nested_physics_leaves_out_the_held_out_manufacturer(fleet):
    """For held-out manufacturer M, M's vehicles are predicted by constants fitted without M,
    and the residuals the correction trains on (manufacturer N) by constants fitted without M
    and N: checked against fits made here on the data with those manufacturers removed."""
    specs, table, _ = fleet
    small = table.manufacturer.value_counts().index[-8:-4]   # four small manufacturers
    keep = np.flatnonzero(table.manufacturer.isin(small).to_numpy())
    sub_specs, sub = [specs[i] for i in keep], table.iloc[keep].reset_index(drop=True)
    d = eib.efe.build_dataset(sub_specs, sub)
    seen = []

    def recording_fit(data):
        seen.append(set(data.manufacturer))
        return eib.efe.fit(data)

    outer = eib.nested_physics(d, sub, fit=recording_fit)
    assert all(len(s) >= 2 for s in seen)
    for m in small:
        for n in small:
            rows = (d.manufacturer == n).to_numpy()
            coef = eib.efe.fit(d[~d.manufacturer.isin({m, n})])
            expect = eib.efe.errors(d[rows], eib.efe.predicted_fuel_g(d[rows], coef))
            got = outer[m].loc[expect.index, expect.columns]
            np.testing.assert_allclose(got.to_numpy(float), expect.to_numpy(float), rtol=1e-12)


def test_correction_never_trains_on_the_held_out_manufacturer(monkeypatch):
    """The learner of fold M is fitted on rows of other manufacturers only, on residuals
    against the physics fitted without M, and predicts each vehicle exactly once."""
    rng = np.random.default_rng(1)
    n = 60
    groups = pd.Series(np.repeat(["a", "b", "c", "d"], n // 4))
    X = pd.DataFrame({"x": rng.normal(size=n)})
    log_meas = pd.Series(rng.normal(3.0, 0.1, n))
    outer = {m: pd.DataFrame({"FTP": np.exp(3.0 + k * 0.01 + rng.normal(0, 0.01, n))})
             for k, m in enumerate("abcd")}
    fits = []

    class Recorder:
        def fit(self, X_, y_):
            fits.append((set(X_.index), y_))
            return self

        def predict(self, X_):
            return np.zeros(len(X_))

    monkeypatch.setattr(eib, "make_learner", lambda kind, X_: Recorder())
    corr, models = eib._nested("boosting", X, log_meas, outer, "FTP", groups)
    assert corr.notna().all() and len(fits) == 4
    predicted = np.concatenate([np.asarray(test) for _, test in models])
    assert sorted(predicted) == list(range(n))                       # each vehicle once
    for (train, y), (_, held) in zip(fits, models):
        m = groups[held[0]]
        assert set(groups[list(train)]) == set("abcd") - {m}          # M never in training
        idx = sorted(train)
        np.testing.assert_allclose(y.loc[idx], log_meas.loc[idx] - np.log(outer[m]["FTP"].loc[idx]))


def test_no_measured_outcome_reaches_the_features(fleet):
    """Features (b) and (c) are the same whatever the list's measured outcomes (mpg, bags, CO2,
    emissions) say: scrambling every outcome column changes no feature."""
    _, table, vehicles = fleet
    rows = eib.own_fuel_rows(eib.test_rows(), table)
    rng = np.random.default_rng(0)
    scrambled = rows.copy()
    for col in eib.OUTCOMES + ("mpg",):
        scrambled[col] = rows[col].to_numpy()[rng.permutation(len(rows))]
    for test in eib.TESTS:
        a = eib.feature_sets(table, vehicles, rows, test)["c"]
        b = eib.feature_sets(table, vehicles, scrambled, test)["c"]
        pd.testing.assert_frame_equal(a, b)
