"""``fleetrun diagnose``: find the physics a recording shows and the model leaves out.

>>> result = diagnose("run7.csv", out="diagnosis-run7")     # doctest: +SKIP
>>> [f["effect"] for f in result["findings"]]                 # doctest: +SKIP

Steps (docs/diagnose.md): load and check the recording (:mod:`.recording`); drive the
configured model with the recording's own inputs (:mod:`.differential`, :mod:`.vehicle`);
locate the residual in time and against operating channels (:mod:`.locate`); fit each
candidate effect and keep only what beats noise on held-out data (:mod:`.engine`,
:mod:`.select`); write diagnosis.json and diagnosis.html (:mod:`.report`).
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fleetrun import __version__
from fleetrun.diagnose import differential as differential_level
from fleetrun.diagnose import vehicle as vehicle_level
from fleetrun.diagnose.engine import Problem, Settings, fitted_on, select
from fleetrun.diagnose.integrals import integrals, phases
from fleetrun.diagnose.locate import drivers as find_drivers
from fleetrun.diagnose.locate import segments as find_segments
from fleetrun.diagnose.recording import load_recording
from fleetrun.diagnose.records import Integral
from fleetrun.diagnose.report import render_html
from fleetrun.errors import InputError
from fleetrun.fileio import JsonDocument, prepare_output_folder, write_text_atomic

SCHEMA = "fleetrun.diagnosis/1"


def build(recording, meta=None, calibrate_on=None, physics="thesis", residual="auto") -> Problem:
    rec = load_recording(recording, meta)
    if rec.level == "differential":
        build_problem = differential_level.build_problem
        if calibrate_on:
            # the differential baseline has no free constants; the reference is still checked
            ref = load_recording(calibrate_on)
            if ref.level != "differential":
                raise InputError("--calibrate-on must be a recording of the same level",
                                 file=calibrate_on)
        prob = build_problem(rec, physics)
        if calibrate_on:
            prob.notes.append("--calibrate-on: the differential-level baseline has no free "
                              "constants to calibrate; the reference was read and not used")
    else:
        build_problem = vehicle_level.build_problem
        ref = load_recording(calibrate_on) if calibrate_on else None
        if ref is not None and ref.level != "vehicle":
            raise InputError("--calibrate-on must be a vehicle-level recording", file=calibrate_on)
        prob = build_problem(rec, ref, physics, residual)
    prob.baseline_info.setdefault("recording", str(rec.path))
    prob.recording = rec
    return prob


def analyse(problem: Problem, settings: Settings | None = None) -> tuple[JsonDocument, np.ndarray]:
    """Locate and select; diagnosis.json's document (docs/interface.md), built from the typed
    records of the steps (:mod:`.records`), and the fitted effects (target units)."""
    s = settings or Settings()
    t0 = time.perf_counter()
    r = problem.residual
    sel = select(problem.coarse or problem, s)
    fitted = sel.fitted_effects
    base_heldout = sel.baseline_heldout_rmse
    if problem.coarse is not None:
        fitted = fitted_on(problem, sel)
    rate = len(r) / max(problem.time_s[-1] - problem.time_s[0], 1e-9)
    drv, drv_sig = find_drivers(problem.driver_channels, r, rng=np.random.default_rng(s.seed + 1),
                                smooth_window=max(1, int(rate)),
                                null_residual=r - fitted if sel.findings else None)
    significant = bool(sel.significant or drv_sig)
    segs = find_segments(problem.time_s, r, noise=(r - fitted) if sel.findings else None) \
        if significant else []
    rmse = float(np.sqrt(np.mean(r ** 2)))
    info = problem.baseline_info
    baseline = {"rmse": round(rmse, 6), "bias": round(float(np.mean(r)), 6),
                "heldout_rmse": round(float(base_heldout if base_heldout is not None else rmse), 6)}
    baseline.update(info)
    after = r - fitted
    rec = problem.recording
    ig = problem.integral
    phase_list = phases(problem.time_s, ig.moving, ig.speed_mps)
    integral_list = integrals(problem.time_s, ig.weight, problem.measured, problem.baseline,
                              problem.baseline + fitted, phase_list, segs)
    chosen = sel.as_json()
    chosen["unexplained"]["integral_share"] = integral_share(integral_list)

    result = {
        "schema": SCHEMA,
        "target": problem.target,
        "level": problem.level,
        "units": problem.units,
        "recording_name": rec.path.name if rec is not None else "",
        "samples": int(len(r)),
        "dt_s": float(rec.dt_s) if rec is not None else float(np.median(np.diff(problem.time_s))),
        "baseline": baseline,
        "mismatch": {"significant": significant, "segments": [x.as_json() for x in segs],
                     "drivers": [x.as_json() for x in drv]},
        "integrals": [x.as_json() for x in integral_list],
        "integral_unit": ig.unit,
        "findings": chosen["findings"],
        "candidates": chosen["candidates"],
        "ambiguities": chosen["ambiguities"],
        "descriptions": chosen["descriptions"],
        "unexplained": chosen["unexplained"],
        "after": {"rmse": round(float(np.sqrt(np.mean(after ** 2))), 6),
                  "bias": round(float(np.mean(after)), 6)},
        "method": {"folds": s.folds, "n_shifts": s.n_shifts, "quantile": s.quantile,
                   "min_gain": s.min_gain, "rounds": _clean(sel.rounds)},
        "notes": problem.notes,
        "version": __version__,
    }
    result["timing_s"] = round(time.perf_counter() - t0, 3)
    return result, fitted


def integral_share(integral_list: list[Integral]) -> float | None:
    """The phase-integral error the findings leave, as a share of the error before:
    ``sum |after - measured| / sum |before - measured|`` over the phases."""
    ph = [e for e in integral_list if e.kind == "phase"]
    before = sum(abs(e.before - e.measured) for e in ph)
    after = sum(abs(e.after - e.measured) for e in ph)
    return float(after / before) if before > 0 else None


def _clean(obj):
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        return None if not np.isfinite(obj) else float(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


@dataclass
class Diagnosis:
    """A diagnosis: the problem (recording, baseline, candidates), diagnosis.json's document
    (the report renders the document it is written beside: the two cannot disagree) and the
    fitted effects in target units (for figures)."""

    problem: Problem
    result: JsonDocument
    fitted: np.ndarray


def diagnosis(recording, meta=None, calibrate_on=None, *, physics="thesis",
              settings: Settings | None = None, residual="auto") -> Diagnosis:
    """Build and analyse; nothing is written."""
    t_start = time.perf_counter()
    problem = build(recording, meta, calibrate_on, physics, residual)
    result, fitted = analyse(problem, settings)
    result = _clean(result)
    result["timing_s"] = round(time.perf_counter() - t_start, 3)
    return Diagnosis(problem, result, fitted)


def write_outputs(d: Diagnosis, out) -> None:
    """``out/diagnosis.json`` and ``out/diagnosis.html``, rendered before anything is written."""
    out = Path(out)
    html = render_html(d.problem, d.result, d.fitted)
    text = json.dumps(d.result, indent=2)
    prepare_output_folder(out, out)
    write_text_atomic(out / "diagnosis.json", text)
    write_text_atomic(out / "diagnosis.html", html)


def diagnose(recording, meta=None, calibrate_on=None, out=None, *, physics="thesis",
             settings: Settings | None = None, write=True, residual="auto") -> JsonDocument:
    """Diagnose ``recording``; writes ``out/diagnosis.json`` and ``out/diagnosis.html``; the
    document written."""
    t_start = time.perf_counter()
    d = diagnosis(recording, meta, calibrate_on, physics=physics, settings=settings,
                  residual=residual)
    if write:
        write_outputs(d, out if out else Path(f"diagnosis-{Path(recording).stem}"))
    d.result["timing_s"] = round(time.perf_counter() - t_start, 3)
    return d.result
