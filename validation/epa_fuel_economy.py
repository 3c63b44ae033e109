"""Fleet-wide calibration and held-out validation of the fuel model on the EPA 2022 Test Car List.

    PYTHONPATH=. python validation/epa_fuel_economy.py [--write] [--plots docs/img] [--ablation] [--candidates]

1. The fleet is what `fleetrun import-epa inputs/epa/22-tstcar.csv` writes, read back as
   `fleetrun run` reads it (validation/epa_table.py): every vehicle of the list that can be
   modelled. Each is simulated once per cycle with its trace; per vehicle and cycle (and FTP
   bag) the eight terms of the fuel equation (fleetrun/simulation/engine.py,
   ``fuel_power_terms_W``) are summed over the fuelled steps. The equation is linear in its
   constants, so warm fuel = terms . c / LHV exactly as the simulation computes it (checked).
2. The constants c >= 0 are fitted by non-negative least squares on the relative fuel error
   of the hot tests: hot UDDS (EPA bags 3 + 2), HWFET, US06 (one set for every light-duty
   gasoline engine; diesels share them with their own Willans slope and no throttle pumping).
3. The cold start (fleetrun/simulation/thermal.py) is then fitted on FTP bag 1 vs bag 3 of
   the same vehicles: its enrichment and heat capacity over a grid (``--thermal``).
4. Held out by manufacturer: for each manufacturer the constants are fitted without its
   vehicles and predict them; the FTP composite adds the simulated cold-start fuel (scaled
   with the fold's warm bag-1 fuel). The distribution of those held-out errors per test is
   ``models/fuel_economy_error.toml`` (read by the budget's ranges), and the spread of the
   fitted constants over the folds is their uncertainty in ``models/engine_calibration.toml``.
5. ``--ablation`` refits without each term or drivetrain piece; ``--candidates`` refits with
   each candidate term added (``candidate_columns``) and prints the test fuels of the rows.

Errors are predicted mpg / measured mpg - 1.
"""
from __future__ import annotations

import argparse
import dataclasses
import datetime
import itertools
import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import lsq_linear, nnls

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from epa_table import epa_fleet  # noqa: E402

from fleetrun.cycles import ftp_weighted_per_mile  # noqa: E402
from fleetrun.simulation.coastdown_driveline import VARIANTS  # noqa: E402
from fleetrun.simulation import simulate  # noqa: E402
from fleetrun.simulation.core import idle_fuel_rate_g_per_s, technology_fuel_inputs, trace_kinematics  # noqa: E402
from fleetrun.simulation.engine import (FUEL_TERMS, fuel_coefficients, fuel_power_terms_W,  # noqa: E402
                                        mean_piston_speed_m_s, mep_power_W_per_kPa)
from fleetrun.simulation.params import FUEL_CONSTANTS, vehicle_arrays  # noqa: E402
from fleetrun.simulation.technology import TECHNOLOGIES, technology_constants  # noqa: E402
from fleetrun.simulation.thermal import thermal_constants  # noqa: E402
from fleetrun.units import RAD_S_PER_RPM  # noqa: E402

GAL_L = 3.785411784
HOT_TESTS = {"UDDS:hot": "UDDS", "HWFET": "HWFET", "US06": "US06"}
REPORTED = ("FTP", "HWFET", "US06")
BAGS = ("bag1", "bag2", "bag3")
CHUNK = 150
MODE = "auto"
COASTDOWN_DRIVELINE = None  # None: models/road_load.toml (--coastdown-driveline)
THERMAL = None              # None: models/thermal.toml (epa_technology.py --cold-start-basis)
AMBIENT_C = 25.0            # EPA's nominal test-cell temperature (40 CFR 86.130: 20-30 C)
THERMAL_GRID = {"heat_capacity_kJ_per_K_per_L": (15.0, 22.0, 35.0, 55.0), "enrichment_gasoline": (0.05, 0.1, 0.15, 0.2, 0.3)}


def trace_terms(va, tr):
    """(V, N, 8) terms x dt over the fuelled steps of a trace (warm engine)."""
    col = lambda x: x[:, None]  # noqa: E731
    n, T, Tmax = tr.engine_speed_rpm, tr.engine_torque_Nm, tr.engine_max_torque_Nm
    k = trace_kinematics(tr)
    # technology classes: an engine that is off (start-stop stops, hybrids coasting) stands still
    # (speed 0) and its fuel, if any, is the fitted stop power, not the fuel equation
    dt = np.broadcast_to(k.dt, n.shape) * (((tr.fuel_rate_g_per_s - tr.cold_start_fuel_g_per_s) > 0) & (n > 0))
    inertial = col(va.mass_kg * (1.0 + va.rot_frac)) * k.accel * k.v_avg
    Tf = np.minimum(T, Tmax)
    pumping, gain = technology_fuel_inputs(va, Tf, n, Tmax, k.v_avg > 1e-6, col)
    terms = fuel_power_terms_W(Tf, n, Tmax, col(va.displacement_L), col(va.stroke_m),
                               col(va.T_peak), col(va.throttled), inertial, pumping, gain)
    return np.stack([np.broadcast_to(t, n.shape) * dt for t in terms], axis=2)


EXTRA_SUMS = ("speed", "speed2", "speed3", "idle_time", "cutoff_time", "stop_off_time", "transient_arrb",
              "friction_piston_speed2", "deac_credit", "idle_mep")


def trace_extras(va, tr):
    """(V, N, len(EXTRA_SUMS)) step quantities x dt for the candidate terms (``--candidates``): v, v^2, v^3 over
    the fuelled steps with positive wheel power [m, m^2/s, m^3/s^2], the fuelled standstill
    time [s], the time the engine turns in fuel cut-off [s] (warm engine), the standstill
    time with the engine off under start-stop [s] (technology classes: its fuel power is fitted;
    the engine stands still, outside a composed cycle's soak) and the acceleration term in the
    ARRB power model's form, max(a, 0) P_acc+ over the steps the fuel equation covers [J m/s^2]
    (docs/validation-epa.md "acceleration term in ARRB's form") and Chen & Flynn's c_m^2 friction
    term, FMEP power x c_m^2 over the same steps [W s^3/(kPa m^2)] (docs/validation-epa.md
    "friction by bore and by speed squared"), the cylinder-deactivation credit
    (:func:`deactivation_credit`) [J/kPa] and the mean-effective-pressure power of the
    displacement over the fuelled standstill steps [J/kPa] (docs/validation-epa.md "Hypothesis D1",
    "Hypothesis I1")."""
    fueled = (tr.fuel_rate_g_per_s - tr.cold_start_fuel_g_per_s) > 0
    k = trace_kinematics(tr)
    dt, v = np.broadcast_to(k.dt, fueled.shape), k.v_avg
    driving = dt * (fueled & (tr.wheel_power_W > 0))
    named = tr.phase != ""
    in_cycle = named if named.any() else True       # the FTP's soak has no phase name
    stop_off = dt * ((tr.engine_speed_rpm <= 0) & (v <= 0.0) & in_cycle)
    warm = dt * (fueled & (tr.engine_speed_rpm > 0))          # trace_terms' steps
    arrb = (va.mass_kg * (1.0 + va.rot_frac))[:, None] * np.maximum(k.accel, 0.0) ** 2 * v * warm
    c_m = mean_piston_speed_m_s(tr.engine_speed_rpm, va.stroke_m[:, None])
    friction_cm2 = mep_power_W_per_kPa(tr.engine_speed_rpm, va.displacement_L[:, None]) * c_m ** 2 * warm
    out = [v * driving, v ** 2 * driving, v ** 3 * driving, dt * (fueled & (v <= 0.0)),
           dt * (~fueled & (tr.engine_speed_rpm > 0)), stop_off, arrb, friction_cm2, deactivation_credit(va, tr, v, warm),
           mep_power_W_per_kPa(tr.engine_speed_rpm, va.displacement_L[:, None]) * warm * (v <= 0.0)]
    return np.stack(out, axis=2)


def deactivation_credit(va, tr, v, warm):
    """Minus the mean-effective-pressure power of half the displacement x dt over the warm steps
    in the cylinder-deactivation window (technology.deactivated_pumping_share's: moving, load below
    ``deac_max_load``, speed within its rpm window; vehicles with the class) [J/kPa]
    (docs/validation-epa.md "Hypothesis D1")."""
    c = technology_constants()
    n = tr.engine_speed_rpm
    load = np.clip(np.maximum(tr.engine_torque_Nm, 0.0) / np.maximum(tr.engine_max_torque_Nm, 1e-9), 0.0, 1.0)
    deac = va.technology[:, TECHNOLOGIES.index("cylinder_deactivation")][:, None]
    window = deac & (v > 1e-6) & (load < c.deac_max_load) & (n >= c.deac_min_rpm) & (n <= c.deac_max_rpm)
    return -mep_power_W_per_kPa(n, 0.5 * va.displacement_L[:, None]) * warm * window


def cycle_sums(specs, cycle):
    """Per vehicle: {part: (term sums (V, 8 + 5 extras), miles (V,), simulated fuel (V,), cold fuel (V,))}
    with part "" for a plain cycle and the bag names for the FTP."""
    parts = {}
    for a in range(0, len(specs), CHUNK):
        chunk = specs[a:a + CHUNK]
        r = simulate(chunk, cycle, mode=MODE, trace=True, ambient_temp_C=AMBIENT_C,
                     coastdown_driveline_removed=COASTDOWN_DRIVELINE, thermal=THERMAL)
        tr, va = r.trace, vehicle_arrays(chunk)
        terms = np.concatenate([trace_terms(va, tr), trace_extras(va, tr)], axis=2)
        if r.phases:
            phase = np.asarray(tr.phase)
            cold = tr.cold_start_fuel_g_per_s * trace_kinematics(tr).dt
            for k, name in enumerate(BAGS):
                m = phase == name if phase.dtype.kind in "UO" else phase == k
                parts.setdefault(name, []).append(((terms * m[..., None]).sum(axis=1), r.phases[name].miles,
                                                   r.phases[name].fuel_g, (cold * m).sum(axis=1)))
        else:
            parts.setdefault("", []).append((terms.sum(axis=1), r.miles, r.fuel_g, np.zeros(va.n)))
    return {k: tuple(np.concatenate([p[i] for p in v]) for i in range(4)) for k, v in parts.items()}


def build_dataset(specs, table):
    """Long table: one row per (vehicle, hot test) and per (vehicle, FTP bag), with the term
    sums, miles, measured and simulated fuel."""
    va = vehicle_arrays(specs)
    frames = []
    runs = {test: cycle_sums(specs, cycle) for test, cycle in HOT_TESTS.items()}
    runs.update({f"FTP:{b}": {"": part} for b, part in cycle_sums(specs, "FTP").items()})
    for test, parts in runs.items():
        S, miles, fuel_g, cold_g = parts[""]
        f = pd.DataFrame(S, columns=[f"S_{k}" for k in FUEL_TERMS] + [f"X_{k}" for k in EXTRA_SUMS])
        f["vehicle"], f["test"], f["miles"], f["sim_fuel_g"], f["cold_g"] = np.arange(len(specs)), test, miles, fuel_g, cold_g
        f["measured_mpg"] = table[test].to_numpy(float)
        frames.append(f)
    d = pd.concat(frames, ignore_index=True)
    d["fuel"] = [specs[i].fuel for i in d.vehicle]
    d["lhv"], d["rho"] = va.lhv[d.vehicle], va.density[d.vehicle]
    d["manufacturer"] = table.manufacturer.to_numpy()[d.vehicle]
    d["measured_fuel_g"] = d.miles / d.measured_mpg * GAL_L * d.rho * 1000.0
    d["X_stop_off_idle"] = d.X_stop_off_time.to_numpy() * idle_fuel_power_W(va)[d.vehicle]
    d.attrs["constants"] = va.fuel_constants
    return d


def idle_fuel_power_W(va):
    """Each vehicle's idle fuel power [W] with the stored constants (core.idle_fuel_rate_g_per_s x LHV)."""
    return idle_fuel_rate_g_per_s(va) * va.lhv * 1e3


def design(d, extra=()):
    """Fuel [g] per unit coefficient: terms / (LHV [MJ/kg] x 1e3); ``extra``: names of candidate
    columns of ``d`` (energy [J] per unit coefficient) appended after the eight terms."""
    return d[[f"S_{k}" for k in FUEL_TERMS] + list(extra)].to_numpy() / (d.lhv.to_numpy()[:, None] * 1e3)


def coefficients_of(constants):
    """The named constants (V, 8) -> the weights of the terms (V, 8) (engine.fuel_coefficients)."""
    return np.stack([np.asarray(c, float) for c in fuel_coefficients(*np.asarray(constants, float).T)], axis=-1)


PUMPING = FUEL_TERMS.index("pumping")


def fit(d, columns=None, extra=(), lower=None):
    """Non-negative least squares on the relative fuel error of the hot tests: {fuel: (8 + extras,)}.

    Gasoline: all eight coefficients (``columns``: the terms kept, others 0). Diesel: the
    gasoline coefficients scaled by one factor (its Willans slope), pumping term 0.
    ``extra``: candidate columns (gasoline only) whose coefficients have the lower bounds
    ``lower`` (default 0; bounded least squares when one is negative).
    """
    columns = list(range(len(FUEL_TERMS))) if columns is None else list(columns)
    columns += list(range(len(FUEL_TERMS), len(FUEL_TERMS) + len(extra)))
    d = d[d.test.isin(list(HOT_TESTS)) & np.isfinite(d.measured_fuel_g)]
    X, y = design(d, extra), d.measured_fuel_g.to_numpy()
    gas = (d.fuel == "gasoline").to_numpy()
    c = np.zeros(len(FUEL_TERMS) + len(extra))
    A = X[gas][:, columns] / y[gas, None]
    if lower is None or min(lower) >= 0:
        c[columns], _ = nnls(A, np.ones(gas.sum()))
    else:
        bounds = np.r_[np.zeros(len(columns) - len(extra)), lower]
        c[columns] = lsq_linear(A, np.ones(gas.sum()), bounds=(bounds, np.inf)).x
    unthrottled = np.where(np.arange(len(c)) == PUMPING, 0.0, c)
    unthrottled[len(FUEL_TERMS):] = 0.0
    result = {"gasoline": c, "diesel": unthrottled}
    if (~gas).any():
        base = X[~gas] @ unthrottled / y[~gas]
        result["diesel"] = float(np.sum(base) / np.sum(base ** 2)) * unthrottled
    return result


def predicted_fuel_g(d, coef, extra=()):
    """Fuel [g] of every row with the coefficients ``coef``: warm terms . c, plus on the FTP
    bags the simulated cold-start fuel scaled with the bag's warm fuel."""
    c = np.where((d.fuel == "gasoline").to_numpy()[:, None], coef["gasoline"], coef["diesel"])
    warm = (design(d, extra) * c).sum(axis=1)
    sim_warm = (d.sim_fuel_g - d.cold_g).to_numpy()
    with np.errstate(divide="ignore", invalid="ignore"):
        return warm + np.where(sim_warm > 0, d.cold_g.to_numpy() * warm / sim_warm, 0.0)


def errors(d, fuel_g):
    """Per vehicle and reported test (incl. the FTP composite and hot UDDS): predicted mpg /
    measured mpg - 1, as a table vehicles x tests."""
    d = d.assign(pred_g=fuel_g, pred_mpg=d.miles / (fuel_g / 1000.0 / d.rho / GAL_L))
    wide = d.pivot_table(index="vehicle", columns="test", values=["pred_g", "miles", "pred_mpg"])
    out = pd.DataFrame(index=wide.index)
    for test in ("UDDS:hot", "HWFET", "US06", "FTP:bag1", "FTP:bag2", "FTP:bag3"):
        out[test] = wide["pred_mpg"][test]
    g = {b: wide["pred_g"][f"FTP:{b}"] for b in BAGS}
    mi = {b: wide["miles"][f"FTP:{b}"] for b in BAGS}
    rho = d.groupby("vehicle").rho.first()
    out["FTP"] = 1.0 / (ftp_weighted_per_mile(g["bag1"], g["bag2"], g["bag3"], mi["bag1"], mi["bag2"], mi["bag3"])
                        / 1000.0 / rho / GAL_L)
    return out


def relative_errors(pred_mpg, table):
    return pd.DataFrame({t: pred_mpg[t].to_numpy() / table[t].to_numpy() - 1.0 for t in pred_mpg.columns})


def held_out(d, table, columns=None, extra=(), lower=None):
    """Predicted mpg of each vehicle by the fit without its manufacturer; the folds' fits."""
    parts, fits = [], {}
    for g in table.manufacturer.unique():
        out = (d.manufacturer == g).to_numpy()
        coef = fit(d[~out], columns, extra, lower)
        parts.append(errors(d[out], predicted_fuel_g(d[out], coef, extra)))
        fits[g] = coef
    return pd.concat(parts).sort_index(), fits


def constants_of(c):
    """Coefficient vector (8,) -> the named constants (eta_indicated first)."""
    eta = 1.0 / c[0]
    return {"eta_indicated": eta, **{k: c[j] * eta for j, k in enumerate(FUEL_CONSTANTS) if j > 0}}


def summary(err):
    e = np.asarray(err, float)
    e = e[np.isfinite(e)]
    return dict(n=int(e.size), mean=float(e.mean()), median=float(np.median(e)),
                median_abs=float(np.median(np.abs(e))), p05=float(np.quantile(e, 0.05)),
                p95=float(np.quantile(e, 0.95)), within_5pct=float(np.mean(np.abs(e) <= 0.05)))


def summaries(err, tests=("FTP", "UDDS:hot", "HWFET", "US06")):
    return {t: summary(err[t]) for t in tests}


def print_summaries(label, s):
    line = f"{label:30s}"
    for test, v in s.items():
        line += f" | {test}: n={v['n']} mean={v['mean']:+.3f} med|e|={v['median_abs']:.3f} w5={v['within_5pct']:.2f}"
    print(line, flush=True)


def write_error_toml(s, path):
    lines = ['source = "validation/epa_fuel_economy.py: EPA 2022 Test Car List, held out by manufacturer"',
             f'measured_on = "{datetime.date.today().isoformat()}"',
             'note = "relative error = predicted mpg / measured mpg - 1 of held-out vehicles (each manufacturer '
             'predicted by the constants fitted without it); docs/validation-epa.md"', ""]
    for test in REPORTED:
        v = s[test]
        lines.append(f"[tests.{test}]")
        lines.append(f"n = {v['n']}")
        lines += [f"{key} = {v[key]:.4f}" for key in ("mean", "median", "p05", "p95", "within_5pct", "median_abs")]
        lines.append("")
    Path(path).write_text("\n".join(lines))


def write_calibration_toml(final, folds, path, n_vehicles):
    """models/engine_calibration.toml: the fitted constants (all vehicles) with the spread of
    the manufacturer-held-out folds."""
    lines = ["# Fleet-wide calibration of the fuel-equation constants (fleetrun/simulation/engine.py).",
             "# Written by validation/epa_fuel_economy.py --write; do not edit by hand.",
             f'source = "EPA 2022 Test Car List (inputs/epa/22-tstcar.csv) through fleetrun import-epa, {n_vehicles} '
             'vehicles; tests hot UDDS (FTP bags 3 + 2), HWFE, US06"',
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


def group_table(err, table, by):
    """Median error and share within 5 % per group of ``by`` (a table column), per test."""
    rows = []
    for key, idx in table.groupby(by, observed=True).groups.items():
        e = err.loc[idx]
        row = {by: key, "n": len(idx)}
        for t in REPORTED:
            x = e[t].dropna()
            row[f"{t} median"] = x.median() if len(x) else np.nan
            row[f"{t} within 5 %"] = np.mean(np.abs(x) <= 0.05) if len(x) else np.nan
        rows.append(row)
    return pd.DataFrame(rows)


def limits(err, table, specs):
    """What limits the held-out accuracy: the correlation of a vehicle's errors across tests,
    and the split of each test's error into manufacturer means and the scatter within them
    (with the share within 5 % that even exact manufacturer means would leave)."""
    lines = ["correlation of held-out errors: " + ", ".join(
        f"{a} vs {b} {err[[a, b]].dropna().corr().iloc[0, 1]:.2f}" for a, b in
        (("UDDS:hot", "HWFET"), ("UDDS:hot", "US06"), ("HWFET", "US06"), ("FTP", "HWFET")))]
    for test in REPORTED:
        e = pd.Series(err[test].to_numpy(), index=table.manufacturer.to_numpy()).dropna()
        means = e.groupby(level=0).transform("mean")
        lines.append(f"{test}: sd {e.std():.3f} (manufacturer means: sd {means.std():.3f}; within manufacturers: sd "
                     f"{(e - means).std():.3f}); within 5 % with each manufacturer's mean error removed (in sample): "
                     f"{np.mean(np.abs(e - means) <= 0.05):.0%}")
    nv = pd.Series([getattr(v, "nv_ratio_rpm_per_mph", None) for v in specs], index=table.index, dtype=float)
    for name, key, edges in (("specific power [kW/L]", table.specific_power_kW_per_L, [0, 100, 130, 1000]),
                             ("N/V [rpm/mph]", nv, [0, 25, 30, 100]),
                             ("displacement [L]", table.displacement_L, [0, 1.6, 2.1, 2.6, 3.1, 4, 5, 9])):
        bins = pd.cut(key, edges)
        cells = [f"{b}: n={int(err.FTP[(bins == b).to_numpy()].notna().sum())} "
                 + " / ".join(f"{err[t][(bins == b).to_numpy()].median():+.1%}" for t in ("FTP", "HWFET"))
                 for b in bins.cat.categories]
        lines.append(f"median error FTP / HWFET by {name}: " + "; ".join(cells))
    return lines


def thermal_variant(heat_capacity_kJ_per_K_per_L, enrichment_gasoline):
    """The cold-start constants of models/thermal.toml with the two fitted ones replaced."""
    k = thermal_constants()
    return dataclasses.replace(k, heat_capacity_J_per_K_per_L=1e3 * heat_capacity_kJ_per_K_per_L,
                               enrichment_at_25C={**k.enrichment_at_25C, "gasoline": enrichment_gasoline})


def bag_ratio_grid(specs, table, grid_values=None, variant=None):
    """Model bag 1 / bag 3 and bag 2 / bag 3 fuel per mile for each grid point {(C, e): (V, 2)}
    (gasoline vehicles with the three bags measured), and EPA's (= mpg bag 3 / mpg bag k).
    ``grid_values``, ``variant``: another grid and constants maker (default THERMAL_GRID,
    :func:`thermal_variant`)."""
    grid_values = THERMAL_GRID if grid_values is None else grid_values
    variant = thermal_variant if variant is None else variant
    keep = np.flatnonzero((table.fuel == "gasoline").to_numpy()
                          & np.isfinite(table[["FTP:bag1", "FTP:bag2", "FTP:bag3"]].to_numpy()).all(axis=1))
    chosen = [specs[i] for i in keep]
    grid = {}
    for point in itertools.product(*grid_values.values()):
        k = variant(*point)
        ratios = []
        for a in range(0, len(chosen), CHUNK):
            ph = simulate(chosen[a:a + CHUNK], "FTP", mode=MODE, ambient_temp_C=AMBIENT_C, thermal=k).phases
            per_mile = {b: ph[b].fuel_g / ph[b].miles for b in BAGS}
            ratios.append(np.stack([per_mile["bag1"] / per_mile["bag3"], per_mile["bag2"] / per_mile["bag3"]], axis=1))
        grid[point] = np.concatenate(ratios)
    measured = np.stack([table["FTP:bag3"] / table["FTP:bag1"], table["FTP:bag3"] / table["FTP:bag2"]], axis=1)[keep]
    return keep, grid, measured


def fit_thermal(specs, table, grid_values=None, variant=None):
    """The grid point with the least squared log error of bag 1 / bag 3 and bag 2 / bag 3 (all
    vehicles: the cold start must show in bag 1 and be over by bag 2), the point each
    manufacturer-held-out fold chooses, and the held-out bag-1 ratio errors (``grid_values``,
    ``variant``: :func:`bag_ratio_grid`)."""
    keep, grid, measured = bag_ratio_grid(specs, table, grid_values, variant)
    groups = table.manufacturer.to_numpy()[keep]
    cost = {p: (np.log(r / measured) ** 2).sum(axis=1) for p, r in grid.items()}
    best = min(cost, key=lambda p: cost[p].mean())
    folds, held = {}, np.full(keep.size, np.nan)
    for g in np.unique(groups):
        out = groups == g
        p = min(cost, key=lambda q: cost[q][~out].mean())
        folds[g] = p
        held[out] = grid[p][out, 0] / measured[out, 0] - 1.0
    return dict(best=best, folds=folds, heldout_ratio_error=held, grid_rmse={p: float(np.sqrt(c.mean() / 2)) for p, c in cost.items()})


def write_thermal_toml(th, path):
    """Replace the two fitted constants of models/thermal.toml (value lines) and its source."""
    text = Path(path).read_text()
    names = list(THERMAL_GRID)
    chosen = dict(zip(names, th["best"]))
    fold = {n: sorted({p[i] for p in th["folds"].values()}) for i, n in enumerate(names)}
    text = re.sub(r"(?m)^heat_capacity_kJ_per_K_per_L = .*$",
                  f"heat_capacity_kJ_per_K_per_L = {chosen[names[0]]:g}", text)
    text = re.sub(r"(?ms)(^\[enrichment\].*?^gasoline = ).*?$", rf"\g<1>{chosen[names[1]]:g}", text)
    note = (f'source = "heat_capacity_kJ_per_K_per_L and [enrichment] gasoline fitted fleet-wide by '
            f'validation/epa_fuel_economy.py --write ({datetime.date.today().isoformat()}): grid '
            f'{THERMAL_GRID[names[0]]} x {THERMAL_GRID[names[1]]}, least squared log error of FTP bag 1 / bag 3 '
            f'and bag 2 / bag 3 fuel per mile (EPA 2022 Test Car List, 25 C); leave-one-manufacturer-out folds chose '
            f'{fold[names[0]]} and {fold[names[1]]}; the other keys are literature defaults"')
    text = re.sub(r"(?m)^source = .*$", note.replace("\\", "\\\\"), text, count=1)
    Path(path).write_text(text)


def plots(err, pred, table, folder):
    """docs/img/validation-epa-*.png: predicted vs measured per test; held-out error by drive,
    gearbox, specific power and displacement."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.3))
    for ax, test in zip(axes, REPORTED):
        m, p_ = table[test].to_numpy(float), pred[test].to_numpy(float)
        ok = np.isfinite(m) & np.isfinite(p_)
        ax.scatter(m[ok], p_[ok], s=6, alpha=0.5)
        lim = [0, np.nanmax(np.r_[m[ok], p_[ok]]) * 1.05]
        ax.plot(lim, lim, "k-", lw=0.8)
        ax.plot(lim, [x * 1.05 for x in lim], "k:", lw=0.8)
        ax.plot(lim, [x * 0.95 for x in lim], "k:", lw=0.8)
        e = err[test].to_numpy(float)[ok]
        ax.set_title(f"{test}: n={ok.sum()}, {np.mean(np.abs(e) <= 0.05):.0%} within 5 %, mean {e.mean():+.1%}")
        ax.set_xlabel("EPA measured mpg (unadjusted)")
        ax.set_ylabel("fleetrun mpg, manufacturer held out")
        ax.set_xlim(lim), ax.set_ylim(lim)
    fig.tight_layout()
    fig.savefig(folder / "validation-epa-predicted-vs-measured.png", dpi=110)
    plt.close(fig)
    groups = {"drive": table.configuration, "gearbox": table.gearbox_type,
              "specific power [kW/L]": pd.cut(table.specific_power_kW_per_L, [0, 50, 60, 70, 80, 100, 130, 400]),
              "displacement [L]": pd.cut(table.displacement_L, [0, 1.6, 2.1, 2.6, 3.1, 4.0, 5.0, 9.0])}
    fig, axes = plt.subplots(len(groups), 1, figsize=(11, 3.2 * len(groups)))
    for ax, (name, g) in zip(axes, groups.items()):
        labels = [str(x) for x in g.dropna().unique()]
        labels = sorted(labels, key=lambda x: (len(x), x)) if name in ("drive", "gearbox") else \
            [str(c) for c in g.cat.categories if str(c) in labels]
        pos = np.arange(len(labels))
        for k, test in enumerate(REPORTED):
            data = [err[test][(g.astype(str) == lab).to_numpy()].dropna().to_numpy() for lab in labels]
            bp = ax.boxplot(data, positions=pos + (k - 1) * 0.27, widths=0.24, showfliers=False, patch_artist=True)
            for box in bp["boxes"]:
                box.set_facecolor(f"C{k}")
            ax.plot([], [], color=f"C{k}", lw=6, label=test)
        ax.axhspan(-0.05, 0.05, color="0.9", zorder=0)
        ax.axhline(0, color="k", lw=0.6)
        ax.set_xticks(pos, [f"{lab}\n(n={int((g.astype(str) == lab).sum())})" for lab in labels], fontsize=8)
        ax.set_ylabel("held-out error")
        ax.set_title(f"error by {name}")
        ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(folder / "validation-epa-error-by-group.png", dpi=110)
    plt.close(fig)


def _with(spec, **extra):
    return dataclasses.replace(spec, extra={**spec.extra, **extra})


#: Drivetrain pieces switched off one at a time (the fuel constants refitted each time).
DRIVETRAIN_ABLATION = {
    "CVT driven as its 10 stepped ratios": lambda v: dataclasses.replace(v, gearbox_type="automatic")
    if v.gearbox_type == "cvt" else v,
    "no spin loss (constant gear efficiency 0.955 / 0.975 as before)": lambda v: _with(
        v, spin_loss_Nm_at_0=0.0, spin_loss_Nm_per_krpm=0.0, gear_efficiency=0.955, direct_gear_efficiency=0.975),
    "converter_lockup ignored (every converter locks)": lambda v: dataclasses.replace(v, converter_lockup="yes"),
    "no later shifts while accelerating": lambda v: _with(v, shift_speed_accel_rpm=0.0),
}


def ablation(specs, table, r):
    """Held-out summaries with one piece of the model left out: each fuel term (refit without
    it) and each drivetrain piece (re-simulated, refit)."""
    lines = []
    for j, name in enumerate(FUEL_TERMS[1:], start=1):
        cols = [i for i in range(len(FUEL_TERMS)) if i != j]
        pred, _ = held_out(r["d"], table, cols)
        lines.append(_summary_line(f"without the {name} term", summaries(relative_errors(pred, table))))
    for name, change in DRIVETRAIN_ABLATION.items():
        variant = run([change(v) for v in specs], table)
        lines.append(_summary_line(name, summaries(variant["err"])))
    return lines


LBF_N, MPH_M_S = 4.4482216152605, 0.44704
ROW_TEST = {"UDDS:hot": "FTP", "FTP:bag1": "FTP", "FTP:bag2": "FTP", "FTP:bag3": "FTP", "HWFET": "HWFET", "US06": "US06"}
LIST_COLUMNS = {"Set Coef A (lbf)": "set_A", "Set Coef B (lbf/mph)": "set_B", "Set Coef C (lbf/mph**2)": "set_C",
                "Target Coef A (lbf)": "target_A", "Target Coef B (lbf/mph)": "target_B",
                "Target Coef C (lbf/mph**2)": "target_C", "DT-Inertia Work Ratio Rating": "IWR",
                "DT-Energy Economy Rating": "EER"}


def list_rows(table, path=None):
    """The list's rows behind the measured values (validation/epa_table.py's ``test_rows`` on
    the vehicle's own fuel: fleetrun.epa.measured's rules) of the vehicles of ``table``: per
    vehicle and test (FTP, HWFET, US06) the mean of the LIST_COLUMNS (drive-quality sentinels
    99.99 -> NaN), and the test fuel descriptions of those rows."""
    from epa_table import TSTCAR, drive_quality_rating, own_fuel_rows, test_rows

    raw = own_fuel_rows(test_rows(path or TSTCAR), table)
    rows = raw[["vehicle_id", "test"]].copy()
    for col, name in LIST_COLUMNS.items():
        rows[name] = (drive_quality_rating(raw[col]) if col.startswith("DT-")
                      else pd.to_numeric(raw[col], errors="coerce"))
    fuels = raw["Test Fuel Type Description"].str.strip().rename("fuel_description")
    return rows.groupby(["vehicle_id", "test"])[list(LIST_COLUMNS.values())].mean(), fuels


def _row_values(d, table, per_test, name):
    """Per row of ``d``: the list value ``name`` of its vehicle and test (0 where missing)."""
    ids = table.vehicle_id.to_numpy()[d.vehicle.to_numpy()]
    keys = pd.MultiIndex.from_arrays([ids, d.test.map(ROW_TEST).to_numpy()])
    return np.nan_to_num(per_test[name].reindex(keys).to_numpy(float))


def candidate_columns(d, specs, table):
    """The candidate terms (docs/validation-epa.md, "Candidates measured"): name -> (columns
    {name: energy [J] per unit coefficient, per row of ``d``}, lower bounds of their
    coefficients). A coefficient multiplies the term like the eight of the fuel equation."""
    va = vehicle_arrays(specs)
    per = lambda x: np.asarray(x, float)[d.vehicle.to_numpy()]  # noqa: E731
    sp = per(table.specific_power_kW_per_L.to_numpy()) / 100.0                      # [100 kW/L]
    bmep = per(4.0 * np.pi * va.T_peak / va.displacement_L) / 1e3                   # bmep_max [MPa]
    per_test, _ = list_rows(table)
    val = lambda name: _row_values(d, table, per_test, name)  # noqa: E731
    dA, dB, dC = (val(f"target_{k}") - val(f"set_{k}") for k in "ABC")
    own_loss_J = LBF_N * (dA * d.X_speed + dB / MPH_M_S * d.X_speed2 + dC / MPH_M_S ** 2 * d.X_speed3)
    drag_W = np.where(va.automatic, (va.n_idle / va.K_tc) ** 2, 0.0) * va.n_idle * RAD_S_PER_RPM
    S = lambda k: d[f"S_{k}"].to_numpy()  # noqa: E731
    free = [-np.inf]
    return {
        "brake work x (P/V_d - 100 kW/L)+ (efficiency falls at high specific output)":
            ({"C": S("brake") * np.maximum(sp - 1.0, 0.0)}, [0.0]),
        "brake work x bmep_max (efficiency falls with boost)": ({"C": S("brake") * bmep}, [0.0]),
        "FMEP x P/V_d (friction rises with specific output)": ({"C": S("friction") * sp}, [0.0]),
        "FMEP c_m x P/V_d": ({"C": S("friction_piston_speed") * sp}, [0.0]),
        "target - set road-load work (free sign)": ({"C": own_loss_J.to_numpy()}, free),
        "converter drag at standstill in drive (automatics)": ({"C": d.X_idle_time.to_numpy() * per(drag_W)}, [0.0]),
        "standstill time (free sign)": ({"C": d.X_idle_time.to_numpy()}, free),
        "time in fuel cut-off (free sign)": ({"C": d.X_cutoff_time.to_numpy()}, free),
        "acceleration term x IWR (drive quality, free sign)": ({"C": S("transient") * val("IWR") / 100.0}, free),
        "brake work x EER (drive quality, free sign)": ({"C": S("brake") * val("EER") / 100.0}, free),
    }


def candidates(r, specs, table):
    """Held-out summaries with each candidate term added to the eight (refit), and the test
    fuels of the measured rows."""
    _, fuels = list_rows(table)
    lines = [f"test fuels of the measured rows: {fuels.value_counts().to_dict()}",
             "| candidate | FTP | hot UDDS | HWFET | US06 | > 100 kW/L: FTP / HWFET median | coefficient x eta_indicated |"]
    high = (table.specific_power_kW_per_L > 100.0).to_numpy()

    def line(name, err, coef):
        group = " / ".join(f"{err[t][high].median():+.1%}" for t in ("FTP", "HWFET"))
        return _summary_line(name, summaries(err))[:-1] + f"| {group} | {coef} |"

    lines.append(line("none (the model)", r["err"], ""))
    for name, (cols, lower) in candidate_columns(r["d"], specs, table).items():
        d = r["d"].assign(**cols)
        pred, _ = held_out(d, table, extra=list(cols), lower=lower)
        c = fit(d, extra=list(cols), lower=lower)["gasoline"]
        lines.append(line(name, relative_errors(pred, table), f"{c[len(FUEL_TERMS)] / c[0]:.4g}"))
    return lines


def _summary_line(label, s):
    return "| " + label + " | " + " | ".join(
        f"{v['mean']:+.1%} / {v['median_abs']:.1%} / {v['within_5pct']:.0%}" for t, v in s.items()) + " |"


#: start-stop's stop fuel, fitted with the constants (models/technology.toml): "constant" a fuel power
#: [W] per second of engine-off standstill, "idle_share" a share of the vehicle's own idle fuel power
#: (docs/validation-epa.md "Hypothesis S1"), "both" the two side by side
STOP_FORMS = {"constant": ("X_stop_off_time",), "idle_share": ("X_stop_off_idle",),
              "both": ("X_stop_off_time", "X_stop_off_idle")}
STOP = STOP_FORMS["constant"]


def run(specs, table):
    """Dataset, held-out predictions, final fit and summaries."""
    d = build_dataset(specs, table)
    own = (design(d) * coefficients_of(d.attrs["constants"][d.vehicle])).sum(axis=1)
    own = own + d.X_stop_off_time.to_numpy() * technology_constants().stop_fuel_power_W / (d.lhv.to_numpy() * 1e3)
    warm_sim = (d.sim_fuel_g - d.cold_g).to_numpy()
    gap = float(np.max(np.abs(own / warm_sim - 1.0)))
    pred, folds = held_out(d, table, extra=STOP)
    final = fit(d, extra=STOP)
    return dict(d=d, gap=gap, pred=pred, folds=folds, final=final,
                err=relative_errors(pred, table), err_sim=relative_errors(errors(d, d.sim_fuel_g.to_numpy()), table),
                err_in=relative_errors(errors(d, predicted_fuel_g(d, final, STOP)), table))


def write_stop_power(final, path):
    """The fitted start-stop stop power [W] into models/technology.toml [fitted]."""
    text = Path(path).read_text()
    Path(path).write_text(re.sub(r"stop_fuel_power_W = [0-9.eE+-]+", f"stop_fuel_power_W = {final['gasoline'][-1]:.1f}",
                                 text))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="write models/engine_calibration.toml and "
                    "models/fuel_economy_error.toml")
    ap.add_argument("--plots", type=Path, help="folder for the figures (docs/img)")
    ap.add_argument("--ablation", action="store_true", help="refit without each fuel term")
    ap.add_argument("--candidates", action="store_true", help="refit with each candidate term added")
    ap.add_argument("--thermal", action="store_true", help="fit the cold start on bag 1 / bag 3 (16 FTP runs)")
    ap.add_argument("--coastdown-driveline", choices=VARIANTS,
                    help="driveline spin loss taken out of the road load (default: models/road_load.toml)")
    args = ap.parse_args(argv)
    global COASTDOWN_DRIVELINE
    COASTDOWN_DRIVELINE = args.coastdown_driveline

    specs, table = epa_fleet()
    if args.thermal:
        th = fit_thermal(specs, table)
        print("cold start: grid RMSE of log(bag1/bag3)", {k: round(v, 4) for k, v in th["grid_rmse"].items()})
        print("chosen", th["best"], "held-out bag-ratio error", summary(th["heldout_ratio_error"]))
        if args.write:
            write_thermal_toml(th, ROOT / "models" / "thermal.toml")
            thermal_constants.cache_clear()
    r = run(specs, table)
    print(f"{len(specs)} vehicles; the terms reproduce the simulated warm fuel to {r['gap']:.1e}")
    print_summaries("simulation as configured", summaries(r["err_sim"]))
    s = summaries(r["err"])
    print_summaries("held out by manufacturer", s)
    print_summaries("in-sample (all vehicles)", summaries(r["err_in"]))
    print_summaries("  bags held out", summaries(r["err"], ("FTP:bag1", "FTP:bag2", "FTP:bag3")))
    for fuel, c in r["final"].items():
        print(fuel, {k: round(float(v), 4) for k, v in constants_of(c).items()})
    for line in limits(r["err"], table, specs):
        print(line)
    for by in ("gearbox_type", "fuel"):
        print(group_table(r["err"], table, by).round(3).to_string(index=False))
    if args.plots:
        plots(r["err"], r["pred"], table, args.plots)
    if args.ablation:
        for line in ablation(specs, table, r):
            print(line, flush=True)
    if args.candidates:
        for line in candidates(r, specs, table):
            print(line, flush=True)
    if args.write:
        write_calibration_toml(r["final"], r["folds"], ROOT / "models" / "engine_calibration.toml", len(specs))
        write_stop_power(r["final"], ROOT / "models" / "technology.toml")
        write_error_toml(s, ROOT / "models" / "fuel_economy_error.toml")
    return r, table


if __name__ == "__main__":
    main()
