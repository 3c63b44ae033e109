"""Issue 22's "one measured number" line (validation/epa_one_number.py, docs/validation-epa.md
"One measured number as physics"): on the EPA 2022 Test Car List, held out by manufacturer, a
label combined figure (EPA's derived formula of the vehicle's measured FTP and HWFET, 40 CFR
600.210-12) puts HWFET >= 88 % and US06 >= 78 % within 5 % (the issue's targets; measured 89.8 and
86.5 %), and `simulate` with `label_combined_mpg` does what the validation assumes. Slow: the whole
list over five cycles."""
from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest


def _within(err, test):
    x = err[test].dropna().to_numpy()
    return np.mean(np.abs(x) <= 0.05)


@pytest.fixture(scope="module")
def prepared():
    from validation.epa_one_number import TESTS, prepare
    from validation.epa_table import epa_fleet

    specs, table = epa_fleet()
    r = prepare(specs, table)
    r["err"] = r["err"][list(TESTS)]
    return r, specs, table


@pytest.mark.slow
def test_the_physical_parts_add_up_to_the_held_out_prediction(prepared):
    from validation.epa_one_number import carry, check_parts, predicted, quantity

    r, _, _ = prepared
    # the candidates redistribute the prediction's own fuel: their parts must be all of it
    assert check_parts(r, predicted(r["parts"], r["err"].index)) < 1e-9
    # any quantity with a positive FTP part makes the FTP exact
    e = carry(r["err"], r["parts"], quantity(r["parts"], "F", r["err"].index))
    assert np.nanmax(np.abs(e["FTP"].to_numpy())) < 1e-9


@pytest.mark.slow
def test_a_label_figure_reaches_the_issue_targets_held_out(prepared):
    from validation.epa_one_number import SHARE_GRID, fit_held_out, label_errors

    r, _, _ = prepared
    family = dict(grid=SHARE_GRID, apply=lambda s: label_errors(r, "share", s))
    e, shares = fit_held_out(r["err"], r["manufacturer"], family)
    assert _within(e, "HWFET") >= 0.88 and _within(e, "US06") >= 0.78      # the issue's targets
    assert 0.45 <= min(shares.values()) and max(shares.values()) <= 0.65    # near models/technology.toml's 0.556
    # the label printed in whole mpg loses part of it (measured 86.2 % on HWFET)
    rounded = label_errors(r, "share", np.median(list(shares.values())), whole_mpg=True)
    assert _within(rounded, "HWFET") < _within(e, "HWFET")


@pytest.mark.slow
def test_simulate_with_a_label_carries_it_as_the_validation_assumes(prepared):
    """End to end: every vehicle of the list with its derived label combined figure, simulated by
    `simulate` at EPA's 25 C with the stored constants (in sample: fitted on all of the list)."""
    from fleetrun.physics import epa_label
    from fleetrun.simulation import simulate

    r, specs, table = prepared
    rows = r["err"].index[np.isfinite(r["paired"]["FTP"].to_numpy()[r["err"].index])
                          & np.isfinite(r["paired"]["HWFET"].to_numpy()[r["err"].index])]
    ftp, hw = r["paired"]["FTP"].to_numpy()[rows], r["paired"]["HWFET"].to_numpy()[rows]
    label = epa_label.combined_label_mpg(ftp, hw, epa_label.set_for_model_year(2022))   # what simulate inverts
    fleet = [dataclasses.replace(specs[i], label_combined_mpg=float(x)) for i, x in zip(rows, label)]
    err = {}
    for test in ("HWFET", "US06"):
        mpg = simulate(fleet, test, ambient_temp_C=25.0).mpg
        err[test] = mpg / r["paired"][test].to_numpy()[rows] - 1.0
    err = pd.DataFrame(err)
    # in sample the constants see every manufacturer: at least the held-out shares (89.8 / 86.5 %)
    assert _within(err, "HWFET") >= 0.88 and _within(err, "US06") >= 0.78
