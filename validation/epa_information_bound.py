"""How far can any model of the EPA Test Car List's inputs get? Evidence for issue 10's target.

    PYTHONPATH=. python validation/epa_information_bound.py [--json out.json] [--quick]

The physics model (validation/epa_fuel_economy.py) misses EPA's measured mpg by a vehicle-level
efficiency that the Vehicles row does not describe. This script measures how much of that
scatter any model of the available inputs could remove:

1. **Repeatability** of EPA's own numbers: rows of the list that are repeat tests of one test
   vehicle and configuration (same vehicle id, same test, several test numbers, on the vehicle's
   own fuel, the rows the importer averages: analytically derived values left out): the
   spread of their mpg about the configuration's mean.
2. **Twins**: distinct configurations whose every model input (the whole Vehicles row that
   ``fleetrun import-epa`` writes, identity columns excepted) is identical. No deterministic
   function of the inputs can tell them apart; predicting each twin group by its geometric mean
   is the best any model can do on them.
3. **A flexible learner on top of the physics**: a correction of log(measured / physics
   prediction), learned nested leave-one-manufacturer-out (for held-out manufacturer M both the
   physics constants and the correction are fitted without any vehicle of M, and the physics
   predictions the correction trains on come from fits without M and without their own
   manufacturer). Learners: scikit-learn ``HistGradientBoostingRegressor`` (shallow, early
   stopping) and a ridge regression. Feature sets: (a) the Vehicles row (the model's inputs);
   (b) + every other non-outcome column of the list; (c) reference only, NOT allowed: (b) +
   the manufacturer, cross-validated by test vehicle (the manufacturer seen in training).
   Measured outcomes (mpg, bags, CO2, emissions) are never features. Held-out permutation
   importance of the features.
4. Protocol effects: the test fuel of each row, and the drive-quality ratings (DT-*) of the
   test runs; the analytically derived rows (why they are not measurements of the row).
5. Where the information is (reference, not a model): each vehicle's physics error corrected
   by the median error of the other vehicles of its manufacturer, engine code or test group.

Errors are predicted mpg / measured mpg - 1 as in validation/epa_fuel_economy.py.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import epa_fuel_economy as efe  # noqa: E402
from epa_table import TSTCAR, epa_fleet, own_fuel_rows, test_rows  # noqa: E402

from fleetrun.epa import import_test_car_list  # noqa: E402

TESTS = ("FTP", "HWFET", "US06")
#: Vehicles-row columns that identify a vehicle but are no model input.
IDENTITY = ("vehicle_id", "manufacturer", "make", "model", "model_year", "count", "annual_miles")
#: Measured outcomes of the list: never features.
OUTCOMES = ("THC (g/mi)", "CO (g/mi)", "CO2 (g/mi)", "NOx (g/mi)", "PM (g/mi)", "CH4 (g/mi)", "N2O (g/mi)",
            "RND_ADJ_FE", "FE_UNIT", "FE Bag 1", "FE Bag 2", "FE Bag 3", "FE Bag 4")
DT_RATINGS = ("DT-Inertia Work Ratio Rating", "DT-Absolute Speed Change Ratg", "DT-Energy Economy Rating")
WITHIN = 0.05


# ----------------------------------------------------------------------------- 1. repeatability
def repeat_spread(rows):
    """Deviations of each repeat row's log mpg from its (vehicle, test) group mean, for groups
    of two or more rows. Returns the rows with ``dev`` and ``group_size``."""
    key = ["vehicle_id", "test"]
    size = rows.groupby(key).mpg.transform("size")
    rep = rows[size > 1].assign(lg=lambda x: np.log(x.mpg))
    rep["dev"] = rep.lg - rep.groupby(key).lg.transform("mean")
    rep["group_size"] = rep.groupby(key).lg.transform("size")
    return rep


def spread_summary(rep):
    """Per test: groups, rows, pooled within-group SD of log mpg, median |deviation| and the
    share of rows within 5 % of their group mean, the median max/min - 1 of a group."""
    out = {}
    for test, x in rep.groupby("test"):
        n = x.groupby("vehicle_id").size()
        rng = x.groupby("vehicle_id").lg.agg(lambda v: v.max() - v.min())
        out[test] = dict(groups=int(n.size), rows=int(len(x)),
                         pooled_sd=float(np.sqrt((x.dev ** 2).sum() / (n - 1).sum())),
                         median_abs_dev=float(x.dev.abs().median()),
                         within_5pct=float((x.dev.abs() <= WITHIN).mean()),
                         median_range=float(np.expm1(rng.median())),
                         groups_range_over_10pct=int((rng > np.log(1.1)).sum()))
    return out


def repeatability(rows):
    """Spread of repeat tests (the measured rows the importer averages). No group of them mixes
    procedures or originators: these are same-procedure repeats."""
    return spread_summary(repeat_spread(rows))


def adfe_road_load(path=TSTCAR):
    """Analytically derived rows: their ADFE road-load power [hp] over the power of the row's
    target coefficients at 50 mph, and their ADFE N/V and weight over the row's (why the
    importer does not use them: they describe another configuration)."""
    x = test_rows(path, derived=True)
    num = lambda c: pd.to_numeric(x[c], errors="coerce")  # noqa: E731
    target_hp = (num("Target Coef A (lbf)") + 50 * num("Target Coef B (lbf/mph)")
                 + 2500 * num("Target Coef C (lbf/mph**2)")) * 50 / 375
    out = {"rows": int(len(x))}
    for name, ratio in (("road_load_power", num("ADFE Total Road Load HP") / target_hp),
                        ("nv", num("ADFE N/V Ratio") / num("N/V Ratio")),
                        ("weight", num("ADFE Equiv. Test Weight (lbs.)") / num("Equivalent Test Weight (lbs.)"))):
        r = ratio.dropna()
        out[name] = dict(n=int(r.size), min=float(r.min()), max=float(r.max()), std=float(r.std()),
                         differ_over_3pct=float(np.mean(np.abs(r - 1) > 0.03)))
    return out


def wide_repeats(rows, limit=0.10):
    """(vehicle_id, test) of measured repeat groups whose rows differ by more than ``limit``
    (max / min - 1), with the vehicle's make and model."""
    rep = repeat_spread(rows)
    rng = rep.groupby(["vehicle_id", "test"]).lg.agg(lambda v: v.max() - v.min())
    return rng[rng > np.log1p(limit)].reset_index()[["vehicle_id", "test"]]


def data_limits(rows, table, err):
    """The physics' held-out errors on the vehicles whose measured value mixes rows the inputs
    cannot describe (repeat rows more than 10 % apart) and on the rest."""
    wide = wide_repeats(rows)
    e = err.set_axis(table.vehicle_id)
    models = table.set_index("vehicle_id").loc[wide.vehicle_id.unique(), ["make", "model"]]
    out = {"wide_repeat_models": sorted({f"{a} {b}" for a, b in models.itertuples(index=False)})}
    for test in TESTS:
        wide_t = set(wide.vehicle_id[wide.test == test])
        ok = e[test].notna()
        masks = {"all": ok, "repeat rows > 10 % apart": ok & e.index.isin(wide_t),
                 "the others": ok & ~e.index.isin(wide_t)}
        out[test] = {k: efe.summary(e[test][m]) for k, m in masks.items()}
    return out


# ----------------------------------------------------------------------------- 2. twins
def input_key(vehicles):
    """One hashable key per Vehicles row: every column except the identity ones."""
    frame = pd.DataFrame(vehicles)
    cols = [c for c in frame.columns if c not in IDENTITY]
    return frame.vehicle_id, frame[cols].apply(lambda c: c.map(repr)).agg("|".join, axis=1)


def twin_groups(vehicles):
    """{key: [vehicle ids]} of the keys shared by two or more vehicles."""
    ids, key = input_key(vehicles)
    groups = pd.Series(ids.to_numpy()).groupby(key.to_numpy()).agg(list)
    return {k: v for k, v in groups.items() if len(v) > 1}


def twin_bound(groups, table):
    """Per test: the errors of the best constant per twin group (its geometric mean) on the
    twins' measured mpg, and the same scaled to the error against the true mean of the inputs
    (a member's deviation from the mean of n has variance sigma^2 (n - 1) / n)."""
    by_id = table.set_index("vehicle_id")
    out = {}
    for test in TESTS:
        devs, scales, dof, members, n_groups, cross = [], [], 0, 0, 0, 0
        for ids in groups.values():
            mpg = by_id.loc[ids, test].dropna().to_numpy(float)
            if mpg.size < 2:
                continue
            lg = np.log(mpg)
            devs.append(lg - lg.mean())
            scales.append(np.full(mpg.size, np.sqrt(mpg.size / (mpg.size - 1))))
            dof += mpg.size - 1
            members += mpg.size
            n_groups += 1
            cross += by_id.loc[ids, "manufacturer"].nunique() > 1
        dev, scale = np.concatenate(devs), np.concatenate(scales)
        # a member's error against the true mean of its inputs: dev x sqrt(n / (n - 1))
        true = dev * scale
        out[test] = dict(groups=n_groups, vehicles=members, groups_across_manufacturers=int(cross),
                         within_5pct=float(np.mean(np.abs(np.expm1(dev)) <= WITHIN)),
                         median_abs=float(np.median(np.abs(np.expm1(dev)))),
                         within_5pct_true_mean=float(np.mean(np.abs(np.expm1(true)) <= WITHIN)),
                         median_abs_true_mean=float(np.median(np.abs(np.expm1(true)))),
                         sd_log=float(np.sqrt((dev ** 2).sum() / dof)))
    return out


# ----------------------------------------------------------------------------- 3. features
def vehicle_features(table, vehicles):
    """(a): the Vehicles row as the model sees it, plus ratios of it (per vehicle)."""
    v = pd.DataFrame(vehicles).set_index("vehicle_id").loc[table.vehicle_id]
    f = pd.DataFrame(index=table.index)
    for col in ("test_weight_kg", "coastdown_A_lbf", "coastdown_B_lbf_per_mph", "coastdown_C_lbf_per_mph2",
                "final_drive_ratio", "nv_ratio_rpm_per_mph", "engine_displacement_L", "rated_power_kW",
                "peak_engine_torque_Nm", "cylinders"):
        f[col] = pd.to_numeric(v[col], errors="coerce").to_numpy()
    f["gears"] = table.gears.to_numpy(float)
    for col in ("gearbox_type", "converter_lockup", "configuration", "fuel", "vehicle_class"):
        f[col] = v[col].astype(str).to_numpy()
    f["specific_power_kW_per_L"] = f.rated_power_kW / f.engine_displacement_L
    f["power_to_weight_W_per_kg"] = 1e3 * f.rated_power_kW / f.test_weight_kg
    f["road_load_50mph_lbf"] = f.coastdown_A_lbf + 50 * f.coastdown_B_lbf_per_mph + 2500 * f.coastdown_C_lbf_per_mph2
    f["road_load_per_weight_50mph"] = f.road_load_50mph_lbf / f.test_weight_kg
    f["displacement_per_weight_L_per_t"] = 1e3 * f.engine_displacement_L / f.test_weight_kg
    return f


def _first_text(s):
    s = s.dropna().astype(str).str.strip()
    return s.iloc[0] if len(s) else "none"


def list_features(rows, table, test):
    """(b) extras: every other non-outcome column of the list for ``test`` (per vehicle, from the
    rows of that test the measured value averages): engine code, test group characters, test
    fuel, aftertreatment, vehicle type, set coefficients and target minus set, drive-quality
    ratings, overdrive, shift indicator, originator, procedure, number of rows."""
    x = rows[rows.test == test].copy()
    num = lambda c: pd.to_numeric(x[c], errors="coerce")  # noqa: E731
    for s in "ABC":
        unit = {"A": "(lbf)", "B": "(lbf/mph)", "C": "(lbf/mph**2)"}[s]
        x[f"set_{s}"] = num(f"Set Coef {s} {unit}")
        x[f"tms_{s}"] = num(f"Target Coef {s} {unit}") - x[f"set_{s}"]
    for mph in (20, 50):
        x[f"target_minus_set_{mph}mph_lbf"] = x.tms_A + mph * x.tms_B + mph ** 2 * x.tms_C
    for k, c in enumerate(DT_RATINGS):
        x[f"dt_{('iwr', 'ascr', 'eer')[k]}"] = num(c)
    x["epa_originator"] = (x["Test Originator"].str.strip() == "EPA").astype(float)
    tg = x["Actual Tested Testgroup"].fillna("").str.strip().str.upper().str.pad(12, "right", "_")
    for i, name in ((0, "testgroup_year_char"), (4, "testgroup_class_char"), (9, "testgroup_char10"),
                    (10, "testgroup_char11"), (11, "testgroup_char12")):
        x[name] = tg.str[i]
    numeric = ["set_A", "set_B", "set_C", "tms_A", "tms_B", "tms_C", "target_minus_set_20mph_lbf",
               "target_minus_set_50mph_lbf", "dt_iwr", "dt_ascr", "dt_eer", "epa_originator"]
    text = {"Engine Code": "engine_code", "Test Fuel Type Description": "test_fuel",
            "Aftertreatment Device Desc": "aftertreatment", "Vehicle Type": "vehicle_type",
            "Transmission Overdrive Desc": "overdrive", "Shift Indicator Light Use Desc": "shift_indicator",
            "Test Procedure Description": "procedure", "Police - Emergency Vehicle?": "police",
            "Averging Method Desc": "averaging", "testgroup_year_char": "testgroup_year_char",
            "testgroup_class_char": "testgroup_class_char", "testgroup_char10": "testgroup_char10",
            "testgroup_char11": "testgroup_char11", "testgroup_char12": "testgroup_char12"}
    g = x.groupby("vehicle_id")
    out = g[numeric].mean()
    out["test_rows"] = g.size().astype(float)
    for col, name in text.items():
        out[name] = g[col].agg(_first_text)
    out = out.reindex(table.vehicle_id)
    out.index = table.index
    return out


def feature_sets(table, vehicles, rows, test):
    """{"a": frame, "b": frame, "c": frame} of one test (rows: vehicles)."""
    a = vehicle_features(table, vehicles)
    b = pd.concat([a, list_features(rows, table, test)], axis=1)
    c = b.assign(manufacturer=table.manufacturer.to_numpy())
    return {"a": a, "b": b, "c": c}


# ----------------------------------------------------------------------------- nested physics
def nested_physics(d, table, fit=None):
    """{outer manufacturer M: predicted mpg (vehicles x tests)} where M's vehicles come from the
    fit without M, and every other manufacturer N's from the fit without M and N: what the
    correction for M may train on."""
    fit = fit or efe.fit
    mans = list(table.manufacturer.unique())
    coef = {}
    outer = {}
    for m in mans:
        parts = []
        for n in mans:
            key = frozenset((m, n))
            if key not in coef:
                coef[key] = fit(d[~d.manufacturer.isin(key)])
            rows = (d.manufacturer == n).to_numpy()
            parts.append(efe.errors(d[rows], efe.predicted_fuel_g(d[rows], coef[key])))
        outer[m] = pd.concat(parts).sort_index()
    return outer


# ----------------------------------------------------------------------------- 3. learners
def _prepare(X, categories=None, max_categories=200):
    """Categorical text columns as pandas categories (rare ones pooled; the category set fixed
    by ``categories`` so the folds agree), numerics as float."""
    X = X.copy()
    cats = {}
    for col in X.columns:
        if not pd.api.types.is_numeric_dtype(X[col]):
            if categories is None:
                counts = X[col].value_counts()
                keep = list(counts[counts >= 3].index[:max_categories])
                cats[col] = keep + ["rare"]
            else:
                cats[col] = categories[col]
            text = X[col].astype(object)
            X[col] = pd.Categorical(text.where(text.isin(cats[col]), "rare"), categories=cats[col])
        else:
            X[col] = X[col].astype(float)
    return X, cats


def make_learner(kind, X):
    from sklearn.compose import ColumnTransformer
    from sklearn.ensemble import HistGradientBoostingRegressor
    from sklearn.impute import SimpleImputer
    from sklearn.linear_model import RidgeCV
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import OneHotEncoder, StandardScaler

    if kind == "boosting":
        return HistGradientBoostingRegressor(loss="absolute_error", max_depth=3, learning_rate=0.05, max_iter=500, min_samples_leaf=15,
                                             l2_regularization=1.0, early_stopping=True, validation_fraction=0.2,
                                             n_iter_no_change=25, categorical_features="from_dtype", random_state=0)
    cat = [c for c in X.columns if isinstance(X[c].dtype, pd.CategoricalDtype)]
    num = [c for c in X.columns if c not in cat]
    pre = ColumnTransformer([
        ("num", make_pipeline(SimpleImputer(strategy="median", add_indicator=True), StandardScaler()), num),
        ("cat", OneHotEncoder(handle_unknown="ignore", min_frequency=5, sparse_output=False), cat)])
    return make_pipeline(pre, RidgeCV(alphas=np.logspace(-1, 4, 21)))


def cross_fit(kind, X, y, folds):
    """Out-of-fold predictions of y; folds: list of (train index, test index)."""
    pred = pd.Series(np.nan, index=X.index)
    models = []
    for train, test in folds:
        model = make_learner(kind, X).fit(X.loc[train], y.loc[train])
        pred.loc[test] = model.predict(X.loc[test])
        models.append((model, test))
    return pred, models


def manufacturer_folds(groups):
    """Leave-one-manufacturer-out: [(train index, test index)] over the index of ``groups``."""
    return [(groups.index[groups != g], groups.index[groups == g]) for g in groups.unique()]


def permutation_importance(models, X, y_true_log_mpg, base_log_pred, repeats=3, seed=0):
    """Held-out permutation importance: each feature permuted over all vehicles, each vehicle
    re-predicted by its own fold's model. Returns {feature: (drop of the share within 5 %,
    rise of the RMS log error)}."""
    rng = np.random.default_rng(seed)

    def score(Xp):
        corr = pd.Series(np.nan, index=X.index)
        for model, test in models:
            corr.loc[test] = model.predict(Xp.loc[test])
        e = base_log_pred + corr - y_true_log_mpg
        return float(np.mean(np.abs(np.expm1(e)) <= WITHIN)), float(np.sqrt(np.mean(e ** 2)))

    w0, r0 = score(X)
    out = {}
    for col in X.columns:
        ws, rs = [], []
        for _ in range(repeats):
            Xp = X.copy()
            Xp[col] = X[col].to_numpy()[rng.permutation(len(X))]
            w, r = score(Xp)
            ws.append(w0 - w)
            rs.append(r - r0)
        out[col] = (float(np.mean(ws)), float(np.mean(rs)))
    return out


def learner_bound(table, vehicles, rows, outer, plain_pred, kinds=("boosting", "ridge"), importance=True):
    """Per test, feature set and learner: the summary of the corrected held-out errors, and
    the permutation importance of the boosting model."""
    results = {}
    for test in TESTS:
        sets = feature_sets(table, vehicles, rows, test)
        measured = table[test]
        keep = measured.notna() & plain_pred[test].notna()
        idx = table.index[keep]
        groups = table.manufacturer[keep]
        log_meas = np.log(measured[keep])
        # held-out physics of each vehicle and the training targets of each outer fold
        held = pd.Series({i: outer[table.manufacturer[i]].loc[i, test] for i in idx})
        res = {"physics": efe.summary(held / measured[keep] - 1.0)}
        for name, X in sets.items():
            X, _ = _prepare(X.loc[idx])
            for kind in kinds:
                if name == "c":
                    corr, models = _vehicle_grouped(kind, X, log_meas, np.log(plain_pred[test][keep]), table.loc[idx])
                    base = np.log(plain_pred[test][keep])
                else:
                    corr, models = _nested(kind, X, log_meas, outer, test, groups)
                    base = np.log(held)
                e = np.expm1(base + corr - log_meas)
                entry = {"summary": efe.summary(e)}
                if importance and kind == "boosting":
                    imp = permutation_importance(models, X, log_meas, base)
                    entry["importance"] = dict(sorted(imp.items(), key=lambda kv: -kv[1][1])[:10])
                res[f"{name}/{kind}"] = entry
                print(f"{test} {name}/{kind}: {_fmt(entry['summary'])}", flush=True)
        results[test] = res
    return results


def _nested(kind, X, log_meas, outer, test, groups):
    """Correction of each held-out manufacturer M trained on the other manufacturers' residuals
    against physics fitted without M (and without their own manufacturer)."""
    corr = pd.Series(np.nan, index=X.index)
    models = []
    for train, held in manufacturer_folds(groups):
        m = groups.loc[held[0]]
        base = np.log(outer[m][test].reindex(X.index))
        y = log_meas - base
        model = make_learner(kind, X).fit(X.loc[train], y.loc[train])
        corr.loc[held] = model.predict(X.loc[held])
        models.append((model, held))
    return corr, models


def _vehicle_grouped(kind, X, log_meas, base, table, n_folds=10):
    """Reference (c): 10 folds grouped by test vehicle, manufacturer seen in training."""
    from sklearn.model_selection import GroupKFold

    tv = table.vehicle_id.str.rsplit("_c", n=1).str[0]
    folds = [(X.index[a], X.index[b]) for a, b in GroupKFold(n_splits=n_folds).split(X, groups=tv)]
    return cross_fit(kind, X, log_meas - base, folds)


def _fmt(s):
    return f"n={s['n']} mean={s['mean']:+.3f} median|e|={s['median_abs']:.3f} within5={s['within_5pct']:.3f}"


def peer_correction(err, table, rows, keys=("manufacturer", "engine code", "test group", "twin group"),
                    vehicles=None):
    """Reference only (uses other vehicles' measured values of the same group, so not a model of
    the inputs): each vehicle's held-out physics error corrected by the median log error of the
    OTHER vehicles of its group (manufacturer, manufacturer + engine code, EPA test group, twin
    group); vehicles without a peer keep the physics error. Where the residual information lives."""
    facts = rows.groupby("vehicle_id")[["Engine Code", "Actual Tested Testgroup"]].first()
    facts = facts.reindex(table.vehicle_id)
    key_of = {"manufacturer": table.manufacturer.to_numpy(),
              "engine code": (table.manufacturer + "|" + facts["Engine Code"].fillna("?").to_numpy()).to_numpy(),
              "test group": facts["Actual Tested Testgroup"].fillna("?").to_numpy()}
    if vehicles is not None:
        ids, key = input_key(vehicles)
        key_of["twin group"] = pd.Series(key.to_numpy(), index=ids.to_numpy()).reindex(table.vehicle_id).to_numpy()
    out = {}
    for test in TESTS:
        lg = np.log1p(err[test]).to_numpy()
        res = {}
        for name in keys:
            if name not in key_of:
                continue
            frame = pd.DataFrame({"g": key_of[name], "e": lg}).dropna()
            corrected, peers = [], 0
            for _, x in frame.groupby("g"):
                e = x.e.to_numpy()
                if e.size == 1:
                    corrected.append(e)
                    continue
                peers += e.size
                others = np.array([np.median(np.delete(e, i)) for i in range(e.size)])
                corrected.append(e - others)
            c = np.expm1(np.concatenate(corrected))
            res[name] = dict(with_peer=peers / len(frame), **efe.summary(c))
        out[test] = res
    return out


# ----------------------------------------------------------------------------- 4. protocol
def test_fuel_effect(rows, table, err):
    """Test fuels of the modelled vehicles' rows and the held-out residual per fuel group."""
    out = {"fuels_of_modelled_rows": rows["Test Fuel Type Description"].value_counts().to_dict()}
    for test in TESTS:
        fuel = rows[rows.test == test].groupby("vehicle_id")["Test Fuel Type Description"].agg(_first_text)
        e = err[test].set_axis(table.vehicle_id)
        frame = pd.DataFrame({"fuel": fuel, "e": e.reindex(fuel.index)}).dropna()
        out[test] = {k: efe.summary(v.e) for k, v in frame.groupby("fuel")}
    return out


def carbon_balance_check(rows):
    """mpg x carbon emissions (0.866 HC + 0.429 CO + 0.273 CO2, g/mi) per fuel: constant for one
    fuel if RND_ADJ_FE follows the carbon balance of 40 CFR 600.113 (Tier 2 gasoline: about
    2,427 = 5174e4 CWF SG / (0.6 SG NHV + 5471))."""
    num = lambda c: pd.to_numeric(rows[c], errors="coerce").fillna(0.0)  # noqa: E731
    k = rows.mpg * (0.866 * num("THC (g/mi)") + 0.429 * num("CO (g/mi)") + 0.273 * num("CO2 (g/mi)"))
    frame = pd.DataFrame({"fuel": rows["Test Fuel Type Description"], "k": k})
    return {f: dict(n=int(len(v)), median=float(v.k.median()), p05=float(v.k.quantile(0.05)),
                    p95=float(v.k.quantile(0.95))) for f, v in frame[frame.k > 0].groupby("fuel")}


def drive_quality_effect(table, vehicles, rows, outer, plain_pred):
    """How much of the held-out residual the DT ratings explain: ridge on the three ratings of
    the test's own runs, nested leave-one-manufacturer-out, and their correlation with it."""
    out = {}
    for test in TESTS:
        f = list_features(rows, table, test)[["dt_iwr", "dt_ascr", "dt_eer"]]
        keep = table[test].notna() & plain_pred[test].notna() & f.notna().all(axis=1)
        idx = table.index[keep]
        groups = table.manufacturer[keep]
        held = pd.Series({i: outer[table.manufacturer[i]].loc[i, test] for i in idx})
        log_meas = np.log(table[test][keep])
        resid = log_meas - np.log(held)
        corr, _ = _nested("ridge", f.loc[idx], log_meas, outer, test, groups)
        e0, e1 = np.expm1(-resid), np.expm1(np.log(held) + corr - log_meas)
        out[test] = dict(n=int(keep.sum()), correlation={c: float(np.corrcoef(f.loc[idx, c], resid)[0, 1]) for c in f},
                         explained_var=float(1 - np.var(resid - corr) / np.var(resid)),
                         within_5pct_before=float(np.mean(np.abs(e0) <= WITHIN)),
                         within_5pct_after=float(np.mean(np.abs(e1) <= WITHIN)),
                         median_abs_before=float(np.median(np.abs(e0))), median_abs_after=float(np.median(np.abs(e1))))
    return out


# ----------------------------------------------------------------------------- main
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", type=Path, help="write every number to this file")
    ap.add_argument("--quick", action="store_true", help="no permutation importance")
    args = ap.parse_args(argv)
    t0 = time.time()
    specs, table = epa_fleet()
    vehicles = import_test_car_list(TSTCAR).vehicles
    rows = own_fuel_rows(test_rows(), table)
    report = {"repeatability": repeatability(rows)}
    groups = twin_groups(vehicles)
    report["twins"] = twin_bound(groups, table)
    _print("repeatability", report["repeatability"])
    _print("twins", report["twins"])
    d = efe.build_dataset(specs, table)
    plain_pred, _ = efe.held_out(d, table)
    err = efe.relative_errors(plain_pred, table)
    outer = nested_physics(d, table)
    report["test_fuel"] = test_fuel_effect(rows, table, err)
    report["carbon_balance"] = carbon_balance_check(pd.concat([test_rows(), test_rows(derived=True)]))
    report["adfe"] = adfe_road_load()
    _print("analytically derived rows", report["adfe"])
    report["drive_quality"] = drive_quality_effect(table, vehicles, rows, outer, plain_pred)
    report["data_limits"] = data_limits(rows, table, err)
    report["peer_correction"] = peer_correction(err, table, rows, vehicles=vehicles)
    _print("peer correction (reference)", report["peer_correction"])
    _print("data limits", report["data_limits"])
    _print("test fuel", report["test_fuel"])
    _print("carbon balance", report["carbon_balance"])
    _print("drive quality", report["drive_quality"])
    report["learner"] = learner_bound(table, vehicles, rows, outer, plain_pred, importance=not args.quick)
    _print("learner", report["learner"])
    print(f"done in {time.time() - t0:.0f} s")
    if args.json:
        args.json.write_text(json.dumps(report, indent=1, default=float))
    return report


def _print(title, obj):
    print(f"== {title}")
    print(json.dumps(obj, indent=1, default=float))


if __name__ == "__main__":
    main()
