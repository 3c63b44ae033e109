"""Real MY2022 labels (fueleconomy.gov `vehicles.csv`, inputs/fueleconomy/) joined to the EPA
2022 Test Car List and carried by the label route of validation/epa_one_number.py, held out by
manufacturer (validation/epa_labels.py; docs/validation-epa.md "Real labels")."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from validation import epa_labels as el


def _vehicle(**kw):
    row = dict(vehicle_id="X_c0", manufacturer="", make="", model="", displacement_L=np.nan, cylinders=np.nan,
               transmission_code="", gears=np.nan, drive_code="", fuel_description="Tier 2 Cert Gasoline")
    return pd.DataFrame([{**row, **kw}])


@pytest.fixture(scope="module")
def labels():
    return el.load_labels()


def test_model_words_normalise_the_lists_and_the_labels_spellings():
    assert el._words("F-150 Super Crew 4X4", "Ford") == (("F150", "SUPER", "CREW"), "4")
    assert el._words("C 300 4MATIC (coupe)", "Mercedes-Benz")[0] == ("C300", "COUPE")
    assert el._words("MAZDA3", "MAZDA")[0] == ("3",)
    assert el._words("Ford Explorer", "Ford")[0] == ("EXPLORER",)
    assert el._words("Explorer FHEV")[0] == el._words("Explorer HEV AWD")[0]
    assert el._label_gearbox("Automatic (AM-S7)") == ("am", 7.0)
    assert el._label_gearbox("Automatic (AV-S8)")[0] == "cvt"
    assert el._label_gearbox("Manual 6-spd") == ("manual", 6.0)


def test_a_vehicle_joins_its_own_label_row(labels):
    """The 2022 Camry Hybrid LE (list: TOYOTA, 2.487 L, CVT, F) is fueleconomy.gov record 44350."""
    j = el.join(_vehicle(make="TOYOTA", model="CAMRY HYBRID LE", displacement_L=2.487, cylinders=4,
                         transmission_code="CVT", gears=1, drive_code="F"), labels)
    assert j.status[0] == "matched" and j.label_ids[0] == "44350"
    assert j.comb08U[0] == labels.set_index("id").comb08U[44350]


def test_a_lexus_tested_as_toyota_joins_across_makes(labels):
    j = el.join(_vehicle(make="TOYOTA", model="NX 250 AWD", displacement_L=2.487, cylinders=4,
                         transmission_code="A", gears=8, drive_code="A"), labels)
    assert j.status[0] == "matched" and j.reason[0].startswith("label make Lexus")


def test_labels_that_differ_are_listed_not_used(labels):
    """RAM 1500 2WD 5.7 L: two labels (with and without eTorque) 17 % apart: ambiguous unless the
    vehicle's technology classes say which."""
    ram = dict(make="RAM", model="1500 2WD", displacement_L=5.7, cylinders=8, transmission_code="SA", gears=8,
               drive_code="R")
    j = el.join(_vehicle(**ram), labels)
    assert j.status[0] == "ambiguous" and np.isnan(j.comb08U[0]) and j.n_candidates[0] >= 2
    j = el.join(_vehicle(**ram, technology="cylinder_deactivation,mild_hybrid_48v,start_stop"), labels)
    assert j.status[0] == "matched" and j.label_ids[0] == "44395"          # "1500 2WD", eng_dscr "Mild Hybrid"
    j = el.join(_vehicle(make="Karma", model="Revero GT", displacement_L=1.5, cylinders=3), labels)
    assert j.status[0] == "unmatched" and j.reason[0] == "make not in the labels"


@pytest.fixture(scope="module")
def routed():
    r, table = el.prepared()
    lab = el.labels_of(r, table, el.joined())
    lines, results = el.route_lines(r, lab)
    return r, lab, results


@pytest.mark.slow
def test_every_list_vehicle_is_matched_or_listed():
    j = el.joined()
    vehicles = el.list_vehicles()
    assert list(j.vehicle_id) == list(vehicles.vehicle_id)                # nothing dropped
    assert set(j.status) == {"matched", "ambiguous", "unmatched"} and (j.reason != "").all()
    assert (j.status == "matched").sum() >= 1100                             # measured 1,162 of 1,370


@pytest.mark.slow
def test_the_my2017_label_coefficients_reproduce_the_labels(labels):
    """fueleconomy.gov MY2022: the label's own unadjusted city figure through the budget.toml
    formulas; exact (0.01 %) for most labels with the MY2017 coefficients (measured 81 %), almost
    none with the 2008 ones (measured 1.3 %)."""
    new = el.label_formula_check(labels, "derived_2017")["city08U"]
    old = el.label_formula_check(labels, "derived_2008")["city08U"]
    assert np.mean(np.abs(new) <= 1e-4) > 0.75 and np.mean(np.abs(old) <= 1e-4) < 0.05


@pytest.mark.slow
def test_the_real_label_route_held_out(routed):
    """The issue's line "one measured FTP or label figure: HWFET >= 88 %, US06 >= 78 % within 5 %"
    with the real label (unrounded comb08U) on the 899 joined vehicles, the share fitted on the
    other manufacturers (22 folds): measured HWFET 78.0 % with the MY2017 formulas (what `simulate`
    applies to a MY2022 vehicle) and 74.7 % with the 2008 ones, US06 82.3 / 79.7 % (158 vehicles).
    Tolerance: 1.5 points on HWFET (13 vehicles), 2.5 on US06 (4 vehicles), for small model
    changes; the HWFET target stays missed."""
    _, lab, results = routed
    assert lab.used.sum() >= 800

    def within(key, test):
        x = results[key][test].dropna().to_numpy()
        return np.mean(np.abs(x) <= 0.05)

    for name, hw, us in (("real comb08U", 0.780, 0.823), ("real comb08U, 2008 formulas", 0.747, 0.797)):
        assert abs(within((name, "22 folds"), "HWFET") - hw) <= 0.015
        assert abs(within((name, "22 folds"), "US06") - us) <= 0.025
        assert within((name, "22 folds"), "HWFET") < 0.88 <= within(("derived (MY2017 formulas)", "22 folds"), "HWFET")


@pytest.mark.slow
def test_vehicles_on_one_label_share_its_scale(routed):
    """Pre-registered G1 (docs/validation-epa.md "Several test vehicles on one label"): the
    vehicles joined to one label share one fuel scale and the simulation carries their
    configuration differences. Measured held out (22 folds) against the per-vehicle route on the
    same 899 vehicles: HWFET 78.0 -> 80.9 %, US06 82.3 -> 84.8 %; vehicles alone on their label
    unchanged (HWFET 78.9 %). The rule's bar: >= 1 point on HWFET, <= 1 point lost on US06."""
    r, lab, _ = routed
    from epa_one_number import SHARE_GRID, fit_held_out, label_errors

    used = lab.used.to_numpy()
    real = np.where(used, lab.comb08U.to_numpy(), np.nan)
    groups = np.where(used, lab.label_ids.astype(str).to_numpy(), None)
    mf = r["manufacturer"]
    one, _ = fit_held_out(r["err"], mf, dict(grid=SHARE_GRID, apply=lambda s: label_errors(r, "share", s, label=real)))
    grp, _ = fit_held_out(r["err"], mf, dict(grid=SHARE_GRID, apply=lambda s: el.group_label_errors(r, s, real, groups)))

    def within(e, test):
        x = e[test].dropna().to_numpy()
        return np.mean(np.abs(x) <= 0.05)

    assert within(grp, "HWFET") - within(one, "HWFET") >= 0.01
    assert within(grp, "US06") - within(one, "US06") >= -0.01
    assert abs(within(grp, "HWFET") - 0.809) <= 0.015 and within(grp, "HWFET") < 0.88
    size = pd.Series(groups).map(pd.Series(groups).value_counts()).to_numpy()
    alone = used & (size == 1)
    assert np.allclose(grp.loc[alone, ["FTP", "HWFET"]], one.loc[alone, ["FTP", "HWFET"]], rtol=0, atol=1e-12)
