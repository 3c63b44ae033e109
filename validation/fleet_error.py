"""The model's fleet-level fuel error, measured on held-out EPA predictions, and how well the
budget's ranges cover it (docs/budget.md, "Ranges").

    PYTHONPATH=. python validation/fleet_error.py heldout      # simulate: write the per-vehicle errors
    PYTHONPATH=. python validation/fleet_error.py fit [--write] # the constants -> models/fleet_error.toml
    PYTHONPATH=. python validation/fleet_error.py coverage      # random fleets: coverage and width

``heldout`` runs validation/epa_fuel_economy.py's manufacturer-held-out fit (each manufacturer
predicted by the constants fitted without it) and writes one row per vehicle with its
manufacturer, fuel and relative errors e = predicted mpg / measured mpg - 1 per test to
``validation/data/epa_heldout_errors.csv`` (the input of the other two steps and of
tests/test_fleet_error.py; a few minutes of simulation).
"""
from __future__ import annotations

import argparse
import datetime
import sys
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

HELDOUT_CSV = ROOT / "validation" / "data" / "epa_heldout_errors.csv"
TESTS = ("FTP", "HWFET", "US06")


def write_heldout(path: Path = HELDOUT_CSV) -> pd.DataFrame:
    """Simulate the EPA list, fit held out by manufacturer, write the per-vehicle errors."""
    from epa_fuel_economy import run
    from epa_table import epa_fleet

    specs, table = epa_fleet()
    r = run(specs, table)
    err = r["err"]
    out = pd.DataFrame({"vehicle_id": table.vehicle_id, "manufacturer": table.manufacturer,
                        "make": table.make, "fuel": table.fuel,
                        "measured_FTP_mpg": table["FTP"], "measured_HWFET_mpg": table["HWFET"]})
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


def fit_constants(d: pd.DataFrame) -> dict:
    """The fleet-level error of the fuel model from per-vehicle held-out errors (docs/budget.md):

    - ``bias``: the gallons-weighted mean of r over the whole list (measured / predicted total
      gallons - 1);
    - ``sigma``: the per-vehicle-type scatter about its manufacturer's mean (pooled within
      manufacturers, gallons-weighted means);
    - ``tau``: the spread between manufacturers' means, DerSimonian and Laird's (1986,
      Controlled Clinical Trials 7:177) moment estimator with weights n_m / sigma^2;
    - ``market_share``: each manufacturer's share of the list's predicted gallons, and the
      list's make -> manufacturer table.
    """
    g, r = d.pred_gpm.to_numpy(), d.r.to_numpy()
    bias = float((g * r).sum() / g.sum())
    groups = d.assign(gr=g * r).groupby("manufacturer")
    n_m = groups.size().to_numpy(float)
    mean_m = (groups.gr.sum() / groups.pred_gpm.sum()).to_numpy()
    resid = r - d.manufacturer.map(dict(zip(groups.size().index, mean_m))).to_numpy()
    sigma2 = float((resid ** 2).sum() / (len(r) - len(n_m)))
    w = n_m / sigma2
    centre = (w * mean_m).sum() / w.sum()
    q = float((w * (mean_m - centre) ** 2).sum())
    tau2 = max(0.0, (q - (len(n_m) - 1)) / (w.sum() - (w ** 2).sum() / w.sum()))
    share = (groups.pred_gpm.sum() / g.sum()).to_dict()
    makes = {}
    for make, maker in zip(d.make.str.strip().str.upper(), d.manufacturer):
        makes.setdefault(make, maker)
    return {"bias": bias, "sigma": sigma2 ** 0.5, "tau": tau2 ** 0.5, "n_vehicles": len(r),
            "n_manufacturers": len(n_m), "market_share": share, "makes": makes}


def write_constants(c: dict, path: Path) -> None:
    """models/fleet_error.toml, [LD]: the constants of :func:`fit_constants`."""
    lines = ["# Fleet-level error of the light-duty fuel model (fleetrun/budget/uncertainty.py, docs/budget.md).",
             "# Written by `python validation/fleet_error.py fit --write` from validation/data/epa_heldout_errors.csv",
             "# (EPA 2022 Test Car List, each manufacturer predicted by constants fitted without it).",
             "# r = measured / predicted gallons - 1 on 55 % FTP / 45 % HWFET miles.", "",
             "[LD]", f'source = "validation/fleet_error.py fit: EPA 2022 Test Car List, held out by manufacturer"',
             f'measured_on = "{datetime.date.today().isoformat()}"',
             f"n_vehicles = {c['n_vehicles']}", f"n_manufacturers = {c['n_manufacturers']}",
             f"bias = {c['bias']:.5f}        # gallons-weighted mean r: the centre is model x (1 + bias)",
             f"tau = {c['tau']:.5f}         # between manufacturers (DerSimonian-Laird)",
             f"sigma = {c['sigma']:.5f}       # per vehicle type, within its manufacturer", "",
             "[LD.market_share]   # share of the list's predicted gallons"]
    lines += [f'"{k}" = {v:.5f}' for k, v in sorted(c["market_share"].items())]
    lines += ["", "[LD.makes]   # make (upper case) -> manufacturer, from the list"]
    lines += [f'"{k}" = "{v}"' for k, v in sorted(c["makes"].items())]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


SIZES = (10, 30, 100, 300, 1000)
MAKERS = (None, 1, 3, 10)       # None: drawn from the whole list; k: from k manufacturers


def random_fleets(d: pd.DataFrame, error, size: int, makers, n: int, rng, by_share: bool = False):
    """``n`` fleets of ``size`` vehicle types drawn with replacement from the list (or from
    ``makers`` manufacturers, chosen uniformly or by their number of vehicles): each fleet's
    held-out error (measured / predicted total gallons - 1) and its range's centre and sd."""
    names = d.manufacturer.unique()
    counts = d.manufacturer.value_counts().reindex(names).to_numpy(float)
    g, r, maker = d.pred_gpm.to_numpy(), d.r.to_numpy(), d.manufacturer.to_numpy()
    out = np.empty((n, 2))
    for k in range(n):
        pool = np.arange(len(d))
        if makers:
            chosen = rng.choice(names, makers, replace=False, p=counts / counts.sum() if by_share else None)
            pool = np.flatnonzero(np.isin(maker, chosen))
        pick = rng.choice(pool, size, replace=True)
        types, repeats = np.unique(pick, return_counts=True)
        gallons = g[types] * repeats
        out[k, 0] = (gallons * r[types]).sum() / gallons.sum()
        out[k, 1] = error.relative_sd(gallons, maker[types])
    return out


def coverage(d: pd.DataFrame, error, n: int = 1000, seed: int = 20) -> pd.DataFrame:
    """Per fleet size and manufacturer draw: how often the 90 % range (bias-corrected centre
    +- 1.645 sd) holds the held-out error, its mean width and the measured 5-95 % interval."""
    from fleetrun.budget.uncertainty import Z90

    rng = np.random.default_rng(seed)
    rows = []
    for by_share in (False, True):
        for makers in MAKERS:
            if by_share and makers is None:
                continue
            for size in SIZES:
                e, sd = random_fleets(d, error, size, makers, n, rng, by_share).T
                p05, p95 = np.quantile(e, [0.05, 0.95])
                rows.append({"size": size, "manufacturers": makers or "all",
                             "drawn": "by vehicles" if by_share else "uniform",
                             "covered": float(np.mean(np.abs(e - error.bias) <= Z90 * sd)),
                             "range_width": float(np.mean(2 * Z90 * sd)), "measured_p05": p05,
                             "measured_p95": p95, "width_ratio": float(np.mean(2 * Z90 * sd) / (p95 - p05))})
    return pd.DataFrame(rows)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("step", choices=("heldout", "fit", "coverage"))
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args(argv)
    if args.step == "heldout":
        out = write_heldout()
        print(f"{len(out)} vehicles -> {HELDOUT_CSV}")
    elif args.step == "fit":
        c = fit_constants(read_heldout())
        print({k: v for k, v in c.items() if k not in ("market_share", "makes")})
        if args.write:
            write_constants(c, ROOT / "models" / "fleet_error.toml")
    else:
        from fleetrun.budget.uncertainty import read_error_model

        table = coverage(read_heldout(), read_error_model(ROOT / "models" / "fleet_error.toml").for_duty("LD"))
        print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
        print(f"all fleets: covered {table.covered.mean():.3f}; fleets of >= 100 vehicle types: width ratio "
              f"at most {table[table['size'] >= 100].width_ratio.max():.2f}")


if __name__ == "__main__":
    main()
