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
   One global constant (a fuel-map scale) is always fitted.
3. **Candidates** (:func:`candidate_columns`), each with one global parameter for the whole
   fleet: ``warmup`` (a scale on the thermal model's cold-start fuel), ``accessory_load``
   (constant power while the engine runs), ``cylinder_deactivation`` (a share of the fuel
   saved while cruising, on engines of 6 or more cylinders).
4. **Selection** by held-out error, held out by manufacturer (:func:`manufacturer_folds`): a
   candidate is accepted only if it lowers the held-out mean absolute error by more than
   ``min_gain`` and by more than the same candidate does with its column shuffled across
   vehicles (the ``quantile`` of ``n_perm`` shuffles).
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

from fleetrun.diagnose.select import _solve_bounded
from fleetrun.errors import InputError

SCHEMA = "fleetrun.fleet-diagnosis/1"
#: Tests the measured-results CSV may hold (CONTRACT.md, diagnose-fleet).
TESTS = ("FTP:bag1", "FTP:bag2", "FTP:bag3", "FTP", "HWFET", "US06")
BAGS = ("FTP:bag1", "FTP:bag2", "FTP:bag3")
#: Vehicle properties the unexplained residual is tested against.
PROPERTIES = ("specific_power_W_per_kg", "engine_displacement_L", "drive", "transmission",
              "test_weight_kg", "cylinders")


@dataclass
class FleetSettings:
    folds: int = 5
    n_perm: int = 200
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
    candidates: dict                    # effect id -> column (rows,)
    untestable: dict                    # effect id -> reason
    properties: dict                    # property -> (vehicles,) values
    notes: list = field(default_factory=list)


# ----------------------------------------------------------------------------- inputs
def read_measured(path, known_ids) -> dict:
    """MEASURED.csv (CONTRACT.md): ``{(vehicle_id, test): (mpg, manufacturer or "")}``.

    Errors name the file, the row as a spreadsheet shows it, the column and the value.
    """
    import pandas as pd

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
        out[(vid, test)] = (mpg, str(getattr(row, "manufacturer", "") or "").strip().lower())
    if not out:
        raise InputError("no measured results", file=path)
    return out


def vehicle_properties(vehicles) -> dict:
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
    from fleetrun.cycles import DriveCycle, load_cycle
    from fleetrun.diagnose.integrals import BAG_BOUNDARIES_S

    u = load_cycle("UDDS")
    t, v = np.asarray(u.time_s, float), np.asarray(u.speed_mps, float)
    end = BAG_BOUNDARIES_S["UDDS"][0]
    parts = {}
    for name, sel in (("bag1", t <= end), ("bag2", t >= end)):
        parts[name] = DriveCycle(f"UDDS {name} (warm)", t[sel] - t[sel][0], v[sel], np.zeros(int(sel.sum())))
    return parts


def simulate_fleet(vehicles, *, ambient_temp_C=20.0) -> dict:
    """Fuel [g] and miles per vehicle and test, ``{"warm": {test: (g, mi)}, "full": {...}}``,
    and the engine-on seconds per mile ``"s_per_mi": {test: (V,)}``. The FTP composite by
    EPA's bag weighting (its seconds per mile: a constant load weighs the same in both
    halves, (bag 1 + bag 2) / their miles)."""
    from fleetrun.cycles import ftp_weighted_per_mile, load_cycle
    from fleetrun.simulation import simulate

    def run(cycle):
        return simulate(vehicles, cycle, mode="map3d", ambient_temp_C=ambient_temp_C)

    bags = _udds_bag_cycles()
    warm, full, seconds = {}, {}, {}
    for name, cycle in bags.items():
        r = run(cycle)
        warm[name] = (np.asarray(r.fuel_g, float), np.asarray(r.miles, float))
        seconds[name] = float(cycle.time_s[-1] - cycle.time_s[0])
    warm["bag3"], seconds["bag3"] = warm["bag1"], seconds["bag1"]
    ftp = run("FTP")
    for name in ("bag1", "bag2", "bag3"):
        full[name] = (np.asarray(ftp.phases[name]["fuel_g"], float), np.asarray(ftp.phases[name]["miles"], float))
    out = {"warm": {}, "full": {}, "s_per_mi": {}}
    for key, model in (("warm", warm), ("full", full)):
        for name in ("bag1", "bag2", "bag3"):
            out[key][f"FTP:{name}"] = model[name]
        g = [model[b][0] for b in ("bag1", "bag2", "bag3")]
        m = [model[b][1] for b in ("bag1", "bag2", "bag3")]
        out[key]["FTP"] = (ftp_weighted_per_mile(*g, *m) * sum(m), sum(m))
    for name in ("bag1", "bag2", "bag3"):
        out["s_per_mi"][f"FTP:{name}"] = seconds[name] / warm[name][1]
    out["s_per_mi"]["FTP"] = (seconds["bag1"] + seconds["bag2"]) / (warm["bag1"][1] + warm["bag2"][1])
    for test in ("HWFET", "US06"):
        cyc = load_cycle(test)
        r = run(cyc)
        out["warm"][test] = out["full"][test] = (np.asarray(r.fuel_g, float), np.asarray(r.miles, float))
        out["s_per_mi"][test] = float(cyc.time_s[-1] - cyc.time_s[0]) / np.asarray(r.miles, float)
    return out


# ----------------------------------------------------------------------------- candidates
#: Fraction of each test's time spent cruising (|a| < 0.15 m/s^2 above 8 m/s): where a
#: cylinder-deactivation engine runs on half its cylinders. Computed from the schedules.
def cruise_share(test: str) -> float:
    from fleetrun.cycles import load_cycle

    name = "UDDS" if test.startswith("FTP") else test
    c = load_cycle(name)
    t, v = np.asarray(c.time_s, float), np.asarray(c.speed_mps, float)
    if test in ("FTP:bag1", "FTP:bag3"):
        keep = t <= 505.0
    elif test == "FTP:bag2":
        keep = t >= 505.0
    else:
        keep = np.ones(len(t), bool)
    a = np.gradient(v, t)
    return float(np.mean(((np.abs(a) < 0.15) & (v > 8.0))[keep]))


def candidate_columns(sim, rows_v, rows_t, vehicles) -> tuple[dict, dict]:
    """Each candidate's effect on ``r`` per unit of its global parameter, per row."""
    from fleetrun.effects.vehicle import marginal_fuel_g_per_J

    def gpm(model, v, t):
        g, m = sim[model][t]
        return g[v] / m[v]

    warm = np.array([gpm("warm", v, t) for v, t in zip(rows_v, rows_t)])
    full = np.array([gpm("full", v, t) for v, t in zip(rows_v, rows_t)])
    cols, untestable = {}, {}
    cols["warmup"] = full / warm - 1.0
    gpj = np.array([marginal_fuel_g_per_J(vehicles[v].fuel) for v in rows_v])
    s_per_mi = np.array([sim["s_per_mi"][t][v] for v, t in zip(rows_v, rows_t)])
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
    "warmup": ("scale", 0.0, 5.0, "-", "the cold-start fuel of the thermal model "
               "(fleetrun/simulation/thermal.py, models/thermal.toml) times this"),
    "accessory_load": ("power_kW", 0.0, 10.0, "kW", "constant accessory power while the engine runs"),
    "cylinder_deactivation": ("cruise_saving_share", 0.0, 0.5, "-",
                              "share of the fuel saved while cruising, engines of 6+ cylinders"),
}
