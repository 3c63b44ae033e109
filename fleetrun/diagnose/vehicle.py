"""Vehicle-level diagnosis: the drive-cycle simulation driven by the measured speed trace.

Baseline: ``fleetrun.simulation.simulate`` runs the sidecar's vehicle (the keys of one
Vehicles row) over the recording's own speed trace (and grade, if recorded) and gives a fuel
rate per step. The simulation's engine map is generic, so the baseline has two free
calibration constants, ``fuel = a * simulated + b * engine_on`` (a: fuel-map scale, b: idle
offset). With ``--calibrate-on REF`` they are fitted on the reference recording (a hot start
of the same vehicle) and then held fixed; without it they are refitted inside every
cross-validation fold, and ``accessory_load`` (a constant while the engine runs) is then
untestable because the idle offset absorbs it.

Engine off: stretches of at least ``ENGINE_OFF_MIN_S`` at standstill with zero measured fuel
(a soak between tests, stop-start) are engine-off; the simulation idles there, so its fuel is
set to zero and no effect acts.
"""
from __future__ import annotations

import numpy as np

from fleetrun.cycles import DriveCycle
from fleetrun.diagnose.engine import IntegralSpec, Problem, windowed
from fleetrun.diagnose.integrals import MATCH_RMS_MPS, STILL_MPS, align, driving_stretches
from fleetrun.diagnose.recording import Recording
from fleetrun.diagnose.select import Candidate, full_fit
from fleetrun.effects import effects_for_level
from fleetrun.effects.vehicle import marginal_fuel_g_per_J
from fleetrun.errors import InputError
from fleetrun.simulation import simulate
from fleetrun.simulation.params import willans_slope
from fleetrun.workbook.vehicle_file import read_vehicle_toml

ENGINE_OFF_MIN_S = 5.0
#: Share of the engine-on samples a reference of the same trace must cover for the
#: difference between the recordings to be the residual (``--residual auto``).
SAME_TRACE_MIN_COVER = 0.5
#: Window [s] over which a same-trace residual is compared (:func:`engine.windowed`).
SAME_TRACE_WINDOW_S = 10.0
ZERO_FUEL_G_PER_S = 1e-3


def engine_on(time_s, speed_mps, fuel_g_per_s, dt_s) -> np.ndarray:
    """1 where the engine runs: not in a run of >= 5 s at standstill with zero fuel."""
    off = (speed_mps < 0.1) & (fuel_g_per_s < ZERO_FUEL_G_PER_S)
    out = np.ones(len(off))
    min_len = max(1, int(round(ENGINE_OFF_MIN_S / dt_s)))
    i = 0
    while i < len(off):
        if off[i]:
            j = i
            while j < len(off) and off[j]:
                j += 1
            if j - i >= min_len:
                out[i:j] = 0.0
            i = j
        else:
            i += 1
    return out


def _vehicle(rec: Recording):
    if rec.meta_path is None:
        raise InputError("a vehicle-level recording needs a sidecar with one Vehicles row", file=rec.path)
    return read_vehicle_toml(rec.meta_path)


def simulated(rec: Recording, physics="thesis"):
    """Simulated fuel rate [g/s] and the trace for ``rec``'s speed (and grade) trace."""

    df = rec.data
    spec = _vehicle(rec)
    grade = df["grade_pct"].to_numpy() if "grade_pct" in df else np.zeros(len(df))
    cycle = DriveCycle(rec.stem, df["time_s"].to_numpy(), df["vehicle_speed_mps"].to_numpy(), grade)
    ambient = float(np.median(df["ambient_temp_C"])) if "ambient_temp_C" in df else \
        float(20.0 if rec.meta.ambient_temp_C is None else rec.meta.ambient_temp_C)
    res = simulate([spec], cycle, mode="direct", ambient_temp_C=ambient, physics=physics, trace=True)
    tr = res.trace_frame(0)
    on = engine_on(df["time_s"].to_numpy(), df["vehicle_speed_mps"].to_numpy(),
                   df["fuel_rate_g_per_s"].to_numpy(), rec.dt_s)
    fuel = tr["fuel_rate_g_per_s"].to_numpy() * on
    return spec, tr, on, fuel


def calibrate(ref: Recording, physics="thesis") -> tuple[float, float, float, float, float]:
    """Fuel-map scale a and idle offset b fitted on a reference recording, its RMSE, and the
    standard errors of a and b.

    The reference's residual is autocorrelated, so the least-squares covariance is inflated by
    ``(1 + rho) / (1 - rho)`` (AR(1) with lag-1 correlation rho).
    """
    _, _, on, fuel = simulated(ref, physics)
    y = ref.data["fuel_rate_g_per_s"].to_numpy()
    a, b = full_fit(y, [fuel, on], [(0.2, 5.0), (-5.0, 5.0)])
    e = y - a * fuel - b * on
    rho = 0.0
    if e.size > 3 and np.std(e[:-1]) > 0 and np.std(e[1:]) > 0:
        rho = float(np.clip(np.corrcoef(e[:-1], e[1:])[0, 1], 0.0, 0.999))
    X = np.column_stack([fuel, on])
    cov = np.linalg.pinv(X.T @ X) * float(np.var(e)) * (1 + rho) / (1 - rho)
    se_a, se_b = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return float(a), float(b), float(np.sqrt(np.mean(e ** 2))), float(se_a), float(se_b)


def same_trace(rec: Recording, ref: Recording) -> tuple[np.ndarray, np.ndarray]:
    """The reference's measured fuel rate on ``rec``'s time grid where both recordings drive
    the same speed trace, and the mask of those samples.

    Each driving stretch of ``rec`` (between standstills longer than
    :data:`fleetrun.diagnose.integrals.GAP_S`) is aligned with each of ``ref``'s
    (:func:`fleetrun.diagnose.integrals.align`); a pair whose speeds agree within
    :data:`fleetrun.diagnose.integrals.MATCH_RMS_MPS` and whose overlap covers 80 % of the
    stretch is used.
    """
    t, v = rec.data["time_s"].to_numpy(), rec.data["vehicle_speed_mps"].to_numpy()
    rt, rv = ref.data["time_s"].to_numpy(), ref.data["vehicle_speed_mps"].to_numpy()
    ry = ref.data["fuel_rate_g_per_s"].to_numpy()
    ref_fuel, covered = np.zeros(len(t)), np.zeros(len(t), bool)
    ref_stretches, _ = driving_stretches(rt, rv > STILL_MPS)
    for a, b in driving_stretches(t, v > STILL_MPS)[0]:
        for c, d in ref_stretches:
            found = align(t[a:b], v[a:b], rt[c:d], rv[c:d])
            if found is None or found[1] > MATCH_RMS_MPS:
                continue
            tt = t[a:b] - found[0]
            inside = (tt >= 0) & (tt <= rt[d - 1] - rt[c])
            if inside.mean() < 0.8:
                continue
            idx = np.arange(a, b)[inside]
            ref_fuel[idx] = np.interp(tt[inside] + rt[c], rt, ry)
            covered[idx] = True
            break
    return ref_fuel, covered


def _calibrated_baseline(rec, ref, fuel, on, physics, residual, notes, info):
    """Baseline and calibration terms with a reference recording: the simulation calibrated
    on it, or (``residual`` same-trace/auto) the reference's own fuel where it drives the
    same trace (the simulation's transient errors cancel)."""
    a, b, ref_rmse, se_a, se_b = calibrate(ref, physics)
    baseline = a * fuel + b * on
    notes.append(f"calibrated on {ref.path.name}: fuel = {a:.4g} x simulated + {b:.4g} g/s "
                 f"while the engine runs (reference RMSE {ref_rmse:.3g} g/s)")
    info.update({"calibrated_on": str(ref.path), "fuel_scale": round(a, 6),
                 "fuel_scale_se": round(se_a, 6), "idle_offset_g_per_s": round(b, 6),
                 "idle_offset_se_g_per_s": round(se_b, 6), "reference_rmse": round(ref_rmse, 6)})
    keep = np.ones(len(fuel))
    if residual != "simulation":
        ref_fuel, covered = same_trace(rec, ref)
        cover = float(covered[on > 0].mean()) if (on > 0).any() else 0.0
        if cover >= SAME_TRACE_MIN_COVER:
            baseline = np.where(covered, ref_fuel, baseline)
            keep = (~covered).astype(float)
            info["residual"] = "same_trace"
            notes.append(f"residual: measured minus {ref.path.name} on the same speed trace "
                         f"({100 * cover:.0f} % of the engine-on samples aligned), so the "
                         "simulation's transient errors cancel; the calibrated simulation "
                         "elsewhere")
        elif residual == "same-trace":
            raise InputError(f"--residual same-trace: {ref.path.name} covers only "
                             f"{100 * cover:.0f} % of the recording's trace", file=ref.path,
                             hint="Give a reference recording of the same cycle, or use "
                                  "--residual simulation")
    info.setdefault("residual", "simulation")
    if info["residual"] == "simulation":
        notes.append("residual: measured minus the calibrated simulation")
    # the calibration is only known to its standard errors: the constants may move within
    # 3 of them on this recording, so that a calibration error is not claimed as an
    # accessory load (a constant) or a grade (fuel ~ speed)
    initial = [(fuel * keep, -3 * se_a, 3 * se_a), (on * keep, -3 * se_b, 3 * se_b)]
    return baseline, [term for term in initial if np.any(term[0] != 0)]


def build_problem(rec: Recording, ref: Recording | None, physics="thesis",
                  residual: str = "auto") -> Problem:
    df = rec.data
    t = df["time_s"].to_numpy()
    t0 = t - t[0]
    y = df["fuel_rate_g_per_s"].to_numpy()
    spec, tr, on, fuel = simulated(rec, physics)
    v = df["vehicle_speed_mps"].to_numpy()
    notes = list(rec.notes)
    info = {"model": f"fleetrun.simulation ({spec.vehicle_id}, {spec.configuration}, physics={physics}) "
                     "on the measured speed trace"}
    initial = []
    if ref is not None:
        baseline, initial = _calibrated_baseline(rec, ref, fuel, on, physics, residual, notes, info)
    else:
        a, b = full_fit(y, [fuel, on], [(0.2, 5.0), (-5.0, 5.0)])
        baseline = a * fuel + b * on
        # the constants are refitted in every fold, so held-out errors are honest
        initial = [(fuel, 0.2 - a, 5.0 - a), (on, -5.0 - b, 5.0 - b)]
        notes.append(f"no --calibrate-on: fuel = a x simulated + b fitted on this recording "
                     f"(a = {a:.4g}, b = {b:.4g} g/s) and refitted in every fold")
        info.update({"fuel_scale": round(float(a), 6), "idle_offset_g_per_s": round(float(b), 6)})
    gpj = marginal_fuel_g_per_J(spec.fuel, willans_slope([spec])[0])
    driving = (tr["wheel_power_W"].to_numpy() > 0).astype(float)
    ch = {"time_s": t0, "vehicle_speed_mps": v * driving, "engine_on": on,
          "vehicle_mass_kg": float(spec.test_weight_kg), "marginal_fuel_g_per_J": gpj}
    candidates, untestable = [], {}
    for effect in effects_for_level("vehicle"):
        if effect.id == "accessory_load" and ref is None:
            untestable[effect.id] = ["--calibrate-on reference (the idle offset absorbs a constant load)"]
            continue
        if effect.id == "road_grade" and "grade_pct" in df:
            notes.append("grade_pct recorded and simulated: road_grade tests a grade beyond it")
        shapes = effect.shape
        grid = [{shapes[0].name: g} for g in shapes[0].grid] if shapes else [{}]
        bounds = (shapes[0].lower, shapes[0].upper) if shapes else None
        if shapes and shapes[0].name == "tau_s":
            # a warm-up slower than half the recording is a constant (an accessory load)
            tau_max = max(0.5 * t0[-1], shapes[0].grid[0])
            grid = [g for g in grid if g["tau_s"] <= tau_max]
            bounds = (shapes[0].lower, min(shapes[0].upper, tau_max))
        lin = effect.parameter(effect.linear)
        cols = [effect.basis(ch, **sh) for sh in grid]
        candidates.append(Candidate(effect.id, cols, grid, lin.lower, lin.upper,
                                    column_for=(lambda sh, e=effect: e.basis(ch, **sh)) if shapes else None,
                                    shape_bounds=bounds))
    drivers = {"speed": v, "acceleration": np.gradient(v, rec.dt_s), "time_since_start": t0,
               "torque": tr["wheel_torque_Nm"].to_numpy()}
    if "grade_pct" in df:
        drivers["grade"] = df["grade_pct"].to_numpy()
    if "ambient_temp_C" in df:
        drivers["temperature"] = df["ambient_temp_C"].to_numpy()
    integral = IntegralSpec(moving=v > 0.1, speed_mps=v, weight=np.ones(len(t)), unit="g")
    problem = Problem("vehicle", "fuel_rate_g_per_s", t, y, baseline, candidates, untestable, {},
                      {}, drivers, info, notes, {}, units="g/s", initial_terms=initial,
                      integral=integral)
    if info.get("residual") == "same_trace":
        w = max(1, int(round(SAME_TRACE_WINDOW_S / rec.dt_s)))
        notes.append(f"same-trace residual compared over {SAME_TRACE_WINDOW_S:g}-s windows: two "
                     "drives place each transient a second or two apart, which a per-second "
                     "difference turns into noise and a window's fuel does not")
        problem.coarse = windowed(problem, w)
    return problem
