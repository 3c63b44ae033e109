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


@pytest.mark.slow
def test_acceleration_term_in_arrb_form_is_measured_and_not_better():
    """Issue 22, fourth round (docs/validation-epa.md, pre-registered): the acceleration term in
    the ARRB power model's form, k_a max(a, 0) P_acc+, refitted held out by manufacturer. The
    fit gives it a positive coefficient of the size ARRB's parameters give (0.3-0.7 s^2/m of the
    Willans slope) and it weakens the road-load trend on HWFET, but it loses joined US06 vehicles,
    so the fuel equation keeps k_tr P_acc+ (the registered rule)."""
    import pandas as pd

    import validation.epa_technology as et
    from validation.epa_table import epa_fleet

    specs, table = epa_fleet()
    feats = et.features(specs, table)
    out = {}
    try:
        for form in ("constant", "arrb"):
            et.TRANSIENT_FORM = form
            out[form] = et.run(specs, table)
    finally:
        et.TRANSIENT_FORM = "constant"
    n = len(et.FUEL_TERMS)
    k = [f["gasoline"][n - 1] / f["gasoline"][0] for f in out["arrb"]["folds"].values()]
    assert 0.3 < min(k) and max(k) < 0.7

    def joined(form):
        return out[form]["technology"].reindex(out[form]["joined"])

    assert _within(joined("arrb"), "US06") < _within(joined("constant"), "US06")

    def trend(form):                    # HWFET median error above 6.5 W/kg minus at 4.5-5 W/kg
        e = joined(form)
        bins = pd.cut(feats.road_load_50mph_W_per_kg.loc[e.index], [4.5, 5.0, 6.5, 10.0])
        med = e.HWFET.groupby(bins, observed=True).median()
        return med.iloc[-1] - med.iloc[0]

    assert 0.0 < trend("arrb") < trend("constant")
    # the breakdown behind the hypothesis (--breakdown): a line in road load per kg fitted without
    # each manufacturer is worth several HWFET points; the cold part is too large for big engines
    err, rows = joined("constant"), out["constant"]["joined"]
    feats_j = feats.loc[rows]
    y = np.log1p(err.HWFET.to_numpy())
    ok = np.isfinite(y)
    line = et._heldout_without_line(y[ok], feats_j.road_load_50mph_W_per_kg.to_numpy()[ok],
                                    table.manufacturer.to_numpy()[rows][ok])
    assert et._share(line) > et._share(y[ok]) + 0.03
    cold = np.log1p(err["FTP:bag1"]) - np.log1p(err["FTP:bag3"])
    assert cold[feats_j.displacement_L > 5.0].median() < -0.03 < 0.0 < cold[feats_j.displacement_L <= 2.1].median()


@pytest.mark.slow
def test_friction_by_bore_and_speed_squared_are_measured_and_not_adopted():
    """Issue 22, fifth round (docs/validation-epa.md, pre-registered in commit 176d8c5): the PNH
    bore terms (ring (B_ref/B)^2, skirt c_m B_ref/B) and Chen & Flynn's c_m^2 term, refitted held
    out by manufacturer. The ring term takes a positive coefficient of the size of the constant
    friction (tens of kPa) and gains under 1.5 points of joined FTP, HWFET not at all; the c_m^2
    term is 0 in every fold. Neither raises all three shares, so the fuel equation keeps Chen-Flynn."""
    import validation.epa_technology as et
    from validation.epa_table import epa_fleet

    specs, table = epa_fleet()
    _, d1 = et.datasets(specs, table)
    joined = np.array([m.join == "road_load" for m in et.omega_matches(specs)])
    out, fits = {}, {}
    try:
        for form in ("chen_flynn", "bore", "speed2"):
            et.FRICTION_FORM = form
            err, _, fits[form] = et.heldout_errors(d1, table, np.ones(len(specs), bool), extra=et.stop_extra())
            out[form] = {t: _within(err.reindex(np.flatnonzero(joined)), t) for t in ("FTP", "HWFET", "US06")}
            if form == "bore":
                ring = [et.friction_kPa(f, "X_friction_ring_bore") for f in fits[form].values()]
            if form == "speed2":
                cm2 = [et.friction_kPa(f, "X_friction_piston_speed2") for f in fits[form].values()]
    finally:
        et.FRICTION_FORM = "chen_flynn"
    assert out["chen_flynn"]["FTP"] == pytest.approx(0.488, abs=0.001)     # the 48.8 / 60.4 / 66.0 %
    assert 20.0 < min(ring) and max(ring) < 120.0
    assert 0.0 < out["bore"]["FTP"] - out["chen_flynn"]["FTP"] < 0.015
    assert out["bore"]["HWFET"] <= out["chen_flynn"]["HWFET"]
    assert max(cm2) == 0.0 and out["speed2"] == out["chen_flynn"]
    # F3 (commit 1d168a8): the Willans slope rising as 1 / bore is taken strongly by the fit
    # (0.4-1.0 of the base slope) but loses joined HWFET vehicles: not adopted
    try:
        et.SLOPE_FORM = "bore"
        err, _, fit = et.heldout_errors(d1, table, np.ones(len(specs), bool), extra=et.stop_extra())
    finally:
        et.SLOPE_FORM = "constant"
    k = [f["gasoline"][len(et.FUEL_TERMS) + 1] / f["gasoline"][0] for f in fit.values()]
    assert 0.3 < min(k) and max(k) < 1.2
    assert _within(err.reindex(np.flatnonzero(joined)), "HWFET") < out["chen_flynn"]["HWFET"]


@pytest.mark.slow
def test_the_ratio_error_is_the_highway_part_and_start_stop_from_idle_is_not_better():
    """Issue 22, sixth round (docs/validation-epa.md "The HWFET / FTP ratio, by bag"), held out by
    manufacturer, pairs merged, 890 vehicles with three bags and HWFET. Measured: the highway part
    (HWFET against the hot-start bag) carries 0.75 of the ratio's log-error variance and 0.87 of the
    one-FTP HWFET error's, the cold start -0.01 / -0.02; made right, the cold start and stop-and-go
    lower the one-FTP HWFET share (79.2 -> 76.1 %), the highway part raises it to 93.5 %.
    S1 (pre-registered, start-stop's stop fuel as a share f of the idle fuel): f 0.30-0.60 over the
    folds, one-FTP HWFET 80.5 -> 81.1 %, US06 81.6 -> 80.0 %: fails its rule (US06 down > 1 point).
    Tolerances: 0.1 on variance shares, 1.5 points (13 vehicles) on shares."""
    import pandas as pd

    import validation.epa_technology as et
    from validation.epa_table import epa_fleet

    efe = et.efe     # the module epa_technology fits with (imported by its own path)
    specs, table = epa_fleet()
    r = et.run(specs, table)
    parts, L, _, _ = et.ratio_parts(r["pairs"], r["paired_table"])
    mf = table.manufacturer.to_numpy()[L.index]
    share = lambda p, total: float(np.cov(p, total)[0, 1] / total.var())  # noqa: E731
    ratio = L.HWFET - L.FTP
    assert share(parts.highway, ratio) == pytest.approx(0.75, abs=0.1)
    assert abs(share(parts.cold, ratio)) < 0.1
    _, one = et._one_ftp_share(L.HWFET.to_numpy(), L.FTP.to_numpy(), mf)
    one = pd.Series(one, index=L.index)
    assert share(et.one_ftp_parts(parts, L, one).highway, one) == pytest.approx(0.87, abs=0.1)
    cases = et.ratio_counterfactuals(L, r["paired_table"], mf)
    assert cases["cold and stop-and-go right"][0] < cases["as is"][0]
    assert cases["highway right (HWFET error := bag 3's)"][0] > 0.9
    try:
        efe.STOP = efe.STOP_FORMS["idle_share"]
        s1 = et.run(specs, table)
    finally:
        efe.STOP = efe.STOP_FORMS["constant"]
    f = [fit["gasoline"][len(et.FUEL_TERMS)] for fit in s1["folds"].values()]
    assert 0.2 < min(f) and max(f) < 0.7
    assert _within(s1["one_number"], "HWFET") == pytest.approx(0.811, abs=0.015)
    assert _within(s1["one_number"], "US06") < _within(r["one_number"], "US06") - 0.01
