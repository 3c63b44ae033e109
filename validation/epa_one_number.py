"""One measured number per vehicle as physics, on the EPA 2022 Test Car List, held out by
manufacturer (docs/validation-epa.md "One measured number as physics"; candidates
pre-registered there before any of their held-out numbers):

    PYTHONPATH=. python validation/epa_one_number.py [--cache FILE]

Each vehicle's measured FTP composite (or its derived label) fixes delta in
fuel_t += delta x Q_t on every test t, Q_t the fuel per mile of one physical quantity of the
held-out prediction (the fuel equation's terms with the fold's constants, the cold start,
the Willans fuel of the road load), so that the FTP (or the label) is exact; HWFET and US06
receive it in their own proportions. Global constants (a share, the cold start's weight, the
choice of quantity) are fitted by least squares of the HWFET and US06 log errors on the other
manufacturers: 22 leave-one-manufacturer-out folds and 5 folds by manufacturer
(validation/fleet_error.folds_of). Predictions, pairs and folds are epa_technology.py's.
Second round (pre-registered after the first): the share with a cap (S1), one share per
gearbox type (S2). Label form: EPA's derived label combined figure of the measured FTP and
HWFET (L1 as `simulate` applies it, L2 carried by a quantity, L1r in whole mpg, L3 the highway
label). Also printed: the in-sample bound of any function of the FTP error alone on HWFET.
"""
from __future__ import annotations

import argparse
import pickle
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import epa_fuel_economy as efe  # noqa: E402
import epa_technology as et  # noqa: E402
from epa_table import epa_fleet  # noqa: E402
from fleet_error import folds_of  # noqa: E402

from fleetrun.cycles import ftp_weighted_per_mile  # noqa: E402
from fleetrun.physics import epa_label  # noqa: E402
from fleetrun.simulation import measured  # noqa: E402

TESTS = et.TESTS
OTHER = ("HWFET", "US06")
#: parts of the held-out fuel (columns of epa_fuel_economy.design with the stop-power column)
PART_TERMS = {"B": (0, 1, 7), "F": (2, 3, 4), "P": (5,), "A": (6,), "S": (8,)}
#: the pre-registered quantities: id -> (description, parts of the fuel it scales)
QUANTITIES = {"N1": ("hot Willans slope (brake, high load, acceleration)", "B"),
              "N2": ("friction mean effective pressure (three FMEP terms)", "F"),
              "N3": ("idle / constant fuel power (accessory-time and stop-power terms)", "AS"),
              "N4": ("road load (Willans fuel of the target A, B v, C v^2 work)", "R"),
              "N5": ("whole warm engine (every warm term, cold start untouched)", "BFPAS")}
SHARE_GRID = np.round(np.arange(0.0, 1.5001, 0.01), 2)
CAP_GRID = (0.05, 0.1, 0.15, 0.2, 0.3, np.inf)
COLD_GRID = np.r_[np.arange(0.0, 10.0, 0.25), np.arange(10.0, 80.1, 2.0)]


def prepare(specs, table):
    """Held-out errors of physics + technology (pairs merged), the split of each prediction into
    parts per test [g/mi], the paired table, grams per gallon per vehicle."""
    d1 = efe.build_dataset(specs, table)
    rep = et.drive_mode_groups(specs)
    single = rep == np.arange(len(specs))
    paired = et.pair_targets(table, rep)
    d1["measured_mpg"] = [paired[t].to_numpy()[v] for t, v in zip(d1.test, d1.vehicle)]
    d1["measured_fuel_g"] = d1.miles / d1.measured_mpg * efe.GAL_L * d1.rho * 1000.0
    err, _, folds = et.heldout_errors(d1, paired, single, extra=et.stop_extra())
    d = d1[d1.vehicle.isin(np.flatnonzero(single))]
    parts = split_parts(d, folds, specs)
    g_per_gal = d.groupby("vehicle").rho.first() * efe.GAL_L * 1000.0
    return dict(err=err, parts=parts, paired=paired, g_per_gal=g_per_gal,
                manufacturer=table.manufacturer.to_numpy()[err.index], gearbox=table.gearbox_type.to_numpy()[err.index])


def split_parts(d, folds, specs):
    """Per part (PART_TERMS, "C" cold start, "R" road-load Willans fuel): vehicles x tests [g/mi]
    of each fold's prediction of its held-out manufacturer."""
    rows = []
    for g, coef in folds.items():
        dm = d[(d.manufacturer == g).to_numpy()]
        c = np.where((dm.fuel == "gasoline").to_numpy()[:, None], coef["gasoline"], coef["diesel"])
        terms = efe.design(dm, et.stop_extra()) * c
        warm, sim_warm = terms.sum(axis=1), (dm.sim_fuel_g - dm.cold_g).to_numpy()
        with np.errstate(divide="ignore", invalid="ignore"):
            cold = np.where(sim_warm > 0, dm.cold_g.to_numpy() * warm / sim_warm, 0.0)
        work = sum(et.road_load_work_J(dm, specs).values())
        later = list(range(PART_TERMS["S"][0] + 1, terms.shape[1]))    # further extra columns: with the stops
        cols = {k: terms[:, list(j) + (later if k == "S" else [])].sum(axis=1) for k, j in PART_TERMS.items()}
        cols.update(C=cold, R=c[:, 0] * work / (dm.lhv.to_numpy() * 1e3))
        rows.append(pd.DataFrame(dict(vehicle=dm.vehicle.to_numpy(), test=dm.test.to_numpy(),
                                      miles=dm.miles.to_numpy(), **cols)))
    rows = pd.concat(rows)
    return {k: et._per_mile(rows, k) for k in list(PART_TERMS) + ["C", "R"]}


def quantity(parts, names, index, cold_weight=0.0):
    """Q (vehicles x TESTS) [g/mi]: the sum of the parts ``names`` (+ ``cold_weight`` x cold start)."""
    q = sum(parts[k].loc[index, list(TESTS)].to_numpy() for k in names)
    return q + cold_weight * parts["C"].loc[index, list(TESTS)].to_numpy()


def predicted(parts, index):
    return quantity(parts, "BFPASC", index)


def carry(err, parts, q, share=1.0):
    """Held-out errors after the measured FTP fixes delta in fuel += delta Q (FTP exact; the
    other tests receive share x delta x Q). Vehicles with Q_FTP <= 0 stay uncalibrated."""
    pred = predicted(parts, err.index)
    meas = pred * (1.0 + err[list(TESTS)].to_numpy())     # error = predicted mpg / measured - 1
    with np.errstate(divide="ignore", invalid="ignore"):
        delta = np.where(q[:, 0] > 0, (meas[:, 0] - pred[:, 0]) / q[:, 0], 0.0)
    new = pred + share * delta[:, None] * q
    new[:, 0] = pred[:, 0] + delta * q[:, 0]
    new = np.maximum(new, 1e-3 * pred)                     # a correction larger than the fuel
    out = pd.DataFrame(meas / new - 1.0, index=err.index, columns=list(TESTS))
    out.loc[err["FTP"].isna(), :] = np.nan
    return out


def share_carry(err, share):
    """The in-place form (R0): other tests' mpg divided by (1 + e_FTP)^share."""
    return et.one_number(err, np.full(len(err), share))


def loss(e):
    x = np.log1p(e[list(OTHER)].to_numpy())
    return float(np.nansum(x ** 2))


def fit_held_out(err, groups, family):
    """Per held-out group: the parameter of ``family`` (p -> errors) that minimizes the HWFET and
    US06 squared log errors of the other groups; returns held-out errors and the fold values."""
    params, out, chosen = family["grid"], err.copy() * np.nan, {}
    tables = [family["apply"](p) for p in params]
    for g in np.unique(groups):
        train = groups != g
        costs = [loss(t[train]) for t in tables]
        best = int(np.argmin(costs))
        chosen[g] = params[best]
        out.loc[~train] = tables[best].loc[~train]
    return out, chosen


def candidates(r):
    """Every pre-registered candidate: id -> (description, family or fixed errors)."""
    err, parts = r["err"], r["parts"]
    idx = err.index
    fam = {"R0": ("(in place) share s of the FTP's log error", dict(grid=SHARE_GRID, apply=lambda s: share_carry(err, s)))}
    fam["R1"] = ("(in place) physical split w_B B + w_O O + C", dict(
        grid=[(wb, wo) for wb in et.SPLIT_GRID for wo in et.SPLIT_GRID],
        apply=lambda w: carry(err, parts, w[0] * quantity(parts, "B", idx) + w[1] * quantity(parts, "FPAS", idx)
                              + quantity(parts, "C", idx))))
    for key, (text, names) in QUANTITIES.items():
        fam[key] = (text, dict(grid=[None], apply=lambda _, n=names: carry(err, parts, quantity(parts, n, idx))))
        fam[key + "s"] = (text + ", global share", dict(
            grid=SHARE_GRID, apply=lambda s, n=names: carry(err, parts, quantity(parts, n, idx), s)))
    fam["N6"] = ("warm engine + cold start weighted w_C", dict(
        grid=COLD_GRID, apply=lambda w: carry(err, parts, quantity(parts, "BFPAS", idx, w))))
    return fam


LIST_MODEL_YEAR = 2022   # the Test Car List's model year: its labels' coefficient set (fleetrun.physics.epa_label)


def label_set(table=None):
    """The derived 5-cycle coefficient set called ``table`` (models/budget.toml), default the
    set `simulate` applies to the list's model year."""
    return epa_label.set_for_model_year(LIST_MODEL_YEAR) if table is None else epa_label.label_set(table)


def derived_label(paired, idx, table=None):
    """EPA's derived label combined figure [mpg] (40 CFR 600.210-12(a)(2); the coefficient set
    :func:`label_set` (table)) of the measured FTP and HWFET of the vehicles ``idx``."""
    ftp, hw = paired["FTP"].to_numpy()[idx], paired["HWFET"].to_numpy()[idx]
    return epa_label.combined_label_mpg(ftp, hw, label_set(table))


def label_errors(r, form, share=None, whole_mpg=False, label=None, table=None):
    """Errors on FTP, HWFET, US06 after calibrating on the derived label combined (40 CFR
    600.210-12(a)(2) of the measured FTP and HWFET; :func:`label_set`), form "share": FTP
    and HWFET scaled by k (the label exact), US06 by k^share; form "Q" (a part set): delta
    on fuel += delta Q such that the label of the calibrated FTP and HWFET is exact, US06 its Q.
    ``whole_mpg``: the label rounded to whole mpg as printed on the window sticker. ``label``
    (mpg per vehicle of ``r["err"]``, NaN where none): a given label instead of the derived one
    (the real label, validation/epa_labels.py); ``table``: the label formulas the calibration
    inverts (and the derived label's, :func:`label_set`)."""
    err, parts, paired, gpg = r["err"], r["parts"], r["paired"], r["g_per_gal"]
    idx = err.index
    (ac, bc), (ah, bh) = label_set(table).city, label_set(table).highway
    city = epa_label.CITY_SHARE
    label = derived_label(paired, idx, table) if label is None else np.asarray(label, float)
    label = np.round(label) if whole_mpg else label
    meas_mpg = np.c_[paired["FTP"].to_numpy()[idx], paired["HWFET"].to_numpy()[idx], paired["US06"].to_numpy()[idx]]
    pred_mpg = meas_mpg * (1.0 + err[list(TESTS)].to_numpy())
    if form == "share":
        k = measured.label_scale(label, pred_mpg[:, 0], pred_mpg[:, 1], label_set=label_set(table))
        scale = np.c_[k, k, k ** share]
        out = (1.0 + err[list(TESTS)].to_numpy()) / scale - 1.0
    else:
        pred = predicted(parts, idx)
        meas = pred * (1.0 + err[list(TESTS)].to_numpy())
        q = quantity(parts, form, idx)
        g = gpg.loc[idx].to_numpy()
        # 1/label = a + city bc (P_F + d Q_F)/g + (1 - city) bh (P_H + d Q_H)/g, linear in d
        a = city * ac + (1 - city) * ah
        base = a + (city * bc * pred[:, 0] + (1 - city) * bh * pred[:, 1]) / g
        slope = (city * bc * q[:, 0] + (1 - city) * bh * q[:, 1]) / g
        delta = (1.0 / label - base) / slope
        new = np.maximum(pred + delta[:, None] * q, 1e-3 * pred)
        out = meas / new - 1.0
    out = pd.DataFrame(out, index=idx, columns=list(TESTS))
    out.loc[~np.isfinite(label), :] = np.nan
    return out


def describe(e, tests=OTHER):
    cells = []
    for t in tests:
        x = e[t].dropna().to_numpy()
        cells.append(f"{t} n={x.size} mean {x.mean():+.2%} med|e| {np.median(np.abs(x)):.2%} "
                     f"within 5 % {np.mean(np.abs(x) <= 0.05):.1%}")
    return " | ".join(cells)


def gallons_line(e, paired):
    b = et.bias_report(e, paired)
    return (f"gallons: whole list {b['total']:+.2%}, 100-vehicle fleets 5-95 % "
            f"{b['fleets'][0]:+.2%}..{b['fleets'][1]:+.2%}")


def ftp_only_bound(err):
    """In sample, the best any function of the FTP error alone can do for HWFET: each vehicle's
    HWFET log error predicted by the median of its bin of FTP log error (5-40 equal-count bins);
    and the residual spread after the least-squares share."""
    lf, lh = np.log1p(err["FTP"].to_numpy()), np.log1p(err["HWFET"].to_numpy())
    ok = np.isfinite(lf) & np.isfinite(lh)
    lf, lh = lf[ok], lh[ok]
    shares = {}
    for bins in (5, 10, 20, 40):
        med = pd.Series(lh).groupby(pd.qcut(lf, bins, labels=False)).transform("median").to_numpy()
        shares[bins] = float(np.mean(np.abs(np.expm1(lh - med)) <= 0.05))
    s = float(np.sum(lf * lh) / np.sum(lf ** 2))
    res = lh - s * lf
    robust = 1.4826 * float(np.median(np.abs(res - np.median(res))))
    return (f"FTP error alone, in sample: HWFET within 5 % by bins of the FTP error "
            + ", ".join(f"{b} bins {v:.1%}" for b, v in shares.items())
            + f"; share {s:.3f} {np.mean(np.abs(np.expm1(res)) <= 0.05):.1%}; correlation {np.corrcoef(lf, lh)[0, 1]:.3f}; "
            f"residual log sd {res.std():.4f} (robust {robust:.4f})")


def report(r):
    err, mf = r["err"], r["manufacturer"]
    five = pd.Series(mf).map(folds_of(pd.DataFrame({"manufacturer": mf}))).to_numpy()
    lines = [f"{len(err)} vehicles (pairs merged); physics + technology held out: " + describe(err, TESTS),
             ftp_only_bound(err)]
    results = {}
    fams = candidates(r)
    for key, (text, family) in fams.items():
        for split_name, groups in (("22 folds", mf), ("5 folds", five)):
            e, chosen = fit_held_out(err, groups, family)
            vals = sorted({tuple(np.atleast_1d(v).tolist()) for v in chosen.values() if v is not None})
            vals = [v[0] if len(v) == 1 else v for v in vals]
            spread = "" if not vals else f"; constant over folds {vals[0]}..{vals[-1]}"
            lines.append(f"{key:4s} {text} [{split_name}]: {describe(e)}{spread}")
            results[(key, split_name)] = e
        lines.append(f"     {gallons_line(results[(key, '22 folds')], r['paired'])}")
    lines += choice_lines(err, fams, mf, five, results)
    lines += second_round(r, five, results)
    lines += label_lines(r)
    return lines, results


def capped_share(err, s, cap):
    """S1: the other tests' mpg divided by exp(s x clip(log(1 + e_FTP), -cap, cap)); FTP exact."""
    carried = np.exp(s * np.clip(np.log1p(err["FTP"].to_numpy()), -cap, cap))
    out = pd.DataFrame({t: (1.0 + err[t].to_numpy()) / carried - 1.0 for t in TESTS}, index=err.index)
    out["FTP"] = 0.0
    out.loc[err["FTP"].isna(), :] = np.nan
    return out


def second_round(r, five, results):
    """S1 (capped share) and S2 (one share per gearbox type), held out as the first round."""
    err, mf, lines = r["err"], r["manufacturer"], []
    family = dict(grid=[(s, c) for s in SHARE_GRID[::2] for c in CAP_GRID],
                  apply=lambda p: capped_share(err, *p))
    for split_name, groups in (("22 folds", mf), ("5 folds", five)):
        e, chosen = fit_held_out(err, groups, family)
        results[("S1", split_name)] = e
        lines.append(f"S1   share with a cap [{split_name}]: {describe(e)}; (s, cap) chosen "
                     + ", ".join(f"({a}, {b})" for a, b in sorted(set(chosen.values()))))
    lines.append(f"     {gallons_line(results[('S1', '22 folds')], r['paired'])}")
    for split_name, groups in (("22 folds", mf), ("5 folds", five)):
        out, shares = err * np.nan, {}
        for box in np.unique(r["gearbox"].astype(str)):
            rows = r["gearbox"].astype(str) == box
            sub = err[rows]
            e, chosen = fit_held_out(sub, groups[rows], dict(grid=SHARE_GRID, apply=lambda s, x=sub: share_carry(x, s)))
            out.loc[rows] = e.to_numpy()
            shares[str(box)] = f"{min(chosen.values())}..{max(chosen.values())}"
        results[("S2", split_name)] = out
        lines.append(f"S2   share per gearbox type [{split_name}]: {describe(out)}; shares {shares}")
    lines.append(f"     {gallons_line(results[('S2', '22 folds')], r['paired'])}")
    return lines


def choice_lines(err, fams, mf, five, results):
    """N7: the quantity (N1-N6 and N1s-N5s, with its own constant) chosen per fold by the
    training manufacturers' loss."""
    lines = []
    keys = [k for k in fams if k.startswith("N")]
    tables = {k: [(p, fams[k][1]["apply"](p)) for p in fams[k][1]["grid"]] for k in keys}
    for split_name, groups in (("22 folds", mf), ("5 folds", five)):
        out, picks = err.copy() * np.nan, []
        for g in np.unique(groups):
            train = groups != g
            best = min(((loss(t[train]), k, p, t) for k in keys for p, t in tables[k]), key=lambda x: x[0])
            picks.append(f"{best[1]}({best[2]})")
            out.loc[~train] = best[3].loc[~train]
        results[("N7", split_name)] = out
        lines.append(f"N7   quantity chosen per fold [{split_name}]: {describe(out)}; chosen "
                     + ", ".join(sorted(set(picks))))
    return lines


def label_lines(r):
    lines = []
    share = measured.transfer_share()
    mf = r["manufacturer"]
    five = pd.Series(mf).map(folds_of(pd.DataFrame({"manufacturer": mf}))).to_numpy()
    for name, form in (("L1 label combined, in place (k on FTP and HWFET, k^s on US06, stored s)", "share"),
                       ("L2 label combined, whole warm engine (N5)", "BFPAS"),
                       ("L2 label combined, hot Willans slope (N1)", "B"),
                       ("L2 label combined, friction (N2)", "F"),
                       ("L2 label combined, road load (N4)", "R")):
        e = label_errors(r, form, share)
        lines.append(f"{name}: {describe(e, TESTS)}")
        lines.append(f"     {gallons_line(e, r['paired'])}")
    for whole in (False, True):
        family = dict(grid=SHARE_GRID, apply=lambda s, w=whole: label_errors(r, "share", s, w))
        for split_name, groups in (("22 folds", mf), ("5 folds", five)):
            e, chosen = fit_held_out(r["err"], groups, family)
            lines.append(f"L1{'r' if whole else 's'} label combined{' rounded to whole mpg' if whole else ''}, "
                         f"s fitted held out [{split_name}]: {describe(e, TESTS)}; s over folds "
                         f"{min(chosen.values())}..{max(chosen.values())}")
        lines.append(f"     {gallons_line(e, r['paired'])}")
    lines += highway_label_lines(r["err"], mf, five)
    return lines


def highway_label_lines(err, mf, five):
    """L3: the derived highway label (a function of the HWFET alone): HWFET exact, FTP and US06 mpg
    divided by k^s, k the HWFET's mpg ratio, s fitted held out on the FTP and US06 log errors."""
    def apply(s):
        k = 1.0 + err["HWFET"].to_numpy()
        out = pd.DataFrame({t: (1.0 + err[t].to_numpy()) / k ** s - 1.0 for t in TESTS}, index=err.index)
        out["HWFET"] = np.where(np.isfinite(k), 0.0, np.nan)
        return out
    lines, tables = [], [(s, apply(s)) for s in SHARE_GRID]
    cost = lambda t, rows: float(np.nansum(np.log1p(t.loc[rows, ["FTP", "US06"]].to_numpy()) ** 2))  # noqa: E731
    for split_name, groups in (("22 folds", mf), ("5 folds", five)):
        out, chosen = err * np.nan, []
        for g in np.unique(groups):
            s, t = min(tables, key=lambda st: cost(st[1], groups != g))
            chosen.append(s)
            out.loc[groups == g] = t.loc[groups == g]
        lines.append(f"L3 highway label (HWFET exact), s fitted held out [{split_name}]: {describe(out, TESTS)}; "
                     f"s over folds {min(chosen)}..{max(chosen)}")
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", help="pickle of the held-out predictions (development; rebuilt when missing)")
    args = ap.parse_args(argv)
    t0 = time.time()
    if args.cache and Path(args.cache).exists():
        r = pickle.loads(Path(args.cache).read_bytes())
    else:
        r = prepare(*epa_fleet())
        if args.cache:
            Path(args.cache).write_bytes(pickle.dumps(r))
    r["err"] = r["err"][list(TESTS)]
    check = predicted(r["parts"], r["err"].index)
    print(f"prepared in {time.time() - t0:.0f} s; parts sum to the held-out prediction: "
          f"FTP mpg rel. diff max {check_parts(r, check):.1e}", flush=True)
    lines, _ = report(r)
    for text in lines:
        print(text, flush=True)


def check_parts(r, pred_gpm):
    """Largest relative difference between the parts' FTP mpg and the held-out FTP prediction."""
    idx = r["err"].index
    mpg_parts = r["g_per_gal"].loc[idx].to_numpy() / pred_gpm[:, 0]
    mpg_pred = r["paired"]["FTP"].to_numpy()[idx] * (1.0 + r["err"]["FTP"].to_numpy())
    ok = np.isfinite(mpg_pred)
    return float(np.max(np.abs(mpg_parts[ok] / mpg_pred[ok] - 1.0)))


if __name__ == "__main__":
    main()
