"""Forward selection of missing physics with held-out error, a shift null and confounding checks.

The level modules (:mod:`fleetrun.diagnose.differential`, :mod:`fleetrun.diagnose.vehicle`)
turn a recording into a :class:`Problem`; :func:`select` decides what the model is missing.

Rules (docs/diagnose.md):
1. Every testable candidate is fitted (shape parameter profiled over its grid) and scored by
   its blocked-CV held-out gain ``1 - RMSE_after / RMSE_before``.
2. The best is accepted only if its gain beats both the ``quantile`` of the largest gain any
   candidate reaches on circularly shifted residuals and ``min_gain`` (a 1 % floor: smaller
   improvements do not change a forecast).
3. A rival that beats the null too, and once in the model leaves the best nothing to add
   beyond noise (conditional held-out SSE reduction below the same null threshold), makes
   both ``ambiguous``; so does an untestable
   candidate that could produce the same residual (its declared confounder, or its
   surrogate with assumed channels fitting as well). The separating test is reported.
4. Accepted effects join the model and the search repeats for a further effect.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fleetrun.diagnose.select import (Candidate, cv_fit, evaluate_candidate, fold_ids, full_fit,
                                      refine_shape, shift_null)
from fleetrun.effects import EFFECTS


@dataclass
class Problem:
    level: str
    target: str
    time_s: np.ndarray
    measured: np.ndarray
    baseline: np.ndarray
    candidates: list[Candidate]
    untestable: dict[str, list[str]]                 # id -> missing channels
    surrogates: dict[str, Candidate] = field(default_factory=dict)   # id -> candidate on assumed channels
    confound_possible: dict[str, bool] = field(default_factory=dict)  # untestable id -> could masquerade
    driver_channels: dict[str, np.ndarray] = field(default_factory=dict)
    baseline_info: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    extra_ambiguity: dict[str, str] = field(default_factory=dict)     # id -> reason (e.g. offset)
    units: str = ""

    @property
    def residual(self) -> np.ndarray:
        return self.measured - self.baseline


@dataclass
class Settings:
    folds: int = 5
    n_shifts: int = 200
    quantile: float = 0.99
    min_gain: float = 0.01
    max_effects: int = 3
    seed: int = 0


def _params(cand: Candidate, shape: dict, coef: float) -> dict:
    effect = EFFECTS[cand.id]
    out = {effect.linear: float(coef)}
    out.update({k: float(v) for k, v in shape.items()})
    return {p.name: round(out[p.name], 6) for p in effect.parameters if p.name in out}


def explanation(effect_id: str, params: dict, before: float, after: float, units: str) -> str:
    e = EFFECTS[effect_id]
    ps = ", ".join(f"{k} = {v:.3g}" for k, v in params.items())
    return (f"The residual follows the signature of {e.title} ({e.signature}); adding it with "
            f"{ps} cuts the held-out error from {before:.3g} to {after:.3g} {units}. "
            f"Physics: {e.seed}.")


def select(problem: Problem, settings: Settings | None = None) -> dict:
    """Run the selection; returns findings, candidate statuses, ambiguities and the model fit."""
    s = settings or Settings()
    rng = np.random.default_rng(s.seed)
    r = problem.residual
    n = len(r)
    k = s.folds
    folds = fold_ids(n, k)
    statuses: dict[str, dict] = {}
    for cid, missing in problem.untestable.items():
        statuses[cid] = {"effect": cid, "status": "untestable", "heldout_gain": None,
                         "missing_channels": missing}
    accepted: list[dict] = []      # {cand, shape, column}
    nuisance: list[tuple] = []          # terms in the model: (column, lower, upper)
    ambiguities: list[dict] = []
    rounds: list[dict] = []
    active = [c for c in problem.candidates]
    first_threshold = None
    significant = False
    for _round in range(s.max_effects):
        if not active:
            break
        evals = {c.id: evaluate_candidate(r, nuisance, c, folds, k) for c in active}
        best = max(active, key=lambda c: evals[c.id].gain)
        bev = evals[best.id]
        best_col = best.columns[bev.shape_index]
        # the noise estimate for the shift null: what is left after the effects already in
        # the model *and* the best candidate. Shifting the raw residual would keep the
        # effect's own structure (e.g. "constant while moving"), which the channels still
        # match after a shift, and inflate the null.
        cols = [t[0] for t in nuisance] + [best_col]
        coefs = full_fit(r, cols, [(t[1], t[2]) for t in nuisance] + [(best.lower, best.upper)])
        r_noise = r - np.array(cols).T @ coefs
        null = shift_null(r_noise, nuisance, active, folds, k, n_shifts=s.n_shifts, rng=rng)
        thr_dsse = null.dsse_threshold(s.quantile)
        dsse = n * (bev.rmse_before ** 2 - bev.rmse_after ** 2)
        thr = max(1 - np.sqrt(max(1 - thr_dsse / (n * bev.rmse_before ** 2), 0.0)), s.min_gain) \
            if bev.rmse_before > 0 else s.min_gain
        if first_threshold is None:
            first_threshold = thr
        rounds.append({"threshold_gain": thr, "threshold_dsse": thr_dsse, "dsse": dsse,
                       "gains": {c.id: evals[c.id].gain for c in active}})
        for c in active:
            statuses[c.id] = {"effect": c.id, "status": "rejected",
                              "heldout_gain": round(evals[c.id].gain, 5),
                              "parameters": _params(c, c.shapes[evals[c.id].shape_index],
                                                    evals[c.id].coefficient)}
        if not (dsse > thr_dsse and bev.gain > s.min_gain):
            # nothing testable explains the residual; say so if an untestable effect could
            for uid, sur in problem.surrogates.items():
                sev = evaluate_candidate(r, nuisance, sur, folds, k)
                if sev.gain > thr and n * (sev.rmse_before ** 2 - sev.rmse_after ** 2) > thr_dsse:
                    significant = True
                    ambiguities.append({
                        "effects": [uid],
                        "reasons": [f"{uid} cannot be tested (missing "
                                    f"{', '.join(problem.untestable[uid])}); with assumed values "
                                    f"it would cut the held-out error by {100 * sev.gain:.0f} %"],
                        "separating_test": EFFECTS[uid].separating_test})
                    statuses[uid]["could_explain"] = "mismatch"
            break
        significant = True
        # a rival is as good if, once the rival is in the model, the best adds no more
        # held-out SSE reduction than noise can (the same shift-null threshold)
        def as_good(cand, ev):
            col = cand.columns[ev.shape_index]
            before, after, _ = cv_fit(r, nuisance + [(col, cand.lower, cand.upper)], best_col, best.lower, best.upper, folds, k)
            return before - after <= thr_dsse

        rivals = []
        for c in active:
            if c is best:
                continue
            ev = evals[c.id]
            if ev.gain > thr and as_good(c, ev):
                rivals.append((c.id, f"fits about as well ({ev.gain:.3f} vs {bev.gain:.3f} held-out "
                                     f"gain): with it in the model, {best.id} adds nothing beyond noise"))
        for uid in problem.untestable:
            eff = EFFECTS[uid]
            if uid in problem.surrogates:
                sur = problem.surrogates[uid]
                sev = evaluate_candidate(r, nuisance, sur, folds, k)
                if sev.gain > thr and as_good(sur, sev):
                    rivals.append((uid, f"cannot be tested (missing {', '.join(problem.untestable[uid])}) "
                                        f"but with assumed values it fits as well ({sev.gain:.3f})"))
                else:
                    # the reverse: with the best in the model, does the untestable effect still
                    # explain more than noise? Then the best alone is not the whole story and
                    # the rest cannot be tested
                    b2, a2, _ = cv_fit(r, nuisance + [(best_col, best.lower, best.upper)], sur.columns[sev.shape_index],
                                       sur.lower, sur.upper, folds, k)
                    if b2 - a2 > thr_dsse:
                        rivals.append((uid, f"cannot be tested (missing "
                                            f"{', '.join(problem.untestable[uid])}) and with assumed "
                                            f"values explains what {best.id} leaves"))
            elif best.id in eff.confounded_with and problem.confound_possible.get(uid, False):
                rivals.append((uid, f"cannot be tested (missing {', '.join(problem.untestable[uid])}) "
                                    f"and produces a residual like {best.id}'s in such data"))
        if best.id in problem.extra_ambiguity:
            rivals.append(("sensor_offset", problem.extra_ambiguity[best.id]))
        shape = dict(best.shapes[bev.shape_index])
        col = best_col
        if best.column_for is not None and len(shape) == 1:
            name = next(iter(shape))
            v, col = refine_shape(r, nuisance, best, bev.shape_index, name)
            shape = {name: v}
        if rivals:
            tests = [EFFECTS[best.id].separating_test] + [
                EFFECTS[rid].separating_test for rid, _ in rivals if rid in EFFECTS]
            test = "; ".join(dict.fromkeys(t for t in tests if t))
            ambiguities.append({"effects": [best.id] + [rid for rid, _ in rivals],
                                "reasons": [why for _, why in rivals],
                                "separating_test": test})
            statuses[best.id]["status"] = "ambiguous"
            statuses[best.id]["separating_test"] = test
            for rid, why in rivals:
                if rid in statuses and statuses[rid]["status"] != "untestable":
                    statuses[rid]["status"] = "ambiguous"
                    statuses[rid]["separating_test"] = test
                elif rid in statuses:
                    statuses[rid]["could_explain"] = best.id
            drop = {best.id} | {rid for rid, _ in rivals}
            active_ids = {c.id for c in active}
            if any(rid not in active_ids and rid not in problem.surrogates for rid, _ in rivals):
                # an untestable effect may be what the residual shows: nothing fitted now can
                # be trusted to leave only noise behind, so the search stops here
                break
            # one of them explains the mismatch: put all of their columns in the model so that
            # a further, different effect can still be found
            for rid, _ in rivals:
                if rid in active_ids:
                    c = next(c for c in active if c.id == rid)
                    cols_r, lo_r, hi_r = c.columns[evals[rid].shape_index], c.lower, c.upper
                elif rid in problem.surrogates:
                    sur = problem.surrogates[rid]
                    cols_r = sur.columns[evaluate_candidate(r, nuisance, sur, folds, k).shape_index]
                    lo_r, hi_r = sur.lower, sur.upper
                else:
                    continue
                nuisance.append((cols_r, lo_r, hi_r))
            nuisance.append((col, best.lower, best.upper))
            active = [c for c in active if c.id not in drop]
            continue
        accepted.append({"cand": best, "shape": shape, "column": col,
                         "before": bev.rmse_before, "after": bev.rmse_after, "gain": bev.gain})
        statuses[best.id]["status"] = "accepted"
        nuisance.append((col, best.lower, best.upper))
        active = [c for c in active if c.id != best.id]
    # joint refit of every accepted effect on all data: the parameters reported
    findings = []
    fitted = np.zeros(n)
    if accepted:
        cols = [a["column"] for a in accepted]
        coefs = full_fit(r, cols, [(a["cand"].lower, a["cand"].upper) for a in accepted])
        for a, c in zip(accepted, coefs):
            params = _params(a["cand"], a["shape"], c)
            statuses[a["cand"].id]["parameters"] = params
            statuses[a["cand"].id]["heldout_gain"] = round(a["gain"], 5)
            findings.append({"effect": a["cand"].id, "parameters": params,
                             "heldout_rmse_before": round(a["before"], 6),
                             "heldout_rmse_after": round(a["after"], 6),
                             "explanation": explanation(a["cand"].id, params, a["before"],
                                                        a["after"], problem.units),
                             "seed": EFFECTS[a["cand"].id].seed})
            fitted = fitted + c * a["column"]
    order = [c.id for c in problem.candidates] + list(problem.untestable)
    candidates = [statuses[cid] for cid in order if cid in statuses]
    return {"findings": findings, "candidates": candidates, "ambiguities": ambiguities,
            "significant": significant or bool(ambiguities), "threshold": first_threshold,
            "rounds": rounds, "fitted_effects": fitted}
