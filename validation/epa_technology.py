"""Light-duty fuel economy with the information that exists, on the EPA 2022 Test Car List,
held out by manufacturer (docs/validation-epa.md "Technology, one measured number, bias"):

    PYTHONPATH=. python validation/epa_technology.py [--write] [--subset N]

Side by side, on the same vehicles (those that join to EPA's OMEGA vehicles and those that
do not; fleetrun/epa/technology.py):

1. physics only: every vehicle simulated without its technology classes, the fuel-equation
   constants fitted held out (validation/epa_fuel_economy.py);
2. physics + technology: the classes of the join as physics (fleetrun/simulation/technology.py),
   the constants and the start-stop stop power fitted held out;
3. drive-mode pairs: configurations of one test vehicle with identical rows are one vehicle
   driven in two modes; its measured value per test is their label-style (harmonic) mean;
4. + one measured number: each vehicle's measured FTP composite calibrates its efficiency
   (FTP exact), and the share ``transfer_share`` of that correction (in log) carries to the
   other cycles: one global constant, fitted with manufacturers held out; beside it the
   transfer on the physical split of the losses (``split_transfer``): the FTP's correction
   spread over the vehicle's cold-start fuel, its Willans-slope fuel (brake, high load,
   acceleration) and its offset fuel (friction, pumping, accessories, stops) with global
   weights fitted held out, which reach HWFET and US06 in their own proportions;
5. the fleet-level bias in total gallons (55 % FTP / 45 % HWFET per vehicle, equal miles),
   estimated without each manufacturer and removed from its predictions; random
   100-vehicle fleets.

"Joined" are the vehicles whose configuration joins an OMEGA vehicle by its road load; the
others ("engine classes") carry their engine's classes (fleetrun/epa/technology.py).
``--residuals``: where the held-out error comes from (by displacement, power to weight,
gearbox, gears, class, road load; HWFET - FTP) and how much of it a flexible learner on the
list's own columns finds, held out (scikit-learn, the ``validation`` extra).

``--write``: models/technology.toml [fitted] transfer_share (the stop power: epa_fuel_economy.py --write) and
models/fuel_economy_bias.toml.
"""
from __future__ import annotations

import argparse
import dataclasses
import datetime
import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import epa_fuel_economy as efe  # noqa: E402
from epa_alpha import alpha_table  # noqa: E402
from epa_table import epa_fleet, udds_bag_miles as udds_miles  # noqa: E402

from fleetrun.cycles import ftp_weighted_per_mile  # noqa: E402
from fleetrun.simulation.coastdown_driveline import VARIANTS  # noqa: E402
from fleetrun.epa.technology import match_configuration  # noqa: E402
from fleetrun.simulation.engine import FUEL_TERMS  # noqa: E402
from fleetrun.simulation.params import GEARBOX_TYPES, vehicle_arrays  # noqa: E402

TESTS = ("FTP", "HWFET", "US06")
ARRB_COLUMN = "X_transient_arrb"
#: the acceleration term's form (``--transient-form``; docs/validation-epa.md "acceleration term in
#: ARRB's form"): "constant" k_tr P_acc+ (the fuel equation), "arrb" k_a max(a, 0) P_acc+ in its place,
#: "both" the two side by side (the ARRB one as an extra column: gasoline only)
TRANSIENT_FORMS = ("constant", "arrb", "both")
TRANSIENT_FORM = "constant"
#: the cold start's heat-capacity basis (``--cold-start-basis``; docs/validation-epa.md "Second
#: hypothesis"): grid of c_m [kJ/(K kg)] x gasoline enrichment, fitted as epa_fuel_economy.fit_thermal
MASS_GRID = {"heat_capacity_kJ_per_K_per_kg": (0.2, 0.285, 0.42, 0.65, 1.0),
             "enrichment_gasoline": (0.05, 0.1, 0.15, 0.2, 0.3)}


def mass_variant(heat_capacity_kJ_per_K_per_kg, enrichment_gasoline):
    """The stored cold-start constants with the node's heat capacity on the engine-mass basis."""
    k = efe.thermal_variant(efe.thermal_constants().heat_capacity_J_per_K_per_L / 1e3, enrichment_gasoline)
    return dataclasses.replace(k, heat_capacity_basis="engine_mass",
                               heat_capacity_J_per_K_per_kg=1e3 * heat_capacity_kJ_per_K_per_kg)


def mass_basis_thermal(specs, table):
    """Fit the mass-basis cold start (grid, as the displacement one) and set it for the runs;
    returns the printed lines."""
    th = efe.fit_thermal(specs, table, MASS_GRID, mass_variant)
    efe.THERMAL = mass_variant(*th["best"])
    held = th["heldout_ratio_error"]
    return [f"cold start on the engine-mass basis: chosen (c_m kJ/(K kg), enrichment) {th['best']}; folds chose "
            f"{sorted(set(th['folds'].values()))}; RMS log error {th['grid_rmse'][th['best']]:.4f}; held-out bag 1 / bag 3 "
            f"within 5 % {np.mean(np.abs(held) <= 0.05):.1%} (median {np.median(held):+.1%})"]
CITY_SHARE = 0.55          # EPA's city / highway weighting of the combined figure (40 CFR 600.210)
FLEET_SIZE, FLEET_DRAWS = 100, 2000


def test_vehicle_of(vehicle_id: str) -> str:
    """``<Test Vehicle ID>_c<configuration>`` -> the test vehicle id."""
    return re.sub(r"_c\d+$", "", vehicle_id)


def drive_mode_groups(specs) -> np.ndarray:
    """Representative index per vehicle: configurations of one test vehicle whose rows are equal
    in everything but the id (the simulation cannot tell them apart) form one group."""
    first: dict = {}
    rep = np.arange(len(specs))
    for i, v in enumerate(specs):
        key = (test_vehicle_of(v.vehicle_id), v.physics_key())
        rep[i] = first.setdefault(key, i)
    return rep


def pair_targets(table: pd.DataFrame, rep: np.ndarray) -> pd.DataFrame:
    """The table with each group's measured mpg replaced by the harmonic mean of its members'
    (the label-style average: mean fuel per mile), rows of non-representatives kept (dropped later)."""
    out = table.copy()
    tests = [c for c in table.columns if c in efe.REPORTED or c.startswith("FTP:") or c == "UDDS:hot"]
    for t in tests:
        gpm = (1.0 / table[t]).groupby(rep).transform("mean")   # NaN members skipped
        out[t] = 1.0 / gpm
    return out


#: the friction's form (``--friction-form``; docs/validation-epa.md "friction by bore and by speed
#: squared"): "chen_flynn" the fuel equation's, "bore" + the PNH ring (B_ref/B)^2 and skirt c_m B_ref/B
#: terms, "speed2" + Chen & Flynn's c_m^2 term; their columns are offset fuel (loss_split)
FRICTION_FORMS = {"chen_flynn": (), "bore": ("X_friction_ring_bore", "X_friction_skirt_bore"),
                  "speed2": ("X_friction_piston_speed2",)}
FRICTION_FORM = "chen_flynn"
#: the Willans slope's form (``--slope-form``; docs/validation-epa.md "Hypothesis F3"): "constant"
#: the fuel equation's, "bore" + the brake work x B_ref / B (heat loss ~ surface / volume); slope fuel
SLOPE_FORMS = {"constant": (), "bore": ("X_brake_bore",)}
SLOPE_FORM = "constant"
#: cylinder deactivation's form (``--deactivation-form``; docs/validation-epa.md "Hypothesis D1"):
#: "pumping" the fuel equation's (the window's pumping share), "half_offset" + a fitted credit of the
#: deactivated half's gas-exchange loss [kPa] in the window (offset fuel)
DEACTIVATION_FORMS = {"pumping": (), "half_offset": ("X_deac_credit",)}
DEACTIVATION_FORM = "pumping"
#: the warm idle's form (``--idle-form``; docs/validation-epa.md "Hypothesis I1"): "equation" the fuel
#: equation at idle speed and zero load, "mep" + a fitted idle mean effective pressure [kPa] (offset
#: fuel), "mep_share" the same with start-stop's stop fuel as a share of the idle fuel (S1)
IDLE_FORMS = {"equation": (), "mep": ("X_idle_mep",), "mep_share": ("X_idle_mep",)}
IDLE_FORM = "equation"
BORE_REF_M = 0.086   # B_ref [m] of the bore forms (docs/validation-epa.md: 86 mm; about a square 2.0 L four, engine.stroke_m)


def stop_extra():
    """The extra columns of the technology fit: the start-stop stop power (and, with the
    transient form "both", the ARRB acceleration term; then the friction form's columns)."""
    arrb = (ARRB_COLUMN,) if TRANSIENT_FORM == "both" else ()
    return (efe.STOP + arrb + FRICTION_FORMS[FRICTION_FORM] + SLOPE_FORMS[SLOPE_FORM] + DEACTIVATION_FORMS[DEACTIVATION_FORM]
            + IDLE_FORMS[IDLE_FORM])


def with_bore_terms(d, specs):
    """The dataset with the bore columns: the friction sum x (B_ref / B)^2, the piston-speed
    friction sum x B_ref / B and the brake work x B_ref / B, B the model's bore (square engines:
    the stroke)."""
    ratio = BORE_REF_M / vehicle_arrays(specs).stroke_m[d.vehicle.to_numpy()]
    return d.assign(X_friction_ring_bore=d.S_friction.to_numpy() * ratio ** 2,
                    X_friction_skirt_bore=d.S_friction_piston_speed.to_numpy() * ratio,
                    X_brake_bore=d.S_brake.to_numpy() * ratio)


def transient_form(d):
    """The dataset with the acceleration term in the chosen form (``TRANSIENT_FORM``)."""
    return d.assign(S_transient=d[ARRB_COLUMN]) if TRANSIENT_FORM == "arrb" else d


def heldout_errors(d, table, keep, extra=()):
    """Held-out relative errors (vehicles x tests) of the vehicles ``keep``, the fits per fold."""
    d = d[d.vehicle.isin(np.flatnonzero(keep))]
    pred, folds = efe.held_out(d, table.iloc[np.flatnonzero(keep)].set_index(pd.Index(np.flatnonzero(keep))),
                               extra=extra)
    err = pd.DataFrame({t: pred[t] / table[t].to_numpy()[pred.index] - 1.0 for t in pred.columns})
    return err, pred, folds


def fit_transfer_share(err, manufacturer):
    """Per held-out manufacturer: sigma fitted on the others, log(1 + e_t) ~ sigma log(1 + e_FTP)
    over HWFET and US06; returns sigma per vehicle (its fold's) and the fold values."""
    a = np.log1p(err[["HWFET", "US06"]].to_numpy())
    b = np.log1p(err["FTP"].to_numpy())[:, None] * np.ones((1, 2))
    ok = np.isfinite(a) & np.isfinite(b)
    sigma, folds = np.full(len(err), np.nan), {}
    for g in np.unique(manufacturer):
        other = (manufacturer != g)[:, None] & ok
        folds[g] = float((a * b)[other].sum() / (b * b)[other].sum())
        sigma[manufacturer == g] = folds[g]
    return sigma, folds


def transfer_share_all(err) -> float:
    """sigma fitted on every vehicle (the value stored in models/technology.toml)."""
    a = np.log1p(err[["HWFET", "US06"]].to_numpy())
    b = np.log1p(err["FTP"].to_numpy())[:, None] * np.ones((1, 2))
    ok = np.isfinite(a) & np.isfinite(b)
    return float((a * b)[ok].sum() / (b * b)[ok].sum())


def one_number(err, sigma):
    """Errors after calibrating each vehicle on its measured FTP: FTP exact, the other tests'
    mpg divided by (1 + e_FTP)^sigma."""
    out = err.copy()
    scale = (1.0 + err["FTP"]) ** sigma
    for t in err.columns:
        out[t] = 0.0 if t == "FTP" else (1.0 + err[t]) / scale - 1.0
    out.loc[err["FTP"].isna(), :] = np.nan
    return out


#: term groups of the fuel equation (engine.FUEL_TERMS, then the stop-power column): the
#: Willans-slope fuel (brake, high load, acceleration) and the offset fuel (friction x 3,
#: throttle pumping, accessories, start-stop stops)
SLOPE_TERMS, OFFSET_TERMS = (0, 1, 7), (2, 3, 4, 5, 6)
SPLIT_GRID = np.round(np.arange(0.0, 0.3001, 0.01), 2)


def loss_split(d, fits, table, extra=None):
    """Per vehicle and test (FTP composite, HWFET, US06), the fuel per mile [g/mi] of each fold's
    prediction split into the slope, offset and cold-start parts: {"B", "O", "C"} -> tables."""
    extra = stop_extra() if extra is None else extra
    parts = []
    for g, coef in fits.items():
        dm = d[(d.manufacturer == g).to_numpy()]
        c = np.where((dm.fuel == "gasoline").to_numpy()[:, None], coef["gasoline"], coef["diesel"])
        terms = efe.design(dm, extra) * c
        warm, sim_warm = terms.sum(axis=1), (dm.sim_fuel_g - dm.cold_g).to_numpy()
        with np.errstate(divide="ignore", invalid="ignore"):
            cold = np.where(sim_warm > 0, dm.cold_g.to_numpy() * warm / sim_warm, 0.0)
        slope_extras = [len(FUEL_TERMS) + j for j, x in enumerate(extra) if x in (ARRB_COLUMN, "X_brake_bore")]
        offset = list(OFFSET_TERMS) + [len(FUEL_TERMS) + j for j, x in enumerate(extra)
                                  if x.startswith(("X_friction", "X_stop", "X_deac", "X_idle"))]
        slope = terms[:, SLOPE_TERMS].sum(1) + terms[:, slope_extras].sum(1)
        parts.append(pd.DataFrame(dict(vehicle=dm.vehicle.to_numpy(), test=dm.test.to_numpy(), miles=dm.miles.to_numpy(),
                                       B=slope, O=terms[:, offset].sum(1), C=cold)))
    rows = pd.concat(parts)
    return {k: _per_mile(rows, k) for k in "BOC"}


def _per_mile(rows, col):
    w = rows.pivot_table(index="vehicle", columns="test", values=[col, "miles"])
    bag = {b: (w[col][f"FTP:{b}"], w["miles"][f"FTP:{b}"]) for b in efe.BAGS}
    out = {"FTP": ftp_weighted_per_mile(*(bag[b][0] for b in efe.BAGS), *(bag[b][1] for b in efe.BAGS))}
    out.update({t: w[col][t] / w["miles"][t] for t in ("HWFET", "US06")})
    return pd.DataFrame(out)


def split_transfer(split, err, weights):
    """Errors after calibrating each vehicle on its measured FTP by adding delta x (w_B B + w_O O
    + C) to every test's fuel, delta such that the FTP is exact (``weights`` = (w_B, w_O), the
    cold start's weight 1): the correction reaches each test in proportion to the parts it has."""
    B, O, C = (split[k].loc[err.index, list(TESTS)].to_numpy() for k in "BOC")
    pred = B + O + C
    meas = pred * (1.0 + err[list(TESTS)].to_numpy())  # g/mi measured = predicted x (1 + mpg error)
    part = weights[0] * B + weights[1] * O + C
    delta = (meas[:, :1] - pred[:, :1]) / part[:, :1]
    return pd.DataFrame(meas / (pred + part * delta) - 1.0, index=err.index, columns=list(TESTS))


def fit_split_transfer(split, err, manufacturer):
    """Weights (w_B, w_O) on SPLIT_GRID by least squares of the log errors of HWFET and US06, per
    held-out manufacturer on the others; returns the held-out errors, fold weights, all-vehicle weights."""
    cost = {}
    for wb in SPLIT_GRID:
        for wo in SPLIT_GRID:
            e = np.log1p(split_transfer(split, err, (wb, wo))[["HWFET", "US06"]].to_numpy()) ** 2
            cost[(float(wb), float(wo))] = np.where(np.isfinite(e), e, 0.0).sum(axis=1)
    out, folds = err[list(TESTS)] * np.nan, {}
    for g in np.unique(manufacturer):
        folds[g] = min(cost, key=lambda w: cost[w][manufacturer != g].sum())
        out.loc[manufacturer == g] = split_transfer(split, err, folds[g]).loc[manufacturer == g]
    return out, folds, min(cost, key=lambda w: cost[w].sum())


def gallons(err, table, index):
    """Predicted and measured gallons per mile (55 % FTP, 45 % HWFET) of the vehicles ``index``
    that have both."""
    meas = CITY_SHARE / table["FTP"].to_numpy()[index] + (1 - CITY_SHARE) / table["HWFET"].to_numpy()[index]
    pred = (CITY_SHARE / (table["FTP"].to_numpy()[index] * (1 + err["FTP"].to_numpy()))
            + (1 - CITY_SHARE) / (table["HWFET"].to_numpy()[index] * (1 + err["HWFET"].to_numpy())))
    ok = np.isfinite(meas) & np.isfinite(pred)
    return pred[ok], meas[ok], np.asarray(index)[ok]


def bias_report(err, table, seed=20221):
    """Total gallons error of the whole list, the same with the bias estimated without each
    manufacturer removed, and the 5-95 % range of random 100-vehicle fleets (both)."""
    pred, meas, idx = gallons(err, table, err.index.to_numpy())
    mf = table.manufacturer.to_numpy()[idx]
    corrected = pred.copy()
    factors = {}
    for g in np.unique(mf):
        o = mf != g
        factors[g] = meas[o].sum() / pred[o].sum()
        corrected[mf == g] *= factors[g]
    rng = np.random.default_rng(seed)
    draws = np.array([rng.choice(len(pred), FLEET_SIZE, replace=False) for _ in range(FLEET_DRAWS)])
    fleets = pred[draws].sum(1) / meas[draws].sum(1) - 1.0
    fleets_c = corrected[draws].sum(1) / meas[draws].sum(1) - 1.0
    return dict(n=len(pred), total=pred.sum() / meas.sum() - 1.0, total_corrected=corrected.sum() / meas.sum() - 1.0,
                bias_all=pred.sum() / meas.sum() - 1.0, fold_factors=factors,
                fleets=(np.quantile(fleets, 0.05), np.quantile(fleets, 0.95)),
                fleets_corrected=(np.quantile(fleets_c, 0.05), np.quantile(fleets_c, 0.95)))


def line(label, err, rows=None):
    e = err if rows is None else err.loc[err.index.intersection(rows)]
    cells = []
    for t in TESTS:
        x = e[t].dropna().to_numpy()
        cells.append(f"{t} n={x.size} mean {x.mean():+.1%} med|e| {np.median(np.abs(x)):.1%} "
                     f"within 5 % {np.mean(np.abs(x) <= 0.05):.1%}" if x.size else f"{t} n=0")
    return f"{label:44s} | " + " | ".join(cells)


def datasets(specs, table):
    """(physics only, physics + technology) datasets (validation/epa_fuel_economy.build_dataset)."""
    bare = [dataclasses.replace(v, technology=None) for v in specs]
    return tuple(with_bore_terms(transient_form(efe.build_dataset(s, table)), specs) for s in (bare, specs))


def omega_matches(specs):
    """Each vehicle's match by the import's join (fleetrun/epa/technology.py)."""
    return [match_configuration(v.manufacturer, v.engine_displacement_L, v.coastdown_A_lbf, v.coastdown_B_lbf_per_mph,
                                v.coastdown_C_lbf_per_mph2) for v in specs]


def omega_classes(specs) -> list[str]:
    """Each vehicle's OMEGA class by the import's join ('' when it does not join)."""
    return [m.cost_curve_class for m in omega_matches(specs)]


def alpha_errors(specs, table, index):
    """ALPHA's errors (vehicles ``index`` x tests) as published, and with its mean log error per
    test estimated without each manufacturer removed (its CO2-to-mpg conversion and test-fuel
    differences are one constant per test)."""
    a = alpha_table([specs[i] for i in index], omega_classes([specs[i] for i in index]))
    raw = pd.DataFrame({t: a[t].to_numpy() / table[t].to_numpy()[index] - 1.0 for t in TESTS}, index=index)
    mf = table.manufacturer.to_numpy()[index]
    scaled = raw.copy()
    for t in TESTS:
        log = np.log1p(raw[t].to_numpy())
        for g in np.unique(mf):
            other = (mf != g) & np.isfinite(log)
            scaled.loc[mf == g, t] = np.expm1(log[mf == g] - log[other].mean())
    return raw, scaled


def blend(err_a, err_b):
    """Geometric mean of two predictions' mpg (equal weights, nothing fitted)."""
    common = err_a.index.intersection(err_b.index)
    return pd.DataFrame({t: np.expm1(0.5 * (np.log1p(err_a.loc[common, t]) + np.log1p(err_b.loc[common, t])))
                         for t in TESTS}, index=common)


def run(specs, table):
    joined = np.array([m.join == "road_load" for m in omega_matches(specs)])
    rep = drive_mode_groups(specs)
    everyone = np.ones(len(specs), bool)
    single = rep == np.arange(len(specs))
    paired = pair_targets(table, rep)
    d0, d1 = datasets(specs, table)
    r = {}
    r["physics"], _, _ = heldout_errors(d0, table, everyone)
    r["technology"], _, r["folds"] = heldout_errors(d1, table, everyone, extra=stop_extra())
    d1p = d1.copy()
    d1p["measured_mpg"] = [paired[t].to_numpy()[v] for t, v in zip(d1p.test, d1p.vehicle)]
    d1p["measured_fuel_g"] = d1p.miles / d1p.measured_mpg * efe.GAL_L * d1p.rho * 1000.0
    r["pairs"], _, r["folds_pairs"] = heldout_errors(d1p, paired, single, extra=stop_extra())
    d0p = d0.assign(measured_mpg=d1p.measured_mpg.to_numpy(), measured_fuel_g=d1p.measured_fuel_g.to_numpy())
    r["physics_pairs"], _, _ = heldout_errors(d0p, paired, single)
    mf = table.manufacturer.to_numpy()
    sigma, r["sigma_folds"] = fit_transfer_share(r["pairs"], mf[r["pairs"].index])
    r["one_number"] = one_number(r["pairs"], sigma)
    r["sigma_all"] = transfer_share_all(r["pairs"])
    r["full_transfer"] = one_number(r["pairs"], np.ones(len(r["pairs"])))
    split = loss_split(d1p[d1p.vehicle.isin(np.flatnonzero(single))], r["folds_pairs"], table, extra=stop_extra())
    r["split"], r["split_folds"], r["split_all"] = fit_split_transfer(split, r["pairs"], mf[r["pairs"].index])
    r["split_parts"] = {k: float((v.FTP / sum(split[j].FTP for j in "BOC")).median()) for k, v in split.items()}
    r["final"] = efe.fit(d1p[d1p.vehicle.isin(np.flatnonzero(single))], extra=stop_extra())
    r["dataset_pairs"] = d1p[d1p.vehicle.isin(np.flatnonzero(single))]
    r.update(joined=np.flatnonzero(joined), unjoined=np.flatnonzero(~joined), paired_table=paired, single=single)
    alpha_rows = r["pairs"].index.intersection(r["joined"])
    r["alpha"], r["alpha_scaled"] = alpha_errors(specs, paired, alpha_rows.to_numpy())
    r["blend"] = blend(r["pairs"], r["alpha_scaled"])
    s_b, _ = fit_transfer_share(r["blend"], mf[r["blend"].index])
    r["blend_one_number"] = one_number(r["blend"], s_b)
    return r


def friction_kPa(fit, col):
    """A friction-form column's fitted coefficient times the Willans slope's efficiency: the
    FMEP it adds at B = B_ref [kPa; kPa s/m for the skirt, kPa (s/m)^2 for c_m^2]."""
    c = fit["gasoline"]
    return float(c[len(FUEL_TERMS) + stop_extra().index(col)] / c[0])


def report(r, table):
    lines = []
    for name, key in (("physics only", "physics"), ("physics + technology", "technology"),
                      ("physics only, drive-mode pairs", "physics_pairs"),
                      ("physics + technology, drive-mode pairs", "pairs"),
                      ("+ one measured FTP (transfer share fitted)", "one_number"),
                      ("+ one measured FTP (full transfer)", "full_transfer"),
                      ("+ one measured FTP (physical split)", "split")):
        for rows_name, label in (("joined", "joined"), ("unjoined", "engine classes"), (None, "all")):
            rows = None if rows_name is None else r[rows_name]
            lines.append(line(f"{name} [{label}]", r[key], rows))
    for name, key in (("ALPHA surfaces as published", "alpha"), ("ALPHA, mean error removed held out", "alpha_scaled"),
                      ("fleetrun + ALPHA geometric mean", "blend"), ("  + one measured FTP", "blend_one_number")):
        lines.append(line(f"{name} [joined]", r[key]))
    a, f = r["alpha_scaled"], r["pairs"].loc[r["alpha_scaled"].index]
    lines.append("correlation of fleetrun and ALPHA errors (joined): " + ", ".join(
        f"{t} {np.corrcoef(*[x[t].to_numpy()[np.isfinite(x[t]) & np.isfinite(y[t])] for x, y in ((a, f), (f, a))])[0, 1]:.2f}"
        for t in TESTS))
    s = np.array(list(r["sigma_folds"].values()))
    lines.append(f"transfer share: all {r['sigma_all']:.3f}; folds {s.min():.3f}-{s.max():.3f}")
    w = np.array(list(r["split_folds"].values()))
    lines.append(f"physical split weights (w_B, w_O; cold start 1): all {r['split_all']}; folds w_B "
                 f"{w[:, 0].min():.2f}-{w[:, 0].max():.2f}, w_O {w[:, 1].min():.2f}-{w[:, 1].max():.2f}; median FTP fuel "
                 "shares B/O/C " + "/".join(f"{r['split_parts'][k]:.3f}" for k in "BOC"))
    n = len(FUEL_TERMS)
    for j, col in enumerate(efe.STOP):
        stop = [f["gasoline"][n + j] for f in r["folds"].values()]
        unit = "share of the idle fuel power" if col == "X_stop_off_idle" else "stop power [W]"
        lines.append(f"start-stop {unit}: final {r['final']['gasoline'][n + j]:.4g}; folds {min(stop):.4g}-{max(stop):.4g}")
    if TRANSIENT_FORM != "constant":
        j = n + stop_extra().index(ARRB_COLUMN) if TRANSIENT_FORM == "both" else n - 1
        k = np.array([f["gasoline"][j] / f["gasoline"][0] for f in r["folds"].values()])
        kf = r["final"]["gasoline"][j] / r["final"]["gasoline"][0]
        lines.append(f"ARRB acceleration coefficient k_a [s^2/m] ({TRANSIENT_FORM}): final {kf:.3f}; folds {k.min():.3f}-{k.max():.3f}")
    for col in IDLE_FORMS[IDLE_FORM]:
        k = [f["gasoline"][n + stop_extra().index(col)] / f["gasoline"][0] for f in r["folds"].values()]
        kf = r["final"]["gasoline"][n + stop_extra().index(col)] / r["final"]["gasoline"][0]
        lines.append(f"idle mean effective pressure [kPa]: final {kf:.2f}; folds {min(k):.2f}-{max(k):.2f}")
    for col in DEACTIVATION_FORMS[DEACTIVATION_FORM]:
        k = [f["gasoline"][n + stop_extra().index(col)] / f["gasoline"][0] for f in r["folds"].values()]
        kf = r["final"]["gasoline"][n + stop_extra().index(col)] / r["final"]["gasoline"][0]
        lines.append(f"deactivation credit [kPa of the deactivated half]: final {kf:.2f}; folds {min(k):.2f}-{max(k):.2f}")
    for col in SLOPE_FORMS[SLOPE_FORM]:
        k = [f["gasoline"][n + stop_extra().index(col)] / f["gasoline"][0] for f in r["folds"].values()]
        lines.append(f"slope form {SLOPE_FORM}: {col} coefficient / Willans slope: final "
                     f"{r['final']['gasoline'][n + stop_extra().index(col)] / r['final']['gasoline'][0]:.4f}; "
                     f"folds {min(k):.4f}-{max(k):.4f}")
    for col in FRICTION_FORMS[FRICTION_FORM]:
        k = [friction_kPa(f, col) for f in r["folds"].values()]
        kf = friction_kPa(r["final"], col)
        lines.append(f"friction form {FRICTION_FORM}: {col} coefficient x eta_indicated [kPa, or kPa (s/m)^2]: final "
                     f"{kf:.3f}; folds {min(k):.3f}-{max(k):.3f}")
    lines.append("constants (final): " + str({k: round(float(v), 4) for k, v in efe.constants_of(r["final"]["gasoline"][:8]).items()}))
    for key in ("physics_pairs", "pairs", "one_number"):
        b = bias_report(r[key], r["paired_table"])
        lines.append(f"gallons [{key}]: n={b['n']} whole list {b['total']:+.2%}, bias removed held out "
                     f"{b['total_corrected']:+.2%}; 100-vehicle fleets 5-95 % {b['fleets'][0]:+.2%}..{b['fleets'][1]:+.2%}, "
                     f"bias removed {b['fleets_corrected'][0]:+.2%}..{b['fleets_corrected'][1]:+.2%}")
        r[f"bias_{key}"] = b
    return lines


LBF_N, MPH_M_S = 4.4482216152605, 0.44704


def features(specs, table) -> pd.DataFrame:
    """Per vehicle, what the Vehicles row says (for ``--residuals``): displacement [L], power to
    weight [W/kg], gearbox type, gear count, classes, road load at 50 mph per test mass [W/kg],
    N/V [rpm/mph], cylinders, drive, converter lockup."""
    v50 = 50.0 * MPH_M_S
    rl = np.array([(v.coastdown_A_lbf + 50.0 * v.coastdown_B_lbf_per_mph + 2500.0 * v.coastdown_C_lbf_per_mph2)
                   * LBF_N * v50 for v in specs])
    return pd.DataFrame(dict(
        displacement_L=table.displacement_L, power_to_weight_W_per_kg=1e3 * table.rated_power_kW / table.test_weight_kg,
        gearbox=table.gearbox_type, gears=table.gears, technology=[v.technology or "" for v in specs],
        road_load_50mph_W_per_kg=rl / table.test_weight_kg, nv_rpm_per_mph=[v.nv_ratio_rpm_per_mph for v in specs],
        cylinders=table.cylinders, drive=table.configuration, lockup=[v.converter_lockup or "" for v in specs]))


RESIDUAL_BINS = {"displacement_L": [0, 1.6, 2.1, 2.6, 3.1, 4.0, 5.0, 9.0],
                 "power_to_weight_W_per_kg": [0, 60, 80, 100, 130, 170, 250, 600],
                 "road_load_50mph_W_per_kg": [0, 4.5, 5.0, 5.5, 6.0, 6.5, 10.0],
                 "nv_rpm_per_mph": [0, 20, 25, 30, 35, 40, 60], "gearbox": None, "gears": None, "technology": None}


def residual_tables(err, feats):
    """Median held-out error, share within 5 % and median HWFET - FTP per group of each feature."""
    lines = []
    e = err.assign(hwfet_minus_ftp=err["HWFET"] - err["FTP"])
    for name, bins in RESIDUAL_BINS.items():
        g = feats.loc[e.index, name]
        g = pd.cut(g, bins).astype(str) if bins else g.astype(str)
        if name == "technology":
            g = g.where(g.map(g.value_counts()) >= 8, "(classes of < 8 vehicles)")
        lines.append(f"-- by {name}: n | median FTP / HWFET / US06 | within 5 % FTP / HWFET / US06 | median HWFET - FTP")
        for key, idx in e.groupby(g.to_numpy()).groups.items():
            x = e.loc[idx]
            lines.append(f"   {key:40s} {len(x):4d} | " + " / ".join(f"{x[t].median():+.1%}" for t in TESTS) + " | "
                         + " / ".join(f"{np.mean(np.abs(x[t].dropna()) <= 0.05):.0%}" for t in TESTS)
                         + f" | {x.hwfet_minus_ftp.median():+.1%}")
    return lines


def learner_bound(err, feats, manufacturer, with_ftp=False):
    """Share within 5 % per test after a gradient-boosted learner on the Vehicles row's columns
    (and the vehicle's own FTP error when ``with_ftp``) predicts each held-out manufacturer's
    log error from the others': what the row's information could still remove."""
    from sklearn.ensemble import HistGradientBoostingRegressor

    X = pd.get_dummies(feats.loc[err.index], columns=["gearbox", "drive", "lockup"], dtype=float)
    for name in ("start_stop", "mild_hybrid_48v", "p2_hybrid", "atkinson", "miller", "cylinder_deactivation", "turbo"):
        X[name] = X.technology.str.contains(name).astype(float)
    X = X.drop(columns="technology")
    if with_ftp:
        X["ftp_log_error"] = np.log1p(err["FTP"].to_numpy())
    out = {}
    for t in (("HWFET", "US06") if with_ftp else TESTS):
        y = np.log1p(err[t].to_numpy())
        ok, pred = np.isfinite(y), np.full(len(y), np.nan)      # the learner takes missing inputs
        for g in np.unique(manufacturer):
            fit_rows, rows = ok & (manufacturer != g), ok & (manufacturer == g)
            if rows.any():
                model = HistGradientBoostingRegressor(max_iter=200, max_depth=3, learning_rate=0.05, random_state=0)
                pred[rows] = model.fit(X[fit_rows], y[fit_rows]).predict(X[rows])
        left = np.expm1(y - pred)[ok]
        out[t] = (float(np.mean(np.abs(err[t].to_numpy()[ok]) <= 0.05)), float(np.mean(np.abs(left) <= 0.05)),
                  float(1.0 - np.var(y[ok] - pred[ok]) / np.var(y[ok])))
    return out


def road_load_work_J(d, specs):
    """Per row of the dataset ``d``: the work [J] of each target road-load coefficient (A, B v,
    C v^2) over the fuelled driving steps (validation/epa_fuel_economy.trace_extras' v sums)."""
    per = lambda name: np.array([getattr(v, name) for v in specs])[d.vehicle.to_numpy()]  # noqa: E731
    return {"A": LBF_N * per("coastdown_A_lbf") * d.X_speed.to_numpy(),
            "B": LBF_N / MPH_M_S * per("coastdown_B_lbf_per_mph") * d.X_speed2.to_numpy(),
            "C": LBF_N / MPH_M_S ** 2 * per("coastdown_C_lbf_per_mph2") * d.X_speed3.to_numpy()}


def road_load_candidates(r, specs, table):
    """Each target road-load coefficient's work as a candidate fuel term (free sign), refitted
    held out: does a part of the road load cost other fuel than the brake work says?"""
    d, lines = r["dataset_pairs"], []
    paired = r["paired_table"]
    rows = np.flatnonzero(r["single"])
    for name, work in road_load_work_J(d, specs).items():
        col = f"X_road_load_{name}"
        extra = efe.STOP + (col,)
        pred, fits = efe.held_out(d.assign(**{col: work}), paired.iloc[rows].set_index(pd.Index(rows)),
                                  extra=extra, lower=[0.0, -np.inf])
        err = pd.DataFrame({t: pred[t] / paired[t].to_numpy()[pred.index] - 1.0 for t in TESTS})
        k = np.array([f["gasoline"][-1] / f["gasoline"][0] for f in fits.values()])
        sigma, _ = fit_transfer_share(err, table.manufacturer.to_numpy()[err.index])
        one = one_number(err, sigma)
        lines.append(f"candidate: {name} road-load work x k (free sign), k/slope over folds {k.min():+.3f}..{k.max():+.3f}: "
                     + ", ".join(f"{t} {np.mean(np.abs(err[t].dropna()) <= 0.05):.1%}" for t in TESTS)
                     + f"; one measured FTP: HWFET {np.mean(np.abs(one.HWFET.dropna()) <= 0.05):.1%}, "
                     f"US06 {np.mean(np.abs(one.US06.dropna()) <= 0.05):.1%}")
    return lines


def residual_report(r, specs, table):
    """``--residuals``: group tables and the learner bounds of physics + technology (pairs merged)."""
    feats, err = features(specs, table), r["pairs"]
    mf = table.manufacturer.to_numpy()[err.index]
    lines = residual_tables(err, feats) + road_load_candidates(r, specs, table)
    lines.append("correlation of held-out errors FTP-HWFET {:.2f}, FTP-US06 {:.2f}, HWFET-US06 {:.2f}".format(
        *(err[a].corr(err[b]) for a, b in (("FTP", "HWFET"), ("FTP", "US06"), ("HWFET", "US06")))))
    for label, with_ftp in (("the row's columns", False), ("the row's columns + the vehicle's FTP error", True)):
        for t, (before, after, r2) in learner_bound(err, feats, mf, with_ftp).items():
            lines.append(f"learner on {label}, held out: {t} within 5 % {before:.1%} -> {after:.1%} "
                         f"(share of log-error variance explained {r2:+.2f})")
    return lines


BREAKDOWN_TESTS = ("FTP:bag1", "FTP:bag2", "FTP:bag3", "HWFET", "US06", "FTP")
BREAKDOWN_GROUPS = {"specific_power_kW_per_L": [0, 50, 60, 70, 80, 100, 130, 400],
                    "road_load_50mph_W_per_kg": RESIDUAL_BINS["road_load_50mph_W_per_kg"],
                    "displacement_L": RESIDUAL_BINS["displacement_L"], "technology": None, "gearbox": None}


def _heldout_without_group(y, groups, manufacturer):
    """Log errors ``y`` less the median of their group fitted on the other manufacturers."""
    out = np.full(len(y), np.nan)
    for g in np.unique(manufacturer):
        median = pd.Series(y[manufacturer != g]).groupby(groups[manufacturer != g]).median()
        out[manufacturer == g] = y[manufacturer == g] - pd.Series(groups[manufacturer == g]).map(median).fillna(0.0).to_numpy()
    return out


def _heldout_without_line(y, x, manufacturer):
    """Log errors ``y`` less a straight line in ``x`` fitted on the other manufacturers."""
    X, out = np.column_stack([np.ones(len(y)), x]), np.full(len(y), np.nan)
    for g in np.unique(manufacturer):
        b = np.linalg.lstsq(X[manufacturer != g], y[manufacturer != g], rcond=None)[0]
        out[manufacturer == g] = y[manufacturer == g] - X[manufacturer == g] @ b
    return out


def _share(log_err):
    return float(np.mean(np.abs(np.expm1(log_err)) <= 0.05))


def breakdown_groups(err, feats, manufacturer):
    """Per test: spread of the log error, and per grouping its eta^2 and the share within 5 % left
    when the group medians (or a line in road load per kg) fitted without each manufacturer are removed."""
    lines, groups = [], feats
    for t in BREAKDOWN_TESTS:
        y = np.log1p(err[t].to_numpy())
        ok = np.isfinite(y)
        y, mf = y[ok], manufacturer[ok]
        cells = [f"{t}: n {ok.sum()}, sd {y.std():.2%}, within 5 % {_share(y):.1%}; line in road load per kg "
                 f"{_share(_heldout_without_line(y, feats.road_load_50mph_W_per_kg.to_numpy()[ok], mf)):.1%}"]
        for name, bins in BREAKDOWN_GROUPS.items():
            g = groups[name].to_numpy()[ok]
            g = (pd.cut(pd.Series(g), bins).astype(str) if bins else pd.Series(g).astype(str)).to_numpy()
            mean = pd.Series(y).groupby(g).transform("mean").to_numpy()
            cells.append(f"{name} eta2 {1 - np.var(y - mean) / np.var(y):.2f} -> {_share(_heldout_without_group(y, g, mf)):.1%}")
        mean = pd.Series(y).groupby(mf).transform("mean").to_numpy()
        cells.append(f"manufacturer eta2 {1 - np.var(y - mean) / np.var(y):.2f}")
        lines.append("; ".join(cells))
    return lines


def breakdown_parts(err, feats):
    """The cold part (bag 1 - bag 3) and the stop-and-go part (bag 2 - bag 3) in log: spread,
    correlations, medians by displacement and specific power; FTP share if each were removed."""
    L = np.log1p(err)
    cold, stop = L["FTP:bag1"] - L["FTP:bag3"], L["FTP:bag2"] - L["FTP:bag3"]
    sp = feats.specific_power_kW_per_L
    lines = [f"bags, HWFET, US06 log-error correlations {L[list(BREAKDOWN_TESTS[:5])].corr().to_numpy()[np.triu_indices(5, 1)].min():.2f}"
             f"-{L[list(BREAKDOWN_TESTS[:5])].corr().to_numpy()[np.triu_indices(5, 1)].max():.2f}; cold part sd {cold.std():.2%} "
             f"(corr with bag 3 {cold.corr(L['FTP:bag3']):+.2f}), stop-and-go part sd {stop.std():.2%} "
             f"(corr {stop.corr(L['FTP:bag3']):+.2f})"]
    for name, key, bins in (("displacement", feats.displacement_L, RESIDUAL_BINS["displacement_L"]),
                            ("specific power", sp, [0, 60, 80, 100, 130, 400])):
        med = cold.groupby(pd.cut(key, bins), observed=True).median()
        lines.append(f"cold part median by {name}: " + ", ".join(f"{k} {v:+.1%}" for k, v in med.items()))
    return lines


def breakdown_without_parts(err, table):
    """FTP composite within 5 % if the cold part (bag 1 error := bag 3's) or the stop-and-go part
    (bag 2's := bag 3's) were removed entirely (EPA's bag weighting of the measured bag mpg)."""
    idx = err.index.to_numpy()
    m = {b: table[f"FTP:{b}"].to_numpy()[idx] for b in efe.BAGS}
    d1, d2 = udds_miles()
    def ftp(m1, m2, m3):
        return 1.0 / ftp_weighted_per_mile(d1 / m1, d2 / m2, d1 / m3, d1, d2, d1)
    p = {b: m[b] * (1 + err[f"FTP:{b}"].to_numpy()) for b in efe.BAGS}
    truth = ftp(m["bag1"], m["bag2"], m["bag3"])
    out = {}
    for name, (a, b, c) in (("as is", (p["bag1"], p["bag2"], p["bag3"])),
                            ("cold part removed", (m["bag1"] * p["bag3"] / m["bag3"], p["bag2"], p["bag3"])),
                            ("stop-and-go part removed", (p["bag1"], m["bag2"] * p["bag3"] / m["bag3"], p["bag3"]))):
        e = ftp(a, b, c) / truth - 1.0
        out[name] = np.mean(np.abs(e[np.isfinite(e)]) <= 0.05)
    return ["FTP (from the bags) within 5 %: " + ", ".join(f"{k} {v:.1%}" for k, v in out.items())]


def breakdown_elasticities(err, table, feats):
    """Elasticities of fuel per mile, measured and modelled, to road load at 50 mph, test weight,
    displacement and rated power (least squares of log fuel per mile across the vehicles)."""
    idx = err.index.to_numpy()
    m = table.test_weight_kg.to_numpy()[idx]
    X = np.column_stack([np.ones(len(idx)), np.log(feats.road_load_50mph_W_per_kg.to_numpy()[idx] * m), np.log(m),
                         np.log(table.displacement_L.to_numpy()[idx]), np.log(table.rated_power_kW.to_numpy()[idx])])
    lines = []
    for t in ("FTP:bag2", "FTP:bag3", "HWFET", "US06"):
        meas = table[t].to_numpy()[idx]
        pred = meas * (1 + err[t].to_numpy())
        ok = np.isfinite(meas) & np.isfinite(pred)
        b = [np.linalg.lstsq(X[ok], -np.log(y[ok]), rcond=None)[0][1:] for y in (meas, pred)]
        lines.append(f"{t}: elasticity to road load / weight / displacement / power, measured "
                     + " / ".join(f"{x:.2f}" for x in b[0]) + ", model " + " / ".join(f"{x:.2f}" for x in b[1]))
    return lines


def breakdown_trend(err, feats, manufacturer, alpha):
    """The road-load trend: median error by road load at 50 mph per kg (fleetrun and ALPHA's
    surfaces, mean removed held out), and its rank correlation within manufacturers."""
    bins = pd.cut(feats.road_load_50mph_W_per_kg, RESIDUAL_BINS["road_load_50mph_W_per_kg"])
    lines = []
    for name, e in (("fleetrun", err), ("ALPHA", alpha)):
        med = e[["FTP", "FTP:bag3", "HWFET", "US06"] if name == "fleetrun" else list(TESTS)].groupby(
            bins.loc[e.index], observed=True).median()
        lines.append(f"{name} median error by road load per kg: " + "; ".join(
            f"{t} " + " ".join(f"{v:+.1%}" for v in med[t]) for t in med.columns) + f" (bins {list(med.index.astype(str))})")
    within = pd.DataFrame({"rl": feats.road_load_50mph_W_per_kg, **{t: err[t] for t in ("FTP:bag3", "HWFET", "US06")}})
    within = within - within.groupby(manufacturer).transform("median")
    lines.append("rank correlation with road load per kg within manufacturers: " + ", ".join(
        f"{t} {within.rl.corr(within[t], method='spearman'):.2f}" for t in ("FTP:bag3", "HWFET", "US06")))
    cold = np.log1p(err["FTP:bag1"]) - np.log1p(err["FTP:bag3"])
    for name, key in (("cylinder volume", feats.displacement_L / feats.cylinders),
                      ("rated power", feats.power_to_weight_W_per_kg * feats.weight_kg / 1e3)):
        g = pd.qcut(key.loc[cold.dropna().index], 6, duplicates="drop")
        c = cold.dropna()
        lines.append(f"cold part eta2 by {name} (6 equal-count bins): {1 - np.var(c - c.groupby(g).transform('mean')) / np.var(c):.2f}")
    return lines


def breakdown_report(r, specs, table):
    """``--breakdown``: where the held-out error of physics + technology is, on the joined vehicles
    (pairs not merged): by cycle, grouping and part (docs/validation-epa.md "Where the held-out error is")."""
    feats = features(specs, table).assign(weight_kg=table.test_weight_kg,
                                          specific_power_kW_per_L=table.specific_power_kW_per_L)
    rows = r["joined"]
    err, f = r["technology"].reindex(rows), feats.loc[rows]
    mf = table.manufacturer.to_numpy()[rows]
    _, alpha = alpha_errors(specs, table, np.asarray(rows))
    return (breakdown_groups(err, f, mf) + breakdown_parts(err, f) + breakdown_without_parts(err, table)
            + breakdown_elasticities(err, table, feats) + breakdown_trend(err, f, mf, alpha))


#: ``--vehicle-residual`` feature groups (vehicle_features' columns)
ENGINE_FEATURES = ("log_displacement", "cylinders", "log_cylinder_volume", "inverse_bore", "log_rated_power",
                   "specific_power", "peak_bmep", "turbo", "atkinson", "miller", "cylinder_deactivation",
                   "start_stop", "mild_hybrid_48v", "diesel")
DRIVETRAIN_FEATURES = ("gears", "cvt", "automated_manual", "manual", "nv", "awd")
RESIDUAL_LINES = ((), ("road_load",), ("road_load", "log_cylinder_volume"), ("road_load", "inverse_bore"),
                  ("road_load", "log_cylinder_volume", "cvt", "awd"))


def vehicle_features(specs, table, feats):
    """Per vehicle, numbers of what the row and the technology join say about its engine,
    drivetrain and body (``--vehicle-residual``; bore of a square engine from the cylinder volume)."""
    v_cyl = table.displacement_L / table.cylinders
    has = lambda name: feats.technology.str.contains(name).astype(float)  # noqa: E731
    return pd.DataFrame(dict(
        log_displacement=np.log(table.displacement_L), cylinders=table.cylinders, log_cylinder_volume=np.log(v_cyl),
        inverse_bore=(4e-3 * v_cyl / np.pi) ** (-1 / 3), log_rated_power=np.log(table.rated_power_kW),
        specific_power=table.specific_power_kW_per_L,
        peak_bmep=[4e-3 * np.pi * v.peak_engine_torque_Nm / v.engine_displacement_L for v in specs],
        **{k: has(k) for k in ("turbo", "atkinson", "miller", "cylinder_deactivation", "start_stop", "mild_hybrid_48v")},
        diesel=(table.fuel != "gasoline").astype(float), gears=table.gears.astype(float),
        **{k: (table.gearbox_type == k).astype(float) for k in ("cvt", "automated_manual", "manual")},
        nv=feats.nv_rpm_per_mph, awd=table.configuration.astype(str).str.contains("4WD|AWD").astype(float),
        log_weight=np.log(table.test_weight_kg), road_load=feats.road_load_50mph_W_per_kg,
        power_to_weight=feats.power_to_weight_W_per_kg))


def _grouped_prediction(X, y, manufacturer, learner=None):
    """Each manufacturer's prediction of ``y`` by a straight line (or ``learner``) fitted on the others."""
    X, pred = np.column_stack([np.ones(len(y)), X]), np.full(len(y), np.nan)
    for g in np.unique(manufacturer):
        fit_rows, rows = manufacturer != g, manufacturer == g
        if learner is None:
            pred[rows] = X[rows] @ np.linalg.lstsq(X[fit_rows], y[fit_rows], rcond=None)[0]
        else:
            pred[rows] = learner().fit(X[fit_rows], y[fit_rows]).predict(X[rows])
    return pred


def _residual_line(name, y, pred, L, joined):
    """cvR2 of a held-out prediction of the vehicle residual and the joined shares with it removed."""
    cells = []
    for t in TESTS:
        e, rows = L[t].to_numpy(), joined & np.isfinite(L[t].to_numpy())
        cells.append(f"{t} {_share(e[rows]):.1%} -> {_share(e[rows] - pred[rows]):.1%}")
    return f"  {name:60s} cvR2 {1 - np.var(y - pred) / np.var(y):+.3f}; joined within 5 %: " + ", ".join(cells)


def vehicle_residual_report(r, specs, table):
    """``--vehicle-residual``: the vehicle-level residual (mean held-out log error over FTP, HWFET,
    US06) regressed on the engine, drivetrain and body, manufacturers held out
    (docs/validation-epa.md "Where the vehicle-level residual comes from")."""
    from sklearn.ensemble import HistGradientBoostingRegressor

    F = vehicle_features(specs, table, features(specs, table))
    L = np.log1p(r["technology"]).reindex(F.index)
    y = L[list(TESTS)].mean(axis=1).to_numpy()
    ok = np.isfinite(y) & F.cylinders.notna().to_numpy()
    F, L, y, mf = F[ok], L[ok], y[ok], table.manufacturer.to_numpy()[ok]
    joined = np.isin(np.flatnonzero(ok), r["joined"])
    lines = [f"vehicle residual: n {ok.sum()}, sd {y.std():.2%} (joined {y[joined].std():.2%}); share of each test's "
             "log-error variance it carries: " + ", ".join(
                 f"{t} {np.corrcoef(L[t][L[t].notna()], y[L[t].notna().to_numpy()])[0, 1] ** 2:.2f}" for t in TESTS)]
    single = {c: 1 - np.var(y - (p := _grouped_prediction(F[[c]].to_numpy(), y, mf))) / np.var(y) for c in F.columns}
    lines.append("single features, straight line, cvR2: " + ", ".join(f"{c} {v:+.3f}" for c, v in
                                                                       sorted(single.items(), key=lambda x: -x[1])))
    for cols in RESIDUAL_LINES:
        lines.append(_residual_line("line: " + (" + ".join(cols) or "constant"), y,
                                    _grouped_prediction(F[list(cols)].to_numpy(), y, mf), L, joined))
    boost = lambda: HistGradientBoostingRegressor(max_iter=200, max_depth=3, learning_rate=0.05, random_state=0)  # noqa: E731
    for name, cols in (("engine", ENGINE_FEATURES), ("drivetrain", DRIVETRAIN_FEATURES),
                       ("engine + drivetrain", ENGINE_FEATURES + DRIVETRAIN_FEATURES), ("every feature", tuple(F.columns))):
        lines.append(_residual_line(f"boosting: {name}", y, _grouped_prediction(F[list(cols)].to_numpy(), y, mf, boost),
                                    L, joined))
    within = F.assign(residual=y) - F.assign(residual=y).groupby(mf).transform("median")
    rank = within.corr(method="spearman")["residual"].drop("residual").sort_values()
    lines.append("rank correlation with the residual within manufacturers: " + ", ".join(f"{k} {v:+.2f}" for k, v in rank.items()))
    return lines


RATIO_FEATURES = ("cvt", "awd", "mild_hybrid_48v", "cylinder_deactivation", "atkinson", "automated_manual", "manual",
                  "road_load", "nv", "cylinders")


def ratio_parts(err, table):
    """The physics' HWFET / FTP log-ratio error per vehicle split by the FTP's bags (EPA's weighting
    linearised in fuel per mile, phi_b the measured bag's share of the composite's fuel):
    log r = (L_H - L_3) - phi_1 (L_1 - L_3) - phi_2 (L_2 - L_3) + rest, L the log mpg errors.
    Returns (parts table, phi_1, phi_2, the vehicles with three bags and HWFET)."""
    cols = ["FTP:bag1", "FTP:bag2", "FTP:bag3", "HWFET", "FTP"]
    L = np.log1p(err[cols]).dropna()
    idx = L.index.to_numpy()
    d1, d2 = udds_miles()
    g = {b: m / table[f"FTP:{b}"].to_numpy()[idx] for b, m in (("bag1", d1), ("bag2", d2), ("bag3", d1))}
    ftp = ftp_weighted_per_mile(g["bag1"], g["bag2"], g["bag3"], d1, d2, d1)
    phi1 = ftp_weighted_per_mile(g["bag1"], 0.0, 0.0, d1, d2, d1) / ftp     # each bag's share of the composite
    phi2 = ftp_weighted_per_mile(0.0, g["bag2"], 0.0, d1, d2, d1) / ftp
    cold, stop = L["FTP:bag1"] - L["FTP:bag3"], L["FTP:bag2"] - L["FTP:bag3"]
    parts = pd.DataFrame({"highway": L.HWFET - L["FTP:bag3"], "cold": -phi1 * cold, "stop_and_go": -phi2 * stop})
    parts["rest"] = (L.HWFET - L.FTP) - parts.sum(axis=1)
    return parts, L, phi1, phi2


def _variance_shares(parts, total):
    return ", ".join(f"{k} {np.cov(parts[k], total)[0, 1] / total.var():+.2f} (sd {parts[k].std():.2%})" for k in parts)


def _one_ftp_share(LH, LF, manufacturer):
    """HWFET within 5 % with each vehicle calibrated on its FTP, the share s fitted without its manufacturer."""
    out = np.full(len(LH), np.nan)
    for g in np.unique(manufacturer):
        o = manufacturer != g
        out[manufacturer == g] = LH[manufacturer == g] - (LH[o] * LF[o]).sum() / (LF[o] ** 2).sum() * LF[manufacturer == g]
    return _share(out), out


def one_ftp_parts(parts, L, one):
    """The one-FTP HWFET log error L_H - s L_F split as the highway part, the warm level (1 - s) L_3,
    s x the cold and stop-and-go parts and the rest (s per vehicle: its fold's)."""
    LF = L.FTP
    s = (L.HWFET - one) / LF.where(LF != 0)
    out = pd.DataFrame({"highway": parts.highway, "warm level": (1 - s) * L["FTP:bag3"], "cold": s * parts.cold,
                        "stop_and_go": s * parts.stop_and_go})
    out["rest"] = one - out.sum(axis=1)
    return out


def ratio_counterfactuals(L, table, manufacturer):
    """One-FTP HWFET within 5 % (s refitted per fold), the ratio within 5 % (s = 1) and the FTP
    within 5 % when one part is made right: bag 1's error := bag 3's (cold), bag 2's := bag 3's
    (stop-and-go), HWFET's := bag 3's (highway), from EPA's weighting of the bags.
    Returns {case: (one-FTP HWFET, ratio, FTP) shares within 5 %}."""
    idx, d1, d2 = L.index.to_numpy(), *udds_miles()
    m = {b: table[f"FTP:{b}"].to_numpy()[idx] for b in efe.BAGS}
    ftp = lambda a, b, c: 1.0 / ftp_weighted_per_mile(d1 / a, d2 / b, d1 / c, d1, d2, d1)  # noqa: E731
    p = {b: m[b] * np.exp(L[f"FTP:{b}"].to_numpy()) for b in efe.BAGS}
    right = {b: m[b] * p["bag3"] / m["bag3"] for b in ("bag1", "bag2")}
    LH, L3 = L.HWFET.to_numpy(), L["FTP:bag3"].to_numpy()
    out = {}
    for name, bags, lh in (("as is", (p["bag1"], p["bag2"]), LH), ("cold right", (right["bag1"], p["bag2"]), LH),
                           ("stop-and-go right", (p["bag1"], right["bag2"]), LH),
                           ("cold and stop-and-go right", (right["bag1"], right["bag2"]), LH),
                           ("highway right (HWFET error := bag 3's)", (p["bag1"], p["bag2"]), L3)):
        LF = np.log(ftp(*bags, p["bag3"]) / ftp(m["bag1"], m["bag2"], m["bag3"]))
        out[name] = (_one_ftp_share(lh, LF, manufacturer)[0], _share(lh - LF), _share(LF))
    return out


def ratio_report(r, specs, table):
    """``--ratio-decomposition``: the physics' HWFET / FTP ratio error, pairs merged, split into
    the FTP's cold start, stop-and-go and the highway against the hot-start bag
    (docs/validation-epa.md "The HWFET / FTP ratio, by bag"); what carries the highway part."""
    parts, L, phi1, phi2 = ratio_parts(r["pairs"], r["paired_table"])
    mf = table.manufacturer.to_numpy()[L.index]
    ratio = L.HWFET - L.FTP
    share, one = _one_ftp_share(L.HWFET.to_numpy(), L.FTP.to_numpy(), mf)
    one = pd.Series(one, index=L.index)
    lines = [f"ratio: {len(L)} vehicles (three bags and HWFET); phi_1 median {np.median(phi1):.3f}, phi_2 "
             f"{np.median(phi2):.3f}; log ratio error sd {ratio.std():.2%}, within 5 % {_share(ratio):.1%}; "
             f"one-FTP HWFET within 5 % {share:.1%}",
             "ratio variance by part (cov / var): " + _variance_shares(parts, ratio),
             "one-FTP HWFET variance by part (cov / var): " + _variance_shares(one_ftp_parts(parts, L, one), one),
             "correlation of the parts: " + ", ".join(f"{a}-{b} {parts[a].corr(parts[b]):+.2f}"
                                                      for a, b in (("highway", "cold"), ("highway", "stop_and_go"))),
             "highway part: share of its variance between manufacturers (eta^2) "
             f"{1 - np.var(parts.highway - parts.highway.groupby(mf).transform('mean')) / np.var(parts.highway):.2f}; "
             f"corr with bag 3's error {parts.highway.corr(L['FTP:bag3']):+.2f}, with HWFET's {parts.highway.corr(L.HWFET):+.2f}"]
    lines += [f"{name}: one-FTP HWFET {a:.1%}, ratio {b:.1%}, FTP {c:.1%}"
              for name, (a, b, c) in ratio_counterfactuals(L, r["paired_table"], mf).items()]
    lines += ratio_features(parts, one, specs, table, mf)
    return lines + ratio_groups(parts, specs, table) + ratio_operating_point(parts, r, mf)


def ratio_operating_point(parts, r, mf):
    """Rank correlation, within manufacturers (each one's median removed), of the highway part with
    the model's mean bmep on the HWFET and bag 3 (brake work / friction-term sum [kPa]) and the
    offset share of the HWFET fuel (friction, pumping, accessories, stops; the final fit)."""
    d = r["dataset_pairs"]
    terms = efe.design(d, stop_extra()) * r["final"]["gasoline"]
    offset = list(OFFSET_TERMS) + list(range(len(FUEL_TERMS), terms.shape[1]))
    d = d.assign(O=terms[:, offset].sum(1), F=terms.sum(1))
    w = d.pivot_table(index="vehicle", columns="test", values=["S_brake", "S_friction", "O", "F"]).reindex(parts.index)
    q = pd.DataFrame({"mean bmep HWFET": w.S_brake.HWFET / w.S_friction.HWFET,
                      "mean bmep bag 3": w.S_brake["FTP:bag3"] / w.S_friction["FTP:bag3"],
                      "offset share HWFET": w.O.HWFET / w.F.HWFET, "highway": parts.highway})
    q = q - q.groupby(mf).transform("median")
    return ["highway part within manufacturers, rank correlation with " + ", ".join(
        f"{c} {q.highway.corr(q[c], method='spearman'):+.2f}" for c in q.columns[:-1])]


def ratio_groups(parts, specs, table):
    """Median of the highway part by gearbox type, technology class and cylinder count."""
    feats = vehicle_features(specs, table, features(specs, table)).loc[parts.index]
    h = parts.highway
    cells = [f"{k} {h[table.gearbox_type.loc[h.index] == k].median():+.1%}" for k in GEARBOX_TYPES]
    cells += [f"{k} {h[feats[k] == 1].median():+.1%} / without {h[feats[k] == 0].median():+.1%}"
              for k in ("start_stop", "mild_hybrid_48v", "cylinder_deactivation", "atkinson", "awd")]
    cells += [f"{c:.0f} cylinders {h[feats.cylinders == c].median():+.1%}" for c in (4, 6, 8)]
    return ["highway part, median by group: " + ", ".join(cells)]


def ratio_features(parts, one, specs, table, mf):
    """Held-out (by manufacturer) share of variance a straight line in each feature explains of the
    highway part, and of the one-FTP HWFET error (and the one-FTP share with that line removed)."""
    feats = vehicle_features(specs, table, features(specs, table)).loc[parts.index]
    lines = []
    for cols in [(c,) for c in RATIO_FEATURES] + [RATIO_FEATURES[:5], RATIO_FEATURES]:
        X = feats[list(cols)].astype(float)
        X = X.fillna(X.median()).to_numpy()
        cells = []
        for name, y in (("highway part", parts.highway.to_numpy()), ("one-FTP HWFET", one.to_numpy())):
            pred = _grouped_prediction(X, y, mf)
            cells.append(f"{name} cvR2 {1 - np.mean((y - pred) ** 2) / np.var(y):+.3f}")
        cells.append(f"one-FTP HWFET within 5 % with the line removed {_share(one.to_numpy() - pred):.1%}")
        lines.append(f"ratio feature {'+'.join(cols)}: " + "; ".join(cells))
    return lines


def write_models(r):
    """models/technology.toml ``transfer_share`` (the stop power is epa_fuel_economy.py --write's)
    and models/fuel_economy_bias.toml."""
    path = ROOT / "models" / "technology.toml"
    path.write_text(re.sub(r"transfer_share = [0-9.eE+-]+", f"transfer_share = {r['sigma_all']:.3f}", path.read_text()))
    b = r["bias_pairs"]
    f = np.array([v - 1.0 for v in b["fold_factors"].values()])
    (ROOT / "models" / "fuel_economy_bias.toml").write_text("\n".join([
        "# Fleet-level bias of the light-duty fuel model (physics + technology), total gallons of the EPA 2022",
        "# Test Car List (55 % FTP / 45 % HWFET per vehicle, equal miles), manufacturers held out.",
        "# Written by validation/epa_technology.py --write; docs/validation-epa.md. The budget's error model",
        "# reads `gallons_bias`: predicted / measured total gallons - 1 (remove: divide by 1 + gallons_bias).",
        'source = "validation/epa_technology.py: EPA 2022 Test Car List, held out by manufacturer"',
        f'measured_on = "{datetime.date.today().isoformat()}"',
        f"n_vehicles = {b['n']}",
        f"gallons_bias = {b['bias_all']:.5f}",
        f"fold_correction_min = {f.min():.5f}",
        f"fold_correction_max = {f.max():.5f}",
        f"after_removal_whole_list = {b['total_corrected']:.5f}",
        f"fleets_100_p05 = {b['fleets_corrected'][0]:.5f}",
        f"fleets_100_p95 = {b['fleets_corrected'][1]:.5f}", ""]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="write models/technology.toml [fitted], models/fuel_economy_bias.toml")
    ap.add_argument("--subset", type=int, default=0, help="every n-th vehicle only (development)")
    ap.add_argument("--residuals", action="store_true", help="where the held-out error comes from (scikit-learn)")
    ap.add_argument("--breakdown", action="store_true", help="the held-out error by cycle, grouping and part (joined vehicles)")
    ap.add_argument("--vehicle-residual", action="store_true",
                    help="the vehicle-level residual regressed on engine, drivetrain and body, held out (scikit-learn)")
    ap.add_argument("--ratio-decomposition", action="store_true",
                    help="the HWFET / FTP ratio error split by the FTP's bags, pairs merged (docs/validation-epa.md)")
    ap.add_argument("--transient-form", choices=TRANSIENT_FORMS, default="constant",
                    help="the acceleration term's form (measured, docs/validation-epa.md; default: the fuel equation's)")
    ap.add_argument("--cold-start-basis", choices=("displacement", "engine_mass"), default="displacement",
                    help="what the cold start's heat capacity follows (measured, docs/validation-epa.md)")
    ap.add_argument("--friction-form", choices=tuple(FRICTION_FORMS), default="chen_flynn",
                    help="the friction's form (measured, docs/validation-epa.md; default: the fuel equation's)")
    ap.add_argument("--slope-form", choices=tuple(SLOPE_FORMS), default="constant",
                    help="the Willans slope's form (measured, docs/validation-epa.md; default: the fuel equation's)")
    ap.add_argument("--deactivation-form", choices=tuple(DEACTIVATION_FORMS), default="pumping",
                    help="cylinder deactivation's form (measured, docs/validation-epa.md \"Hypothesis D1\")")
    ap.add_argument("--idle-form", choices=tuple(IDLE_FORMS), default="equation",
                    help="the warm idle's form (measured, docs/validation-epa.md \"Hypothesis I1\")")
    ap.add_argument("--stop-form", choices=tuple(efe.STOP_FORMS), default="constant",
                    help="start-stop's stop fuel (measured, docs/validation-epa.md \"Hypothesis S1\"; default: constant power)")
    ap.add_argument("--coastdown-driveline", choices=VARIANTS,
                    help="driveline spin loss taken out of the road load (default: models/road_load.toml)")
    args = ap.parse_args(argv)
    efe.COASTDOWN_DRIVELINE = args.coastdown_driveline
    efe.STOP = efe.STOP_FORMS[args.stop_form]
    global TRANSIENT_FORM, FRICTION_FORM, SLOPE_FORM, DEACTIVATION_FORM, IDLE_FORM
    TRANSIENT_FORM, FRICTION_FORM, SLOPE_FORM = args.transient_form, args.friction_form, args.slope_form
    DEACTIVATION_FORM, IDLE_FORM = args.deactivation_form, args.idle_form
    if IDLE_FORM == "mep_share":
        efe.STOP = efe.STOP_FORMS["idle_share"]
    specs, table = epa_fleet()
    if args.subset:
        keep = np.arange(0, len(specs), args.subset)
        specs, table = [specs[i] for i in keep], table.iloc[keep].reset_index(drop=True)
    if args.cold_start_basis == "engine_mass":
        for text in mass_basis_thermal(specs, table):
            print(text, flush=True)
    r = run(specs, table)
    print(f"{len(specs)} vehicles, {len(r['joined'])} joined to OMEGA; {int((~r['single']).sum())} drive-mode "
          f"duplicates merged into their pair", flush=True)
    for text in report(r, table):
        print(text, flush=True)
    optional = ((args.breakdown, breakdown_report), (args.vehicle_residual, vehicle_residual_report),
                (args.residuals, residual_report), (args.ratio_decomposition, ratio_report))
    for text in (line for wanted, lines in optional if wanted for line in lines(r, specs, table)):
        print(text, flush=True)
    if args.write:
        write_models(r)
    return r


if __name__ == "__main__":
    main()
