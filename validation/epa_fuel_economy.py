"""Fleet-wide calibration and held-out validation of the fuel model on the EPA 2022 Test Car List.

    PYTHONPATH=. python validation/epa_fuel_economy.py [--write] [--plots docs/img] [--ablation]

1. Every vehicle of the list that can be modelled (conventional gasoline and diesel, measured
   FTP and HWFE; validation/epa_table.py) is simulated over each test's cycle once, with its
   trace; per vehicle and cycle the eight terms of the fuel equation
   (fleetrun/simulation/engine.py, ``fuel_power_terms_W``) are summed over the fuelled steps.
   The fuel equation is linear in its eight constants, so predicted fuel = terms . c / LHV
   exactly as the simulation computes it (the script checks this on the default constants).
2. The constants c >= 0 are fitted by non-negative least squares on the relative fuel error,
   all tests together (one set for every light-duty gasoline engine; diesels share them with
   their own Willans slope and no throttle pumping).
3. Held out by manufacturer: for each manufacturer the constants are fitted without its
   vehicles and predict them; the distribution of those held-out errors per test is
   ``models/fuel_economy_error.toml`` (read by the budget's ranges), and the spread of the
   fitted constants over the folds is their uncertainty in ``models/engine_calibration.toml``.

Tests: ``UDDS:hot`` (hot-start UDDS vs EPA bags 3 + 2) until the FTP cycle with its cold start
is on main, ``HWFET`` (EPA "HWFE"), ``US06``. Errors are predicted mpg / measured mpg - 1.
"""
from __future__ import annotations

import argparse
import datetime
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import nnls

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from epa_table import measured_table, read_tstcar, spec_rows  # noqa: E402

from fleetrun.simulation import simulate  # noqa: E402
from fleetrun.simulation.core import engine_fuel_rate_g_per_s  # noqa: E402,F401 (the equation fitted)
from fleetrun.simulation.engine import FUEL_TERMS, fuel_power_terms_W  # noqa: E402
from fleetrun.simulation.params import FUEL_CONSTANTS, vehicle_arrays  # noqa: E402

GAL_L = 3.785411784
TESTS = {"UDDS:hot": "UDDS", "HWFET": "HWFET", "US06": "US06"}
CHUNK = 150
MODE = "map2d"   # every axle ratio of the list (map3d's grid stops at 6)


def cycle_terms(specs, cycle):
    """(V, 8) sums over the cycle of the fuel terms x dt over fuelled steps [J], miles, fuel_g."""
    S, miles, fuel = [], [], []
    for a in range(0, len(specs), CHUNK):
        part = specs[a:a + CHUNK]
        r = simulate(part, cycle, mode=MODE, trace=True)
        tr = r.trace
        va = vehicle_arrays(part)
        col = lambda x: x[:, None]  # noqa: E731
        n, T, Tmax = tr["engine_speed_rpm"], tr["engine_torque_Nm"], tr["engine_max_torque_Nm"]
        dt = tr["_dt"] * (tr["fuel_rate_g_per_s"] > 0)
        inertial = col(va.mass_kg * (1.0 + va.rot_frac)) * tr["_accel"] * tr["_v_avg"]
        terms = fuel_power_terms_W(np.minimum(T, Tmax), n, Tmax, col(va.displacement_L), col(va.stroke_m),
                                   col(va.T_peak), col(va.throttled), inertial)
        S.append(np.stack([(np.broadcast_to(t, n.shape) * dt).sum(axis=1) for t in terms], axis=1))
        miles.append(r.miles)
        fuel.append(r.fuel_g)
    return np.vstack(S), np.concatenate(miles), np.concatenate(fuel)


def build_dataset(specs, table):
    """Long table: one row per (vehicle, test) with the term sums, measured and simulated fuel."""
    va = vehicle_arrays(specs)
    rows = []
    for test, cycle in TESTS.items():
        S, miles, fuel_g = cycle_terms(specs, cycle)
        measured = table[test].to_numpy(float)
        ok = np.isfinite(measured) & (measured > 0)
        for i in np.flatnonzero(ok):
            rows.append(dict(vehicle=i, test=test, miles=miles[i], sim_fuel_g=fuel_g[i],
                             measured_mpg=measured[i], fuel=specs[i].fuel, lhv=va.lhv[i], rho=va.density[i],
                             constants=va.fuel_constants[i], **{f"S_{k}": S[i, j] for j, k in enumerate(FUEL_TERMS)}))
    d = pd.DataFrame(rows)
    d["measured_fuel_g"] = d.miles / d.measured_mpg * GAL_L * d.rho * 1000.0
    return d


def design(d):
    """Fuel [g] per unit coefficient: terms / (LHV [MJ/kg] x 1e3)."""
    return d[[f"S_{k}" for k in FUEL_TERMS]].to_numpy() / (d.lhv.to_numpy()[:, None] * 1e3)


def coefficients_of(constants):
    from fleetrun.simulation.engine import fuel_coefficients
    return np.array([float(c) for c in fuel_coefficients(*constants)])


def fit(d, columns=None):
    """Non-negative least squares on the relative error: {fuel: coefficient vector (8,)}.

    Gasoline: all eight coefficients (``columns``: the terms kept, others 0). Diesel: the
    gasoline coefficients scaled by one factor (its Willans slope), pumping term 0.
    """
    columns = list(range(len(FUEL_TERMS))) if columns is None else list(columns)
    X, y = design(d), d.measured_fuel_g.to_numpy()
    gas = (d.fuel == "gasoline").to_numpy()
    c = np.zeros(len(FUEL_TERMS))
    c[columns], _ = nnls(X[gas][:, columns] / y[gas, None], np.ones(gas.sum()))
    result = {"gasoline": c}
    dsl = ~gas
    if dsl.any():
        base = X[dsl] @ np.where(np.arange(len(c)) == FUEL_TERMS.index("pumping"), 0.0, c)
        scale = float(np.sum(base / y[dsl]) / np.sum((base / y[dsl]) ** 2))
        result["diesel"] = scale * np.where(np.arange(len(c)) == FUEL_TERMS.index("pumping"), 0.0, c)
    else:
        result["diesel"] = c
    return result


def predict(d, coef):
    X = design(d)
    c = np.where((d.fuel == "gasoline").to_numpy()[:, None], coef["gasoline"], coef["diesel"])
    fuel = (X * c).sum(axis=1)
    return d.measured_fuel_g.to_numpy() / fuel - 1.0   # predicted mpg / measured mpg - 1


def held_out(d, groups, columns=None):
    """Errors of each row predicted by the fit without its manufacturer; the folds' fits."""
    err = np.full(len(d), np.nan)
    fits = {}
    for g in np.unique(groups):
        out = groups == g
        coef = fit(d[~out], columns)
        err[out] = predict(d[out], coef)
        fits[g] = coef
    return err, fits


def constants_of(c):
    """Coefficient vector (8,) -> the named constants (eta_indicated first)."""
    eta = 1.0 / c[0]
    return {"eta_indicated": eta, **{k: c[j] * eta for j, k in enumerate(FUEL_CONSTANTS) if j > 0}}


def summary(err):
    e = err[np.isfinite(err)]
    return dict(n=int(e.size), mean=float(e.mean()), median=float(np.median(e)),
                median_abs=float(np.median(np.abs(e))), p05=float(np.quantile(e, 0.05)),
                p95=float(np.quantile(e, 0.95)), within_5pct=float(np.mean(np.abs(e) <= 0.05)))


def summaries(d, err):
    return {test: summary(err[(d.test == test).to_numpy()]) for test in TESTS}


def print_summaries(label, s):
    line = f"{label:34s}"
    for test, v in s.items():
        line += (f" | {test}: n={v['n']} mean={v['mean']:+.3f} med|e|={v['median_abs']:.3f} "
                 f"w5={v['within_5pct']:.2f}")
    print(line, flush=True)


def write_error_toml(s, path, source_note):
    lines = [f'source = "validation/epa_fuel_economy.py: EPA 2022 Test Car List, held out by manufacturer"',
             f'measured_on = "{datetime.date.today().isoformat()}"',
             f'note = "{source_note}"', ""]
    names = {"UDDS:hot": "FTP", "HWFET": "HWFET", "US06": "US06"}
    for test, v in s.items():
        lines.append(f"[tests.{names[test]}]")
        if test == "UDDS:hot":
            lines.append('compared = "hot-start UDDS vs EPA FTP bags 3 + 2 (the FTP cycle with its cold start is not yet simulated)"')
        for key in ("n", "mean", "median", "p05", "p95", "within_5pct"):
            lines.append(f"{key} = {v[key]:.4f}" if key != "n" else f"n = {v['n']}")
        lines.append(f"median_abs = {v['median_abs']:.4f}")
        lines.append("")
    Path(path).write_text("\n".join(lines))


def write_calibration_toml(final, folds, s, path, n_vehicles):
    """models/engine_calibration.toml: the fitted constants (all vehicles) with the spread of
    the manufacturer-held-out folds."""
    lines = ["# Fleet-wide calibration of the fuel-equation constants (fleetrun/simulation/engine.py).",
             "# Written by validation/epa_fuel_economy.py --write; do not edit by hand.",
             f'source = "EPA 2022 Test Car List (inputs/epa/22-tstcar.csv), {n_vehicles} vehicles; '
             'tests hot UDDS (bags 3+2), HWFE, US06"',
             'method = "non-negative least squares on the relative fuel error; uncertainty = the spread (std, min, max) '
             'of the constants over leave-one-manufacturer-out folds"',
             f'fitted_on = "{datetime.date.today().isoformat()}"', ""]
    for fuel in ("gasoline", "diesel"):
        named = constants_of(final[fuel])
        fold_named = [constants_of(f[fuel]) for f in folds.values()]
        lines.append(f"[{fuel}.LD.constants]")
        for key in FUEL_CONSTANTS:
            vals = np.array([f[key] for f in fold_named])
            lines.append(f"{key} = {{ value = {named[key]:.6g}, fold_std = {vals.std():.3g}, "
                         f"fold_min = {vals.min():.6g}, fold_max = {vals.max():.6g} }}")
        lines.append("")
    Path(path).write_text("\n".join(lines))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="write models/engine_calibration.toml and "
                    "models/fuel_economy_error.toml")
    ap.add_argument("--plots", type=Path, help="folder for the figures (docs/img)")
    ap.add_argument("--ablation", action="store_true", help="refit without each fuel term")
    args = ap.parse_args(argv)

    table = measured_table(read_tstcar())
    specs, table = spec_rows(table)
    d = build_dataset(specs, table)
    groups = table["Vehicle Manufacturer Name"].to_numpy()[d.vehicle.to_numpy()]
    # the simulation's own fuel from the summed terms (exactness of the linear form)
    own = (design(d) * np.stack([coefficients_of(c) for c in d.constants])).sum(axis=1)
    gap = np.max(np.abs(own / d.sim_fuel_g.to_numpy() - 1.0))
    print(f"{len(specs)} vehicles, {len(d)} vehicle-tests; terms reproduce the simulated fuel to {gap:.1e}")
    print_summaries("simulation as configured", summaries(d, d.measured_fuel_g.to_numpy() / d.sim_fuel_g.to_numpy() - 1))
    err, folds = held_out(d, groups)
    s = summaries(d, err)
    print_summaries("held out by manufacturer", s)
    final = fit(d)
    print_summaries("in-sample (all vehicles)", summaries(d, predict(d, final)))
    for fuel, c in final.items():
        print(fuel, {k: round(v, 4) for k, v in constants_of(c).items()})
    if args.ablation:
        for j, name in enumerate(FUEL_TERMS[1:], start=1):
            cols = [i for i in range(len(FUEL_TERMS)) if i != j]
            print_summaries(f"without {name}", summaries(d, held_out(d, groups, cols)[0]))
    if args.write:
        write_calibration_toml(final, folds, s, ROOT / "models" / "engine_calibration.toml", len(specs))
        write_error_toml(s, ROOT / "models" / "fuel_economy_error.toml",
                         "fit and errors on the simulation of this commit; see docs/validation-epa.md")
    d["error_heldout"] = err
    return d, table, s


if __name__ == "__main__":
    main()
