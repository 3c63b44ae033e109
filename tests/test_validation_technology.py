"""Issue 22's validation (validation/epa_technology.py) reproduces what models/ store and what
docs/validation-epa.md reports: the transfer share, the held-out gallons bias, and that one
measured FTP per vehicle carries to HWFET and US06 better than the physics alone (the issue's
re-analysis: about 82 % / 73 % within 5 %). Slow: the whole 2022 list over four cycles."""
from __future__ import annotations

import tomllib

import numpy as np
import pytest

from fleetrun.resources import models_dir


def _toml(name):
    with open(models_dir() / name, "rb") as f:
        return tomllib.load(f)


def _within(err, test):
    x = err[test].dropna().to_numpy()
    return np.mean(np.abs(x) <= 0.05)


@pytest.mark.slow
def test_technology_validation_reproduces_models_and_its_claims():
    from validation.epa_table import epa_fleet
    from validation.epa_technology import bias_report, run

    specs, table = epa_fleet()
    r = run(specs, table)
    assert r["sigma_all"] == pytest.approx(_toml("technology.toml")["fitted"]["transfer_share"], abs=5e-4)
    bias = bias_report(r["pairs"], r["paired_table"])
    stored = _toml("fuel_economy_bias.toml")
    assert bias["bias_all"] == pytest.approx(stored["gallons_bias"], abs=1e-4)
    assert abs(bias["total_corrected"]) <= 0.005                       # the issue's +-0.5 %
    assert -0.02 <= bias["fleets_corrected"][0] and bias["fleets_corrected"][1] <= 0.02
    # one measured number beats the physics alone on the cycles it was not measured on
    for test in ("HWFET", "US06"):
        assert _within(r["one_number"], test) > _within(r["pairs"], test) + 0.08
    # the technology classes do not make the joined vehicles worse than physics only
    joined = r["pairs"].index.intersection(r["joined"])
    for test in ("FTP", "HWFET", "US06"):
        assert _within(r["pairs"].loc[joined], test) >= _within(r["physics_pairs"].loc[joined], test) - 0.01
    # the vehicles that take their engine's classes gain on the FTP and HWFET (about 300 vehicles
    # each; US06 has 42, where one vehicle is 2.4 points: not asserted, reported in the docs)
    engine = r["pairs"].index.intersection(r["unjoined"])
    for test in ("FTP", "HWFET"):
        assert _within(r["pairs"].loc[engine], test) > _within(r["physics_pairs"].loc[engine], test)
    # the transfer on the physical split of losses is fitted held out too, and its weights put most
    # of a vehicle's FTP correction on its cold start (weight 1 against w_B, w_O < 0.3)
    assert max(max(w) for w in r["split_folds"].values()) < 0.3
    for test in ("HWFET", "US06"):
        assert _within(r["split"], test) > _within(r["pairs"], test) + 0.08
