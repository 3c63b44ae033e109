"""The model's fleet-level fuel error, measured on held-out EPA predictions, and how well the
budget's ranges cover it (docs/budget.md, "Ranges").

    PYTHONPATH=. python validation/fleet_error.py heldout      # simulate: write the per-vehicle errors
    PYTHONPATH=. python validation/fleet_error.py fit [--write] # the constants -> models/fleet_error.toml
    PYTHONPATH=. python validation/fleet_error.py coverage      # random fleets: coverage and width
    PYTHONPATH=. python validation/fleet_error.py cv [--effect E] # the same, cross-validated by manufacturer
    PYTHONPATH=. python validation/fleet_error.py diagnose      # why: scatter shape, effects by size

``heldout`` runs validation/epa_fuel_economy.py's manufacturer-held-out fit (each manufacturer
predicted by the constants fitted without it) and writes one row per vehicle with its
manufacturer, fuel and relative errors e = predicted mpg / measured mpg - 1 per test to
``validation/data/epa_heldout_errors.csv`` (the input of the other two steps and of
tests/test_fleet_error.py; a few minutes of simulation).
"""
from __future__ import annotations

import argparse
import datetime
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import optimize, stats

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

HELDOUT_CSV = ROOT / "validation" / "data" / "epa_heldout_errors.csv"
TESTS = ("FTP", "HWFET", "US06")


def write_heldout(path: Path = HELDOUT_CSV) -> pd.DataFrame:
    """Simulate the EPA list, fit held out by manufacturer, write the per-vehicle errors.

    The predictions are validation/epa_technology.py's "physics + technology, drive-mode pairs"
    (the model as the budget runs it; the same errors as models/fuel_economy_bias.toml): each
    test vehicle once, its measured mpg the label-style mean of its drive modes."""
    from epa_table import epa_fleet
    from epa_technology import run

    specs, table = epa_fleet()
    r = run(specs, table)
    err, paired = r["pairs"], r["paired_table"].iloc[r["pairs"].index]
    out = pd.DataFrame({"vehicle_id": paired.vehicle_id, "manufacturer": paired.manufacturer,
                        "make": paired.make, "fuel": paired.fuel,
                        "measured_FTP_mpg": paired["FTP"], "measured_HWFET_mpg": paired["HWFET"]})
    for test in TESTS:
        out[f"e_{test}"] = err[test].to_numpy()
    path.parent.mkdir(parents=True, exist_ok=True)
    out.to_csv(path, index=False, float_format="%.6g")
    return out


def fleet_gallons(d: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Per vehicle: predicted and measured gallons per mile on 55 % FTP / 45 % HWFET miles
    (EPA's combined weighting, 40 CFR 600.210-12(c))."""
    w = constants()["combined_weights"]
    meas = w["FTP"] / d.measured_FTP_mpg + w["HWFET"] / d.measured_HWFET_mpg
    pred = (w["FTP"] / (d.measured_FTP_mpg * (1 + d.e_FTP)) + w["HWFET"] / (d.measured_HWFET_mpg * (1 + d.e_HWFET)))
    return pred.to_numpy(float), meas.to_numpy(float)


def constants() -> dict:

    return {"combined_weights": {"FTP": 0.55, "HWFET": 0.45}}


def read_heldout(path: Path = HELDOUT_CSV) -> pd.DataFrame:
    """The per-vehicle held-out errors with both tests measured, and each vehicle's predicted
    gallons per mile ``pred_gpm`` and relative gallons error ``r`` = measured / predicted - 1."""
    d = pd.read_csv(path).dropna(subset=["e_FTP", "e_HWFET", "measured_FTP_mpg", "measured_HWFET_mpg"])
    d = d.reset_index(drop=True)
    pred, meas = fleet_gallons(d)
    d["pred_gpm"], d["r"] = pred, meas / pred - 1.0
    return d


DF_GRID = (2.0, 4.0, 10.0, math.inf)
SHARE_REF = 0.01      # the market share at which a manufacturer's effect has scale tau


def manufacturer_means(d: pd.DataFrame, bias: float, sigma: float) -> pd.DataFrame:
    """Per manufacturer: ``x`` its gallons-weighted mean r minus ``bias``, ``s2`` the sampling
    variance of that mean from the per-vehicle scatter (sigma^2 sum g_i^2, g its types' gallon
    shares) and ``share`` of the list's predicted gallons."""
    groups = d.assign(gr=d.pred_gpm * d.r).groupby("manufacturer")
    return pd.DataFrame({"x": groups.gr.sum() / groups.pred_gpm.sum() - bias,
                         "s2": groups.pred_gpm.apply(lambda g: float(((g / g.sum()) ** 2).sum())) * sigma ** 2,
                         "share": groups.pred_gpm.sum() / d.pred_gpm.sum()})


def effect_nll(params, m: pd.DataFrame, df: float) -> float:
    """Negative log likelihood of the manufacturers' means: x_m ~ t_df (normal for df = inf)
    with scale sqrt(tau_m^2 + s2_m), tau_m^2 = tau^2 (share_m / SHARE_REF)^-2gamma + tau_size^2
    SHARE_REF / share_m (the sum of the effect and its mean's sampling error taken as one t);
    params = (ln tau, gamma, ln tau_size)."""
    share = m.share.to_numpy() / SHARE_REF
    tau2 = math.exp(2 * params[0]) * share ** (-2 * params[1]) + math.exp(2 * params[2]) / share
    scale = np.sqrt(tau2 + m.s2.to_numpy())
    z = m.x.to_numpy() / scale
    logpdf = stats.norm.logpdf(z) if math.isinf(df) else stats.t.logpdf(z, df)
    return float(-(logpdf - np.log(scale)).sum())


EFFECTS = {                       # manufacturer-effect families compared by `cv --effect` (docs/budget.md)
    "size": ((math.inf,), False, True),     # normal, variance tau^2 + tau_size^2 SHARE_REF / share (stored)
    "normal": ((math.inf,), False, False),  # one normal spread tau, every manufacturer counted once
    "t": (DF_GRID, False, False),           # heavier tails: Student t, df by likelihood
    "share": ((math.inf,), True, False),    # small manufacturers err more: tau (share / SHARE_REF)^-gamma
    "t+share": (DF_GRID, True, False),
}
DEFAULT_EFFECT = "size"
_NO_SIZE = math.log(1e-6)        # ln tau_size where the family has no size term (held there)


def fit_effect(m: pd.DataFrame, effect: str = DEFAULT_EFFECT) -> tuple[float, float, float, float]:
    """(tau, gamma, df, tau_size) of the manufacturer effect by maximum likelihood
    (:func:`effect_nll`; every manufacturer counts once): tau continuous, gamma in 0-2 and
    tau_size continuous where ``effect`` lets them vary (else 0), df the best of the family's grid."""
    grid, free_gamma, free_size = EFFECTS[effect]
    best = (math.inf, 0.0, 0.0, math.inf, 0.0)
    size_bounds = (math.log(1e-4), math.log(0.5)) if free_size else (_NO_SIZE, _NO_SIZE)
    for df in grid:
        o = optimize.minimize(effect_nll, [math.log(0.02 if free_size else 0.03), 0.2 if free_gamma else 0.0,
                                           math.log(0.02) if free_size else _NO_SIZE], args=(m, df),
                              method="L-BFGS-B", bounds=[(math.log(1e-4), math.log(0.5)),
                                                         (0.0, 2.0 if free_gamma else 0.0), size_bounds])
        if o.fun < best[0]:
            best = (float(o.fun), math.exp(o.x[0]), float(o.x[1]), df, math.exp(o.x[2]) if free_size else 0.0)
    return best[1:]


def fit_constants(d: pd.DataFrame, effect: str = DEFAULT_EFFECT) -> dict:
    """The fleet-level error of the fuel model from per-vehicle held-out errors (docs/budget.md):

    - ``bias``: the gallons-weighted mean of r over the list (measured / predicted total
      gallons - 1);
    - ``sigma``: the per-vehicle-type scatter about its manufacturer's mean (pooled within
      manufacturers, gallons-weighted means);
    - ``tau``, ``share_exponent`` (gamma), ``df``, ``tau_size``: the manufacturer effect,
      Student t of squared scale tau^2 (share / SHARE_REF)^-2gamma + tau_size^2 SHARE_REF / share,
      by maximum likelihood over the manufacturers' means (:func:`fit_effect`; each manufacturer
      counts once, its mean's own sampling error added; the stored family ``size``: normal,
      gamma 0);
    - ``market_share``: each manufacturer's share of the list's predicted gallons, and the
      list's make -> manufacturer table.
    """
    g, r = d.pred_gpm.to_numpy(), d.r.to_numpy()
    bias = float((g * r).sum() / g.sum())
    groups = d.assign(gr=g * r).groupby("manufacturer")
    mean_m = groups.gr.sum() / groups.pred_gpm.sum()
    resid = r - d.manufacturer.map(mean_m).to_numpy()
    sigma = float((resid ** 2).sum() / (len(r) - len(mean_m))) ** 0.5
    tau, gamma, df, tau_size = fit_effect(manufacturer_means(d, bias, sigma), effect)
    makes = {}
    for make, maker in zip(d.make.str.strip().str.upper(), d.manufacturer):
        makes.setdefault(make, maker)
    return {"bias": bias, "sigma": sigma, "tau": tau, "share_exponent": gamma, "share_ref": SHARE_REF, "df": df,
            "tau_size": tau_size,
            "n_vehicles": len(r), "n_manufacturers": len(mean_m),
            "market_share": (groups.pred_gpm.sum() / g.sum()).to_dict(), "makes": makes}


def duty_error(c: dict):
    """The budget's DutyError of fitted constants ``c``."""
    from fleetrun.budget.uncertainty import DutyError

    return DutyError(bias=c["bias"], tau=c["tau"], sigma=c["sigma"], df=c["df"], size_share=c.get("size_share", {}),
                     share_exponent=c["share_exponent"], share_ref=c["share_ref"], tau_size=c["tau_size"],
                     market_share=c["market_share"], makes=c["makes"])


def write_constants(c: dict, path: Path) -> None:
    """models/fleet_error.toml, [LD]: the constants of :func:`fit_constants`."""
    lines = ["# Fleet-level error of the light-duty fuel model (fleetrun/budget/uncertainty.py, docs/budget.md).",
             "# Written by `python validation/fleet_error.py fit --write` from validation/data/epa_heldout_errors.csv",
             "# (EPA 2022 Test Car List, each manufacturer predicted by constants fitted without it; drive-mode",
             "# pairs as one vehicle, validation/epa_technology.py). Cross-validated by manufacturer: `... cv`.",
             "# r = measured / predicted gallons - 1 on 55 % FTP / 45 % HWFET miles.", "",
             "[LD]", 'source = "validation/fleet_error.py fit: EPA 2022 Test Car List, held out by manufacturer"',
             f'measured_on = "{datetime.date.today().isoformat()}"',
             f"n_vehicles = {c['n_vehicles']}", f"n_manufacturers = {c['n_manufacturers']}",
             f"bias = {c['bias']:.5f}        # gallons-weighted mean r: the centre is model x (1 + bias)",
             f"tau = {c['tau']:.5f}         # manufacturer effect, the part every manufacturer has: sd (scale of a t if df is finite)",
             f"tau_size = {c['tau_size']:.5f}    # plus variance tau_size^2 share_ref / W (averages out over a large manufacturer)",
             f"share_exponent = {c['share_exponent']:.4f}  # gamma: scale tau (W / share_ref)^-gamma, W the market share",
             f"share_ref = {c['share_ref']}",
             f"df = {c['df']:g}             # degrees of freedom of the t (inf: normal)",
             f"sigma = {c['sigma']:.5f}       # per vehicle type, within its manufacturer", "",
             "[LD.market_share]   # share of the list's predicted gallons"]
    lines += [f'"{k}" = {v:.5f}' for k, v in sorted(c["market_share"].items())]
    lines += ["", "[LD.makes]   # make (upper case) -> manufacturer, from the list"]
    lines += [f'"{k}" = "{v}"' for k, v in sorted(c["makes"].items())]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


SIZES = (10, 30, 100, 300, 1000)
MAKERS = (None, 1, 3, 10)       # None: drawn from the whole list; k: from k manufacturers
FOLDS = 5


def random_fleets(d: pd.DataFrame, error, size: int, makers, n: int, rng, by_share: bool = False):
    """``n`` fleets of ``size`` vehicle types drawn with replacement from the list (or from
    ``makers`` manufacturers, chosen uniformly or by their number of vehicles): each fleet's
    held-out error (measured / predicted total gallons - 1) and the half-width of its 90 % range."""
    from fleetrun.budget.uncertainty import half_width

    names = d.manufacturer.unique()
    counts = d.manufacturer.value_counts().reindex(names).to_numpy(float)
    g, r, maker = d.pred_gpm.to_numpy(), d.r.to_numpy(), d.manufacturer.to_numpy()
    e, scales = np.empty(n), np.empty((n, 2))
    for k in range(n):
        pool = np.arange(len(d))
        if makers:
            chosen = rng.choice(names, makers, replace=False, p=counts / counts.sum() if by_share else None)
            pool = np.flatnonzero(np.isin(maker, chosen))
        pick = rng.choice(pool, size, replace=True)
        types, repeats = np.unique(pick, return_counts=True)
        gallons = g[types] * repeats
        e[k] = (gallons * r[types]).sum() / gallons.sum()
        scales[k] = error.scales(gallons, maker[types])
    return e, half_width(scales[:, 0], scales[:, 1], error.df)


def coverage(d: pd.DataFrame, error, n: int = 1000, seed: int = 20) -> pd.DataFrame:
    """Per fleet size and manufacturer draw: how often the 90 % range (bias-corrected centre
    +- its half-width) holds the held-out error, its mean width and the measured 5-95 % interval."""
    rng = np.random.default_rng(seed)
    rows = []
    n_makers = d.manufacturer.nunique()
    for by_share in (False, True):
        for makers in MAKERS:
            if (by_share and makers is None) or (makers or 0) >= n_makers:
                continue
            for size in SIZES:
                e, h = random_fleets(d, error, size, makers, n, rng, by_share)
                p05, p95 = np.quantile(e, [0.05, 0.95])
                rows.append({"size": size, "manufacturers": makers or "all",
                             "drawn": "by vehicles" if by_share else "uniform",
                             "covered": float(np.mean(np.abs(e - error.bias) <= h)),
                             "range_width": float(np.mean(2 * h)), "measured_p05": p05,
                             "measured_p95": p95, "width_ratio": float(np.mean(2 * h) / (p95 - p05))})
    return pd.DataFrame(rows)


def folds_of(d: pd.DataFrame, k: int = FOLDS) -> dict[str, int]:
    """Manufacturer -> fold: ranked by number of vehicles, dealt out in turn (every fold gets
    large and small manufacturers)."""
    ranked = d.manufacturer.value_counts().sort_index(kind="stable").sort_values(ascending=False, kind="stable")
    return {m: i % k for i, m in enumerate(ranked.index)}


def cross_validate(d: pd.DataFrame, k: int = FOLDS, n: int = 1000, seed: int = 20, effect: str = DEFAULT_EFFECT):
    """Constants fitted on the manufacturers of k - 1 folds, coverage measured on random fleets
    of the held-out fold's manufacturers (from all of them, or from 1 or 3, uniformly or by
    size): per fold, the fitted constants and the coverage table.

    The fleets' D compares their make-up with the market the centre (bias) was measured on, the
    k - 1 training folds (a held-out manufacturer has W_m = 0 there, so its whole effect and the
    training mean's own error count); a manufacturer's size (which sets its effect's scale) is
    its share of the whole list, a fact an analyst knows of a real manufacturer."""
    fold = d.manufacturer.map(folds_of(d, k)).to_numpy()
    out = []
    for f in range(k):
        c = fit_constants(d[fold != f].reset_index(drop=True), effect)
        whole = fit_constants(d)     # the manufacturers' sizes and makes only (facts of the list)
        c = c | {"size_share": whole["market_share"], "makes": whole["makes"]}
        table = coverage(d[fold == f].reset_index(drop=True), duty_error(c), n=n, seed=seed + f)
        out.append({"fold": f, "constants": c, "held_out": sorted(d.manufacturer[fold == f].unique()),
                    "table": table})
    return out


def print_cv(folds) -> pd.DataFrame:
    """One line per fold, the pooled table; returns every fold's rows."""
    rows = []
    for f in folds:
        c, t = f["constants"], f["table"]
        one = t[t.manufacturers == 1]
        print(f"fold {f['fold']}: held out {', '.join(f['held_out'])}")
        print(f"  fitted on the others: bias {c['bias']:+.2%}, sigma {c['sigma']:.2%}, tau {c['tau']:.2%}, tau_size {c['tau_size']:.2%}, "
              f"gamma {c['share_exponent']:.2f}, df {c['df']:g}; covered {t.covered.mean():.1%} (one manufacturer {one.covered.mean():.1%}); "
              f">= 100 types width ratio {t[t['size'] >= 100].width_ratio.min():.2f}-"
              f"{t[t['size'] >= 100].width_ratio.max():.2f}")
        rows.append(t.assign(fold=f["fold"]))
    table = pd.concat(rows, ignore_index=True)
    summary(table, "cross-validated (5 folds by manufacturer)")
    return table


def summary(table: pd.DataFrame, label: str) -> None:
    """The figures the README and docs/budget.md quote."""
    one = table[table.manufacturers == 1]
    whole = table[table.manufacturers == "all"]
    large = whole[whole["size"] >= 100]
    print(f"{label}: covered {table.covered.mean():.1%} of all fleets; whole pool {whole.covered.mean():.1%}; "
          f"one manufacturer {one.covered.mean():.1%} (uniform {one[one.drawn == 'uniform'].covered.mean():.1%}, "
          f"by size {one[one.drawn == 'by vehicles'].covered.mean():.1%}); cells {table.covered.min():.1%}-"
          f"{table.covered.max():.1%}; whole pool >= 100 types: width ratio {large.width_ratio.min():.2f}-"
          f"{large.width_ratio.max():.2f}, all >= 100 types at most {table[table['size'] >= 100].width_ratio.max():.2f}")
    kinds = table.groupby(["manufacturers", "drawn"], sort=False)
    print("  per kind of draw (all sizes): " + "; ".join(
        f"{m} {'' if m == 'all' else ('uniformly' if drawn == 'uniform' else 'by size') + ' '}{t.covered.mean():.1%} "
        f"({t.covered.min():.1%}-{t.covered.max():.1%})" for (m, drawn), t in kinds))


SIZE_GROUPS = (0.0, 0.015, 0.05, 1.0)     # manufacturers by share of the list's gallons (`diagnose`)


def diagnose(d: pd.DataFrame) -> None:
    """Why a range over- or under-covers: the per-type scatter's shape, the manufacturers'
    effects by size against what each family of effect says, and each family's likelihood."""
    c = fit_constants(d, "normal")
    groups = d.assign(gr=d.pred_gpm * d.r).groupby("manufacturer")
    resid = d.r - d.manufacturer.map(groups.gr.sum() / groups.pred_gpm.sum())
    print(f"per vehicle type, within its manufacturer: sd {resid.std():.2%}, excess kurtosis "
          f"{stats.kurtosis(resid):.2f}, 90 % of |r - mean| within {np.quantile(np.abs(resid), 0.9) / resid.std():.2f} sd "
          f"(normal: {stats.norm.ppf(0.95):.2f})")
    m = manufacturer_means(d, c["bias"], c["sigma"])
    fits = {e: fit_constants(d, e) for e in EFFECTS}
    for lo, hi in zip(SIZE_GROUPS[:-1], SIZE_GROUPS[1:]):
        part = m[(m.share >= lo) & (m.share < hi)]
        model = {e: math.sqrt(np.mean([duty_error(f).effect_variance(k) for k in part.index])) for e, f in fits.items()
                 if math.isinf(f["df"])}
        print(f"manufacturers with {lo:.1%}-{hi:.1%} of the gallons ({len(part)}): mean effect {part.x.mean():+.2%}, "
              f"rms {math.sqrt((part.x ** 2).mean()):.2%} (sampling {math.sqrt(part.s2.mean()):.2%}); rms effect said by "
              + ", ".join(f"{e} {v:.2%}" for e, v in model.items()))
    size = duty_error(fits[DEFAULT_EFFECT])
    share = size.market_share
    big, small = max(share, key=share.get), min(share, key=share.get)
    print(f"stored family ({DEFAULT_EFFECT}): effect sd {math.sqrt(size.tau ** 2 + size.tau_size ** 2):.2%} at "
          f"{size.share_ref:.0%} of the gallons, {math.sqrt(size.effect_variance(big)):.2%} for {big} ({share[big]:.1%}), "
          f"{math.sqrt(size.effect_variance(small)):.2%} for {small} ({share[small]:.2%}) and a manufacturer the list lacks; "
          f"measured effect of {big} {m.x[big]:+.2%}")
    t = np.random.default_rng(2).standard_t(2.0, (200_000, 3)).mean(axis=1)
    print(f"t family's one-t range of a sum: the mean of three equal t_2 effects has its 95th percentile at "
          f"{np.quantile(t, 0.95):.2f} scale, one t of the same D says {stats.t.ppf(0.95, 2.0) / math.sqrt(3):.2f} (200,000 draws)")
    for e, f in fits.items():
        nll = effect_nll([math.log(f["tau"]), f["share_exponent"], math.log(max(f["tau_size"], 1e-6))], m, f["df"])
        print(f"  {e}: log likelihood of the 22 means {-nll:.2f}, constants {int(len(EFFECTS[e][0]) > 1)} df + "
              f"{1 + EFFECTS[e][1] + EFFECTS[e][2]} scale")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("step", choices=("heldout", "fit", "coverage", "cv", "diagnose"))
    ap.add_argument("--write", action="store_true")
    ap.add_argument("--effect", choices=tuple(EFFECTS), default=None,
                    help=f"manufacturer-effect family [{DEFAULT_EFFECT}]; with coverage: fit it in sample "
                         "instead of reading the stored constants")
    ap.add_argument("--fleets", type=int, default=1000, help="random fleets per cell")
    args = ap.parse_args(argv)
    if args.step == "heldout":
        out = write_heldout()
        print(f"{len(out)} vehicles -> {HELDOUT_CSV}")
    elif args.step == "fit":
        c = fit_constants(read_heldout(), args.effect or DEFAULT_EFFECT)
        print({k: v for k, v in c.items() if k not in ("market_share", "makes")})
        if args.write:
            write_constants(c, ROOT / "models" / "fleet_error.toml")
    elif args.step == "diagnose":
        diagnose(read_heldout())
    elif args.step == "cv":
        print_cv(cross_validate(read_heldout(), n=args.fleets, effect=args.effect or DEFAULT_EFFECT))
    else:
        from fleetrun.budget.uncertainty import read_error_model

        d = read_heldout()
        error = duty_error(fit_constants(d, args.effect)) if args.effect else read_error_model().for_duty("LD")
        table = coverage(d, error, n=args.fleets)
        print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
        summary(table, f"{args.effect} fitted in sample" if args.effect else "stored constants, every manufacturer")


if __name__ == "__main__":
    main()
