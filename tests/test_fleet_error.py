"""The fleet-level error behind the budget's ranges, against the held-out EPA predictions.

validation/data/epa_heldout_errors.csv holds, per vehicle of the EPA 2022 Test Car List, the
error of the prediction made with its manufacturer held out (validation/fleet_error.py
heldout: validation/epa_technology.py's drive-mode pairs, the model as the budget runs it).
Random fleets are drawn from it (10-1,000 vehicle types, from the whole list or from 1, 3 or
10 manufacturers, chosen uniformly or by size); each fleet's true error is its measured /
predicted gallons - 1. Target (issue "a forecast a budget committee accepts"): the 90 % range
covers 85-95 % of the fleets, and for fleets of 100 or more vehicle types drawn from the list
it is at most 1.5x the measured 5-95 % interval. The bounds below are the measured figures
(docs/budget.md, "Ranges"; `python validation/fleet_error.py coverage` / `cv`, 1,000 fleets per
cell) with the sampling noise of 300 fleets per cell here (binomial sd ~1.7 points per cell,
~0.3 pooled; the cells share manufacturers, so the pooled figure moves more: +-1.5 points).
"""
from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from fleetrun.budget.uncertainty import half_width, read_error_model
from fleetrun.resources import models_dir
from validation.fleet_error import coverage, cross_validate, fit_constants, read_heldout


@pytest.fixture(scope="module")
def heldout():
    return read_heldout()


@pytest.fixture(scope="module")
def table(heldout):
    return coverage(heldout, read_error_model(models_dir() / "fleet_error.toml").for_duty("LD"), n=300, seed=7)


def test_stored_constants_are_the_fit_of_the_stored_errors(heldout):
    stored = tomllib.loads((models_dir() / "fleet_error.toml").read_text())["LD"]
    fitted = fit_constants(heldout)
    for key in ("bias", "tau", "sigma", "share_exponent", "tau_size"):
        assert stored[key] == pytest.approx(fitted[key], abs=1e-4), f"{key}: run validation/fleet_error.py fit --write"
    assert stored["df"] == fitted["df"]
    # the same predictions as the light-duty work's models/fuel_economy_bias.toml (predicted /
    # measured - 1 there): one bias, two files that must agree
    other = tomllib.loads((models_dir() / "fuel_economy_bias.toml").read_text())["gallons_bias"]
    assert fitted["bias"] == pytest.approx(1.0 / (1.0 + other) - 1.0, abs=5e-5), (
        "the held-out errors are older than the light-duty model: run `PYTHONPATH=. python "
        "validation/fleet_error.py heldout` and `... fit --write`, then `... coverage` / `... cv` for the docs")


def test_half_width_of_t_plus_normal_against_direct_draws():
    """The tabulated convolution against 400,000 direct draws of a t_3 + b z."""
    rng = np.random.default_rng(3)
    t, z = rng.standard_t(3, 400_000), rng.standard_normal(400_000)
    for a, b in ((0.03, 0.0), (0.03, 0.02), (0.01, 0.05)):
        assert float(half_width(a, b, 3.0)) == pytest.approx(np.quantile(np.abs(a * t + b * z), 0.90), rel=0.01)
    assert float(half_width(0.03, 0.04)) == pytest.approx(0.05 * 1.6448536269514722, rel=1e-12)   # normal


def test_ranges_cover_the_measured_share_of_random_fleets(table):
    # measured (seed 20, 1,000 fleets per cell): 87.3 % pooled (the one normal spread before:
    # 95.4 %, over the target), inside the target 85-95 %
    assert 0.855 <= table.covered.mean() <= 0.89
    one = table[(table.manufacturers == 1) & (table.drawn == "uniform")]
    # single manufacturers drawn uniformly (small ones err most): 88.6-90.2 %
    assert one.covered.min() >= 0.85
    # the least covered kind: 10 manufacturers drawn by size, 78.5-87.0 % (the small
    # manufacturers' effects are not centred on zero: docs/budget.md); none over 96.1 %
    assert table.covered.min() >= 0.72 and table.covered.max() <= 0.985


def test_ranges_are_at_most_one_and_a_half_times_the_measured_interval(table):
    large = table[table["size"] >= 100]
    # every kind of draw (measured at most 1.33; 1.73 with the one normal spread)
    assert (large.width_ratio <= 1.5).all()
    whole = large[large.manufacturers == "all"]
    assert (whole.width_ratio >= 0.9).all()       # and not narrower than what is measured (0.99-1.33)


@pytest.mark.slow
def test_cross_validated_by_manufacturer(heldout):
    """Constants fitted on 4 of 5 folds of manufacturers, coverage on fleets of the fifth;
    measured (1,000 fleets per cell): 91.9 % pooled, folds 78.5-99.1 % (BMW's fold the least:
    BMW is -4.0 % on its own, the largest manufacturer), one manufacturer 90.0 %. With 200 fleets
    per cell (here): 92.0 %, folds 78.7-99.2 %."""
    folds = cross_validate(heldout, n=200, seed=11)
    per_fold = [f["table"].covered.mean() for f in folds]
    pooled = float(np.mean(per_fold))
    one = np.mean([f["table"][f["table"].manufacturers == 1].covered.mean() for f in folds])
    assert 0.89 <= pooled <= 0.95, per_fold
    assert min(per_fold) >= 0.74 and one >= 0.87, per_fold
    assert all(math.isinf(f["constants"]["df"]) and f["constants"]["tau_size"] > 0 for f in folds)


def test_manufacturer_effect_sized_by_the_manufacturer_by_hand():
    """tau_m^2 = tau^2 + tau_size^2 share_ref / W_m (docs/budget.md): a hand calculation of the
    effect's scale a for a fleet of one make, of an unknown make-up and of a manufacturer the
    market does not know (sized as its smallest)."""
    from fleetrun.budget.uncertainty import DutyError

    e = DutyError(bias=0.0, tau=0.01, sigma=0.05, tau_size=0.04, share_ref=0.01,
                  market_share={"A": 0.6, "B": 0.4}, makes={"AMAKE": "A"})
    var = {"A": 0.01 ** 2 + 0.04 ** 2 * 0.01 / 0.6, "B": 0.01 ** 2 + 0.04 ** 2 * 0.01 / 0.4}
    a, b = e.scales([1.0, 1.0], ["Amake", "A"])          # one manufacturer, two equal types
    assert a == pytest.approx(math.sqrt(0.4 ** 2 * var["A"] + 0.4 ** 2 * var["B"]), rel=1e-12)
    assert b == pytest.approx(0.05 * math.sqrt(0.5), rel=1e-12)
    a, _ = e.scales([1.0, 1.0])                            # make-up unknown: E D
    assert a == pytest.approx(math.sqrt((0.24 * var["A"] + 0.24 * var["B"]) * 0.5), rel=1e-12)
    a, _ = e.scales([1.0], ["Nobody"])                     # not in the market: the smallest share
    assert a == pytest.approx(math.sqrt(var["B"] + 0.6 ** 2 * var["A"] + 0.4 ** 2 * var["B"]), rel=1e-12)
    assert e.half_width90([1.0], ["A"]) == pytest.approx(1.6448536 * math.hypot(0.4 * math.sqrt(var["A"] + var["B"]), 0.05), rel=1e-6)
