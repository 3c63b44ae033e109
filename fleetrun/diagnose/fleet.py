"""``fleetrun diagnose-fleet``: physics hidden in a whole fleet's test results (issue 11).

>>> result = diagnose_fleet("fleet.xlsx", "measured.csv", out="diagnosis-fleet")  # doctest: +SKIP

A fleet's certification results hold, per vehicle, the fuel economy of the cold-start bag 1
and the hot-start bag 3 of the same 505-s trace, bag 2, the highway and US06 tests. Effects
the simulation leaves out show up as a pattern across tests and vehicles. Steps
(docs/diagnose-fleet.md):

1. **Simulate** every vehicle (:func:`simulate_fleet`): the *baseline* is the simulation
   without the physics to be found: a warm engine on every test (the UDDS bags driven as
   plain cycles; HWFET and US06 are driven warm anyway). The *full model* adds the
   cold-start thermal model (:mod:`fleetrun.simulation.thermal`, on the FTP).
2. **Residual** per vehicle and test: ``r = ln(measured fuel per mile / simulated)`` =
   ``ln(simulated mpg / measured mpg)``; errors are reported as predicted mpg / measured - 1.
   One global constant (a fuel-map scale) is always fitted, on the hot-engine tests only
   (bag 2, bag 3, HWFET, US06: the fleet's hot-start reference, as ``--calibrate-on`` for one
   recording), so that it cannot absorb a cold start.
3. **Candidates** (:func:`candidate_columns`), each with one global parameter for the whole
   fleet: ``warmup`` (a cold start's extra fuel as a share of bag 1's), ``warmup_thermal``
   (a scale on the simulation's own cold-start model), ``accessory_load``
   (constant power while the engine runs), ``cylinder_deactivation`` (a share of the fuel
   saved while cruising, on engines of 6 or more cylinders).
4. **Selection** by held-out error, held out by manufacturer (:func:`manufacturer_folds`): a
   candidate is accepted only if it lowers the held-out mean absolute error by more than
   ``min_gain`` and the improvement holds across manufacturers (paired one-sided t test,
   each manufacturer one observation, beyond the ``quantile``).
5. **What stays unexplained** (:func:`unexplained`): the held-out residual by test and by
   vehicle property (specific power, displacement, drive, transmission, weight, cylinders),
   each against a shuffled null; also against the full model.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from fleetrun import __version__, plausible
from fleetrun.cycles import DriveCycle, FTP_TRANSIENT_WEIGHT, ftp_bag1_end_s, ftp_weighted_per_mile, load_cycle
from fleetrun.diagnose.fleet_report import render_fleet_html
from fleetrun.diagnose.integrals import BAG_BOUNDARIES_S
from fleetrun.diagnose.select import _solve_bounded
from fleetrun.effects.vehicle import marginal_fuel_g_per_J
from fleetrun.errors import InputError
from fleetrun.fileio import JsonDocument, prepare_output_folder, write_text_atomic
from fleetrun.simulation import simulate
from fleetrun.simulation.params import willans_slope
from fleetrun.workbook.reader import read_fleet

SCHEMA = "fleetrun.fleet-diagnosis/1"
#: Tests the measured-results CSV may hold (docs/interface.md, diagnose-fleet).
TESTS = ("FTP:bag1", "FTP:bag2", "FTP:bag3", "FTP", "HWFET", "US06")
BAGS = ("FTP:bag1", "FTP:bag2", "FTP:bag3")
#: Vehicle properties the unexplained residual is tested against.
PROPERTIES = ("specific_power_W_per_kg", "engine_displacement_L", "drive", "transmission",
              "test_weight_kg", "cylinders")


@dataclass
class FleetSettings:
    folds: int = 5
    n_perm: int = 200                    # shuffles of the unexplained-by-property null
    quantile: float = 0.99
    min_gain: float = 0.01
    max_effects: int = 3
    seed: int = 0
    #: an effect "is in" a test where it adds more than this share of fuel on average
    test_share: float = 0.01


@dataclass
class FleetProblem:
    """Residuals and candidate columns, one row per measured (vehicle, test)."""

    vehicle_ids: list
    vehicle: np.ndarray                 # row -> vehicle index
    test: np.ndarray                    # row -> test name
    manufacturer: np.ndarray            # row -> manufacturer
    residual: np.ndarray                # ln(measured fuel per mile / baseline)
    residual_full: np.ndarray           # the same against the full model
    candidates: dict[str, np.ndarray]   # effect id -> column (rows,)
    untestable: dict[str, str]          # effect id -> reason
    properties: dict[str, np.ndarray]   # property -> (vehicles,) values
    notes: list = field(default_factory=list)


@dataclass(frozen=True)
class FuelAmounts:
    """Simulated fuel [g, gal] and miles per vehicle over one test (arrays (V,))."""
    g: np.ndarray
    gal: np.ndarray
    mi: np.ndarray


@dataclass(frozen=True)
class FleetSimulation:
    """:func:`simulate_fleet`: per test (``FTP``, ``FTP:bag1``.., ``HWFET``, ``US06``) the fuel
    with a warm engine (``warm``) and with the cold-start model (``full``), and the engine-on
    seconds per mile (``s_per_mi``, (V,) or one number)."""
    warm: dict[str, FuelAmounts]
    full: dict[str, FuelAmounts]
    s_per_mi: dict[str, np.ndarray | float]


@dataclass(frozen=True)
class PerTestError:
    """One test's row of diagnosis.json's ``tests`` tables: rows, mean error (all data
    fitted), held-out mean absolute error."""
    n: int
    mean_error: float
    heldout_mae: float

    def as_json(self) -> JsonDocument:
        return {"n": self.n, "mean_error": self.mean_error, "heldout_mae": self.heldout_mae}


@dataclass(frozen=True)
class OutlyingTest:
    """A test whose mean held-out error stands out (``unexplained.test_details``)."""
    test: str
    mean_error: float
    clustered_se: float

    def as_json(self) -> JsonDocument:
        return {"test": self.test, "mean_error": self.mean_error, "clustered_se": self.clustered_se}


@dataclass(frozen=True)
class PropertyLink:
    """How strongly the per-vehicle mean error follows a vehicle property (``unexplained.drivers``),
    with the mean error per bin of the property (``profile``: (bin label, vehicles, mean error))."""
    property: str
    strength: float
    significant: bool
    null_threshold: float
    profile: tuple[tuple[str, int, float], ...]

    def as_json(self) -> JsonDocument:
        return {"property": self.property, "strength": self.strength, "significant": self.significant,
                "null_threshold": self.null_threshold,
                "profile": [{"bin": b, "n": n, "mean_error": e} for b, n, e in self.profile]}


@dataclass(frozen=True)
class FleetUnexplained:
    """diagnosis.json's ``unexplained`` of a fleet (:func:`unexplained`)."""
    significant: bool
    test_details: tuple[OutlyingTest, ...]
    drivers: tuple[PropertyLink, ...]

    def as_json(self) -> JsonDocument:
        return {"significant": self.significant, "tests": [t.test for t in self.test_details],
                "test_details": [t.as_json() for t in self.test_details],
                "drivers": [d.as_json() for d in self.drivers]}


# ----------------------------------------------------------------------------- inputs
def read_measured(path, known_ids) -> dict[tuple[str, str], tuple[float, str]]:
    """MEASURED.csv (docs/interface.md): ``{(vehicle_id, test): (mpg, manufacturer or "")}``.

    Errors name the file, the row as a spreadsheet shows it, the column and the value.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("measured-results file not found", file=path,
                         hint="Give the CSV that `fleetrun import-epa --measured-out` writes")
    try:
        df = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (pd.errors.ParserError, UnicodeDecodeError, pd.errors.EmptyDataError) as exc:
        raise InputError(f"cannot read the CSV ({str(exc).splitlines()[0]})", file=path) from None
    missing = [c for c in ("vehicle_id", "test", "mpg") if c not in df.columns]
    if missing:
        raise InputError(f"missing column {', '.join(missing)}", file=path, column=missing[0],
                         hint="Columns: vehicle_id, test, mpg (and manufacturer)")
    known = set(known_ids)
    out = {}
    first_row: dict = {}
    for i, row in enumerate(df.itertuples(index=False), start=2):
        vid, test, raw = str(row.vehicle_id).strip(), str(row.test).strip(), str(row.mpg).strip()
        if test not in TESTS:
            raise InputError(f"unknown test '{test}'", file=path, row=i, column="test", value=test,
                             hint="Tests: " + ", ".join(TESTS))
        if vid not in known:
            raise InputError(f"vehicle_id '{vid}' is not in the fleet workbook", file=path, row=i,
                             column="vehicle_id", value=vid,
                             hint="Give the workbook the measured results were written for")
        try:
            mpg = float(raw)
        except ValueError:
            mpg = float("nan")
        if not np.isfinite(mpg) or mpg <= 0:
            raise InputError(f"mpg must be a positive number, got '{raw}'", file=path, row=i,
                             column="mpg", value=raw)
        plausible.check_mpg([mpg], file=path, column="mpg", rows=[i])
        maker = str(getattr(row, "manufacturer", "") or "").strip().lower()
        if (vid, test) in out and out[(vid, test)][:2] != (mpg, maker):
            raise InputError(f"{vid} {test} again, with mpg {raw} (row {first_row[(vid, test)]}: "
                             f"{out[(vid, test)][0]:g}); which one is measured is ambiguous", file=path, row=i,
                             column="mpg", value=raw, hint="Keep one row per vehicle and test (or their mean)")
        first_row.setdefault((vid, test), i)
        out[(vid, test)] = (mpg, maker)
    if not out:
        raise InputError("no measured results", file=path)
    return out


def vehicle_properties(vehicles) -> dict[str, np.ndarray]:
    """The properties the unexplained residual is tested against, per vehicle."""
    def num(name):
        return np.array([np.nan if getattr(v, name, None) is None else float(getattr(v, name))
                         for v in vehicles])

    power = num("rated_power_kW")
    weight = num("test_weight_kg")
    return {"specific_power_W_per_kg": 1000.0 * power / weight,
            "engine_displacement_L": num("engine_displacement_L"),
            "drive": np.array([v.configuration for v in vehicles], dtype=object),
            "transmission": np.array([getattr(v, "gearbox_type", None) or v.transmission
                                      for v in vehicles], dtype=object),
            "test_weight_kg": weight, "cylinders": num("cylinders")}


# ----------------------------------------------------------------------------- simulation
def _udds_bag_cycles():
    """UDDS bag 1 (0-505 s) and bag 2 (505-1369 s) as plain cycles: driven with a warm engine."""

    u = load_cycle("UDDS")
    t, v = np.asarray(u.time_s, float), np.asarray(u.speed_mps, float)
    end = BAG_BOUNDARIES_S["UDDS"][0]
    parts = {}
    for name, sel in (("bag1", t <= end), ("bag2", t >= end)):
        parts[name] = DriveCycle(f"UDDS {name} (warm)", t[sel] - t[sel][0], v[sel], np.zeros(int(sel.sum())))
    return parts


def _amounts(fuel_g, fuel_gal, miles) -> FuelAmounts:
    return FuelAmounts(g=np.asarray(fuel_g, float), gal=np.asarray(fuel_gal, float), mi=np.asarray(miles, float))


def simulate_fleet(vehicles, *, ambient_temp_C=20.0) -> FleetSimulation:
    """Fuel [g, gal] and miles per vehicle and test with a warm engine and with the cold-start
    model, and the engine-on seconds per mile (:class:`FleetSimulation`). The FTP
    composite by EPA's bag weighting (its seconds per mile: a constant load weighs the same
    in both halves, (bag 1 + bag 2) / their miles)."""

    def run(cycle):
        return simulate(vehicles, cycle, mode="map3d", ambient_temp_C=ambient_temp_C)

    bags = _udds_bag_cycles()
    warm, full, seconds = {}, {}, {}
    for name, cycle in bags.items():
        r = run(cycle)
        warm[name] = _amounts(r.fuel_g, r.fuel_gal, r.miles)
        seconds[name] = float(cycle.time_s[-1] - cycle.time_s[0])
    warm["bag3"], seconds["bag3"] = warm["bag1"], seconds["bag1"]
    ftp = run("FTP")
    for name in ("bag1", "bag2", "bag3"):
        ph = ftp.phases[name]
        full[name] = _amounts(ph.fuel_g, ph.fuel_gal, ph.miles)
    by_test = {"warm": {}, "full": {}}
    s_per_mi = {}
    for key, model in (("warm", warm), ("full", full)):
        bag = [model[b] for b in ("bag1", "bag2", "bag3")]
        miles = [b.mi for b in bag]
        for name in ("bag1", "bag2", "bag3"):
            by_test[key][f"FTP:{name}"] = model[name]
        by_test[key]["FTP"] = FuelAmounts(g=ftp_weighted_per_mile(*[b.g for b in bag], *miles) * sum(miles),
                                          gal=ftp_weighted_per_mile(*[b.gal for b in bag], *miles) * sum(miles),
                                          mi=sum(miles))
    for name in ("bag1", "bag2", "bag3"):
        s_per_mi[f"FTP:{name}"] = seconds[name] / warm[name].mi
    s_per_mi["FTP"] = (seconds["bag1"] + seconds["bag2"]) / (warm["bag1"].mi + warm["bag2"].mi)
    for test in ("HWFET", "US06"):
        cyc = load_cycle(test)
        r = run(cyc)
        by_test["warm"][test] = by_test["full"][test] = _amounts(r.fuel_g, r.fuel_gal, r.miles)
        s_per_mi[test] = float(cyc.time_s[-1] - cyc.time_s[0]) / np.asarray(r.miles, float)
    return FleetSimulation(warm=by_test["warm"], full=by_test["full"], s_per_mi=s_per_mi)


# ----------------------------------------------------------------------------- candidates
#: Fraction of each test's time spent cruising (|a| < 0.15 m/s^2 above 8 m/s): where a
#: cylinder-deactivation engine runs on half its cylinders. Computed from the schedules.
def cruise_share(test: str) -> float:
    name = "UDDS" if test.startswith("FTP") else test
    c = load_cycle(name)
    t, v = np.asarray(c.time_s, float), np.asarray(c.speed_mps, float)
    if test in ("FTP:bag1", "FTP:bag3"):
        keep = t <= ftp_bag1_end_s()
    elif test == "FTP:bag2":
        keep = t >= ftp_bag1_end_s()
    else:
        keep = np.ones(len(t), bool)
    a = np.gradient(v, t)
    return float(np.mean(((np.abs(a) < 0.15) & (v > 8.0))[keep]))


def _bag1_share_column(warm, rows_v, rows_t) -> np.ndarray:
    """Relative extra fuel per unit extra share of bag 1's fuel: 1 in bag 1; in the FTP
    composite its 0.43-weighted part (40 CFR 86.144: 0.43 (Y1 + Y2) / (D1 + D2) + ...)."""
    g = {b: warm[f"FTP:{b}"].g for b in ("bag1", "bag2", "bag3")}
    mi = {b: warm[f"FTP:{b}"].mi for b in ("bag1", "bag2", "bag3")}
    composite = warm["FTP"].g / warm["FTP"].mi
    in_ftp = FTP_TRANSIENT_WEIGHT * g["bag1"] / (mi["bag1"] + mi["bag2"]) / composite
    return np.array([1.0 if t == "FTP:bag1" else (in_ftp[v] if t == "FTP" else 0.0)
                     for v, t in zip(rows_v, rows_t)])


def candidate_columns(sim: FleetSimulation, rows_v, rows_t,
                      vehicles) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Each candidate's effect on ``r`` per unit of its global parameter, per row (effect id ->
    column), and the candidates that cannot be tested (effect id -> reason)."""

    def gpm(model, v, t):
        return model[t].g[v] / model[t].mi[v]

    warm = np.array([gpm(sim.warm, v, t) for v, t in zip(rows_v, rows_t)])
    full = np.array([gpm(sim.full, v, t) for v, t in zip(rows_v, rows_t)])
    cols, untestable = {}, {}
    cols["warmup"] = _bag1_share_column(sim.warm, rows_v, rows_t)
    cols["warmup_thermal"] = full / warm - 1.0
    simulated = sorted(set(rows_v))
    eta = dict(zip(simulated, willans_slope([vehicles[v] for v in simulated])))
    gpj = np.array([marginal_fuel_g_per_J(vehicles[v].fuel, eta[v]) for v in rows_v])
    s_per_mi = np.array([sim.s_per_mi[t][v] for v, t in zip(rows_v, rows_t)])
    cols["accessory_load"] = 1000.0 * gpj * s_per_mi / warm
    cyl = np.array([getattr(vehicles[v], "cylinders", None) or np.nan for v in rows_v], float)
    if np.isfinite(cyl).mean() > 0.5:
        share = {t: cruise_share(t) for t in set(rows_t)}
        cols["cylinder_deactivation"] = -np.where(cyl >= 6, 1.0, 0.0) * np.array([share[t] for t in rows_t])
    else:
        untestable["cylinder_deactivation"] = "no cylinders column for most vehicles"
    return cols, untestable


#: Global parameter of each candidate: name, bounds, unit, meaning.
PARAMETERS = {
    "warmup": ("bag1_extra_share", 0.0, 1.0, "-", "extra fuel of a cold start as a share of the "
               "warm engine's fuel over FTP bag 1 (0-505 s after the start)"),
    "warmup_thermal": ("scale", 0.0, 5.0, "-", "the cold-start fuel of the simulation's thermal "
                       "model (fleetrun/simulation/thermal.py, models/thermal.toml) times this"),
    "accessory_load": ("power_kW", 0.0, 10.0, "kW", "constant accessory power while the engine runs"),
    "cylinder_deactivation": ("cruise_saving_share", 0.0, 0.5, "-",
                              "share of the fuel saved while cruising, engines of 6+ cylinders"),
}


# ----------------------------------------------------------------------------- fitting
def manufacturer_folds(manufacturer: np.ndarray, k: int) -> np.ndarray:
    """Fold of each row: whole manufacturers dealt, largest first, to the fold with the
    fewest rows so far (every manufacturer is held out once, with all its vehicles)."""
    names, counts = np.unique(manufacturer, return_counts=True)
    load = np.zeros(k)
    fold_of = {}
    for i in np.argsort(-counts, kind="stable"):
        f = int(np.argmin(load))
        fold_of[names[i]] = f
        load[f] += counts[i]
    return np.array([fold_of[m] for m in manufacturer])


def _fit(r, X, lo, hi, hot):
    """The fuel scale (column 0) from the hot-engine rows ``hot``, then the effects (bounded
    least squares) on what is left over all rows."""
    a = float(np.mean(r[hot])) if hot.any() else float(np.mean(r))
    if X.shape[1] == 1:
        return np.array([a])
    Xe, y = X[:, 1:], r - a
    return np.r_[a, _solve_bounded(Xe.T @ Xe, Xe.T @ y, lo[1:], hi[1:])]


def heldout_prediction(r, X, lo, hi, folds, hot) -> np.ndarray:
    """Each row predicted from a fit on the other manufacturers' rows."""
    pred = np.zeros(len(r))
    for f in np.unique(folds):
        test = folds == f
        b = _fit(r[~test], X[~test], lo, hi, hot[~test])
        pred[test] = X[test] @ b
    return pred


def relative_error(r, fitted) -> np.ndarray:
    """Predicted mpg / measured - 1 for a model that predicts ``fitted`` of ``r``."""
    return np.exp(r - fitted) - 1.0


def _mae(err, tests, test=None) -> float:
    sel = np.ones(len(err), bool) if test is None else tests == test
    return float(np.mean(np.abs(err[sel]))) if sel.any() else float("nan")


@dataclass
class _Model:
    effects: list                         # candidate ids in the model
    X: np.ndarray                         # (rows, 1 + len(effects)): scale, then effects
    lo: np.ndarray
    hi: np.ndarray


#: Tests without a cold start: the fleet's hot-engine reference, where the fuel scale is
#: calibrated (as ``--calibrate-on`` a hot start for one recording).
HOT_TESTS = ("FTP:bag2", "FTP:bag3", "HWFET", "US06")


def _model(prob: FleetProblem, effects) -> _Model:
    cols = [np.ones(len(prob.residual))] + [prob.candidates[e] for e in effects]
    lo = np.array([-np.inf] + [PARAMETERS[e][1] for e in effects])
    hi = np.array([np.inf] + [PARAMETERS[e][2] for e in effects])
    return _Model(list(effects), np.column_stack(cols), lo, hi)


def _heldout_errors(prob, model, folds) -> np.ndarray:
    pred = heldout_prediction(prob.residual, model.X, model.lo, model.hi, folds,
                              np.isin(prob.test, HOT_TESTS))
    return np.abs(relative_error(prob.residual, pred))


def manufacturer_t(prob, before: np.ndarray, after: np.ndarray) -> float:
    """t statistic of the held-out absolute errors' improvement across manufacturers (each
    manufacturer one paired observation: its mean before minus its mean after)."""
    makers = np.unique(prob.manufacturer)
    d = np.array([before[prob.manufacturer == m].mean() - after[prob.manufacturer == m].mean()
                  for m in makers])
    sd = float(np.std(d, ddof=1)) if len(d) > 2 else 0.0
    if sd == 0.0:
        return float("inf") if d.mean() > 0 else 0.0
    return float(d.mean() / (sd / np.sqrt(len(d))))


def select_effects(prob: FleetProblem, settings: FleetSettings) -> tuple[list, list]:
    """Forward selection by held-out (by manufacturer) MAE: the best candidate is accepted if
    it lowers the MAE by more than ``min_gain`` and its improvement holds across
    manufacturers (paired one-sided t beyond the ``quantile`` of Student's t). Accepted ids
    and candidate statuses."""
    from scipy.stats import t as student_t  # scipy: slow to import, only this routine needs it

    folds = manufacturer_folds(prob.manufacturer, settings.folds)
    makers = len(np.unique(prob.manufacturer))
    t_crit = float(student_t.ppf(settings.quantile, max(makers - 1, 1)))
    statuses = {c: {"effect": c, "status": "rejected"} for c in prob.candidates}
    statuses.update({c: {"effect": c, "status": "untestable", "reason": why} for c, why in prob.untestable.items()})
    accepted = []
    for _ in range(settings.max_effects):
        rest = [c for c in prob.candidates if c not in accepted]
        if not rest:
            break
        before = _heldout_errors(prob, _model(prob, accepted), folds)
        after = {c: _heldout_errors(prob, _model(prob, accepted + [c]), folds) for c in rest}
        for c in rest:
            statuses[c]["heldout_gain"] = round(float(1 - after[c].mean() / before.mean()), 5)
            statuses[c]["manufacturer_t"] = round(manufacturer_t(prob, before, after[c]), 3)
            if not accepted:       # on its own, over the baseline: the story of each candidate
                m = _model(prob, [c])
                coef = _fit(prob.residual, m.X, m.lo, m.hi, np.isin(prob.test, HOT_TESTS))[-1]
                statuses[c]["parameters_alone"] = {PARAMETERS[c][0]: round(float(coef), 6)}
                statuses[c]["heldout_gain_vs_baseline"] = statuses[c]["heldout_gain"]
        best = max(rest, key=lambda c: statuses[c]["heldout_gain"])
        if statuses[best]["heldout_gain"] <= settings.min_gain or statuses[best]["manufacturer_t"] <= t_crit:
            break
        accepted.append(best)
        statuses[best]["status"] = "accepted"
    for c in statuses.values():
        c.setdefault("t_threshold", round(t_crit, 3))
    return accepted, [statuses[c] for c in list(prob.candidates) + list(prob.untestable)]


def test_table(prob: FleetProblem, r, fitted_heldout, fitted_all) -> dict[str, PerTestError]:
    """Per test: rows, mean error (all data fitted) and held-out MAE."""
    out = {}
    for t in TESTS:
        sel = prob.test == t
        if not sel.any():
            continue
        out[t] = PerTestError(n=int(sel.sum()),
                            mean_error=round(float(np.mean(relative_error(r[sel], fitted_all[sel]))), 5),
                            heldout_mae=round(_mae(relative_error(r, fitted_heldout), prob.test, t), 5))
    return out


def _tests_json(table: dict[str, PerTestError]) -> JsonDocument:
    return {t: row.as_json() for t, row in table.items()}


# ----------------------------------------------------------------------------- unexplained
def _property_bins(values: np.ndarray, n_bins: int = 6) -> tuple[np.ndarray, list]:
    """Bin index per vehicle and bin labels: quantile bins of a number, categories of a text
    (fewer than 10 vehicles: "other"); unknown values get their own bin."""
    if values.dtype == object:
        text = np.array(["unknown" if v is None else str(v) for v in values], dtype=object)
        names, counts = np.unique(text, return_counts=True)
        keep = set(names[counts >= 10])
        text = np.array([v if v in keep else "other" for v in text], dtype=object)
        labels = sorted(set(text))
        return np.array([labels.index(v) for v in text]), labels
    ok = np.isfinite(values)
    if ok.sum() < 2 * n_bins:
        return np.zeros(len(values), int), ["all"]
    edges = np.unique(np.quantile(values[ok], np.linspace(0, 1, n_bins + 1)[1:-1]))
    idx = np.where(ok, np.searchsorted(edges, np.where(ok, values, 0.0), side="right"), len(edges) + 1)
    bounds = np.r_[np.nanmin(values), edges, np.nanmax(values)]
    labels = [f"{bounds[i]:.3g}-{bounds[i + 1]:.3g}" for i in range(len(edges) + 1)] + ["unknown"]
    return idx, labels


def _eta2(e: np.ndarray, idx: np.ndarray) -> float:
    nb = int(idx.max()) + 1
    cnt = np.bincount(idx, minlength=nb)
    s = np.bincount(idx, weights=e, minlength=nb)
    ok = cnt > 0
    total = float(np.sum((e - e.mean()) ** 2))
    between = float(np.sum(cnt[ok] * (s[ok] / cnt[ok] - e.mean()) ** 2))
    return between / total if total > 0 else 0.0


def unexplained(prob: FleetProblem, err: np.ndarray, settings: FleetSettings) -> FleetUnexplained:
    """What the held-out errors ``err`` (per row) still show: tests whose mean error stands
    out (manufacturer-clustered t > 3 and more than 2 %), vehicle properties whose bins
    explain the per-vehicle mean error beyond shuffled errors."""
    rng = np.random.default_rng(settings.seed + 1)
    tests = []
    for t in TESTS:
        sel = prob.test == t
        if sel.sum() < 10:
            continue
        means = np.array([err[sel & (prob.manufacturer == m)].mean()
                          for m in np.unique(prob.manufacturer[sel])])
        mean = float(err[sel].mean())
        se = float(np.std(means, ddof=1) / np.sqrt(len(means))) if len(means) > 2 else np.inf
        if abs(mean) > 0.02 and abs(mean) > 3 * se:
            tests.append(OutlyingTest(test=t, mean_error=round(mean, 5), clustered_se=round(se, 5)))
    vehicles = np.unique(prob.vehicle)
    e_v = np.array([err[prob.vehicle == v].mean() for v in vehicles])
    bins = {name: _property_bins(prob.properties[name][vehicles]) for name in PROPERTIES
            if name in prob.properties}
    null = np.max([[_eta2(rng.permutation(e_v), idx) for idx, _ in bins.values()]
                   for _ in range(settings.n_perm)], axis=1)
    thr = float(np.quantile(null, settings.quantile))
    drivers = []
    for name, (idx, labels) in bins.items():
        st = _eta2(e_v, idx)
        profile = tuple((labels[i], int((idx == i).sum()), round(float(e_v[idx == i].mean()), 5))
                        for i in range(len(labels)) if (idx == i).any())
        drivers.append(PropertyLink(property=name, strength=round(st, 4), significant=bool(st > thr),
                                    null_threshold=round(thr, 4), profile=profile))
    drivers.sort(key=lambda d: -d.strength)
    return FleetUnexplained(significant=bool(tests) or any(d.significant for d in drivers),
                            test_details=tuple(tests), drivers=tuple(drivers))


# ----------------------------------------------------------------------------- the diagnosis
def build_fleet_problem(fleet_path, measured_path, *, ambient_temp_C=20.0) -> FleetProblem:
    """Read the workbook and the measured results, simulate, and set up the residuals."""
    fleet = read_fleet(fleet_path)
    vehicles = fleet.vehicles
    ids = [v.vehicle_id for v in vehicles]
    index = {vid: i for i, vid in enumerate(ids)}
    measured = read_measured(measured_path, ids)
    used = sorted({index[vid] for vid, _ in measured})
    sub = [vehicles[i] for i in used]
    pos = {i: k for k, i in enumerate(used)}
    rows = sorted(measured, key=lambda key: (index[key[0]], TESTS.index(key[1])))
    rows_v = np.array([pos[index[vid]] for vid, _ in rows])
    rows_t = np.array([t for _, t in rows], dtype=object)
    mpg = np.array([measured[key][0] for key in rows])
    makers = np.array([measured[key][1] or str(getattr(sub[v], "manufacturer", "") or "").lower()
                       for key, v in zip(rows, rows_v)], dtype=object)
    if np.any(makers == ""):
        vid = rows[int(np.flatnonzero(makers == "")[0])][0]
        raise InputError(f"no manufacturer for vehicle '{vid}'", file=measured_path, column="manufacturer",
                         hint="Give a manufacturer column (errors are held out by manufacturer)")
    if len(set(makers)) < 2:
        raise InputError(f"every measured result is of one manufacturer ({makers[0]}); diagnose-fleet "
                         "judges each effect on manufacturers it was not fitted to, so it needs two or more",
                         file=measured_path, column="manufacturer",
                         hint="Add the results of other manufacturers (import-epa without --make)")
    sim = simulate_fleet(sub, ambient_temp_C=ambient_temp_C)

    def residual(model):
        # measured fuel per mile over simulated = simulated mpg / measured mpg
        sim_mpg = np.array([model[t].mi[v] / model[t].gal[v] for v, t in zip(rows_v, rows_t)])
        return np.log(sim_mpg / mpg)

    plausible.check_mpg_scale(np.exp(-residual(sim.warm)), file=measured_path, column="mpg")
    cols, untestable = candidate_columns(sim, rows_v, rows_t, sub)
    return FleetProblem([v.vehicle_id for v in sub], rows_v, rows_t, makers, residual(sim.warm),
                        residual(sim.full), cols, untestable, vehicle_properties(sub))


def _finding(prob, effect, coef, before: dict[str, PerTestError], after: dict[str, PerTestError],
             settings) -> JsonDocument:
    """One accepted effect for the JSON: parameters, the tests it is in, errors, words."""
    name, _, _, unit, meaning = PARAMETERS[effect]
    col = prob.candidates[effect]
    added = {t: float(coef * np.mean(col[prob.test == t])) for t in TESTS if (prob.test == t).any()}
    tests = [t for t, a in added.items() if abs(a) > settings.test_share]
    by_test = {t: {"heldout_mae_before": round(before[t].heldout_mae, 5),
                   "heldout_mae_after": round(after[t].heldout_mae, 5),
                   "fuel_added": round(added[t], 5)} for t in added}
    where = ", ".join(f"{t} {100 * added[t]:+.1f} %" for t in tests) or "no test by more than 1 %"
    absent = ", ".join(t for t in ("FTP:bag3", "HWFET", "US06") if t in added and t not in tests)
    size = f"{coef:.3g}" + ("" if unit == "-" else f" {unit}")
    text = (f"{effect} with {name} = {size} ({meaning}) for the whole fleet: it adds "
            f"fuel where the measured results ask for it ({where})"
            + (f", and not in {absent}" if absent else "") + ". ")
    if "FTP" in before and "FTP" in after:
        text += (f"The FTP composite's held-out error (by manufacturer) goes from "
                 f"{100 * before['FTP'].heldout_mae:.2f} % to {100 * after['FTP'].heldout_mae:.2f} %.")
    return {"effect": effect, "parameters": {name: round(float(coef), 6)}, "tests": tests,
            "by_test": by_test, "explanation": text}


def analyse_fleet(prob: FleetProblem, settings: FleetSettings | None = None) -> JsonDocument:
    """The fleet diagnosis as the JSON of docs/interface.md (``fleetrun.fleet-diagnosis/1``)."""
    st = settings or FleetSettings()
    folds = manufacturer_folds(prob.manufacturer, st.folds)
    r = prob.residual

    hot = np.isin(prob.test, HOT_TESTS)

    def tables(effects, res=r):
        m = _model(prob, effects)
        held = heldout_prediction(res, m.X, m.lo, m.hi, folds, hot)
        coef = _fit(res, m.X, m.lo, m.hi, hot)
        return test_table(prob, res, held, m.X @ coef), held, coef

    base_tests, base_held, base_coef = tables([])
    accepted, candidates = select_effects(prob, st)
    findings, before = [], base_tests
    for k, effect in enumerate(accepted):
        after, held, coef = tables(accepted[:k + 1])
        f = _finding(prob, effect, coef[k + 1], before, after, st)
        f["heldout_mae_before"] = round(float(np.mean(np.abs(relative_error(r, tables(accepted[:k])[1])))), 5)
        f["heldout_mae_after"] = round(float(np.mean(np.abs(relative_error(r, held)))), 5)
        findings.append(f)
        before = after
    final_tests, final_held, final_coef = tables(accepted)
    full_tests, full_held, full_coef = tables([], prob.residual_full)
    return {"schema": SCHEMA, "vehicles": int(len(prob.vehicle_ids)),
            "manufacturers": int(len(np.unique(prob.manufacturer))), "rows": int(len(r)),
            "baseline": {"model": "fleetrun simulation with a warm engine on every test (cold-start "
                                  "model off), one global fuel scale calibrated on the hot-engine "
                                  "tests (" + ", ".join(HOT_TESTS) + ")",
                         "fuel_scale": round(float(np.exp(base_coef[0])), 5), "tests": _tests_json(base_tests)},
            "findings": findings, "candidates": candidates,
            "after": {"fuel_scale": round(float(np.exp(final_coef[0])), 5), "tests": _tests_json(final_tests)},
            "unexplained": unexplained(prob, relative_error(r, final_held), st).as_json(),
            "full_model": {"model": "fleetrun simulation with its cold-start model (FTP), one "
                                    "global fuel scale calibrated on the hot-engine tests",
                           "fuel_scale": round(float(np.exp(full_coef[0])), 5), "tests": _tests_json(full_tests),
                           "unexplained": unexplained(prob, relative_error(prob.residual_full, full_held),
                                                      st).as_json()},
            "method": {"folds": st.folds, "held_out": "manufacturer", "n_perm": st.n_perm,
                       "hot_tests": list(HOT_TESTS),
                       "quantile": st.quantile, "min_gain": st.min_gain},
            "notes": prob.notes}


def diagnose_fleet(fleet_path, measured_path, out=None, *, settings: FleetSettings | None = None,
                   write=True) -> JsonDocument:
    """Diagnose a fleet's measured results; writes ``out/diagnosis.json`` and ``.html``; the
    document written."""

    t0 = time.perf_counter()
    prob = build_fleet_problem(fleet_path, measured_path)
    result = analyse_fleet(prob, settings)
    result["version"] = __version__
    result["timing_s"] = round(time.perf_counter() - t0, 3)
    if write:
        out = Path(out) if out else Path(f"diagnosis-{Path(fleet_path).stem}")
        html = render_fleet_html(prob, result)
        prepare_output_folder(out, out)
        write_text_atomic(out / "diagnosis.json", json.dumps(result, indent=2))
        write_text_atomic(out / "diagnosis.html", html)
    return result
