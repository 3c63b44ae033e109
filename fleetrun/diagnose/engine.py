"""Forward selection of missing physics with held-out error, a shift null and confounding checks.

The level modules (:mod:`fleetrun.diagnose.differential`, :mod:`fleetrun.diagnose.vehicle`)
turn a recording into a :class:`Problem`; :func:`select` decides what the model is missing.

Rules (docs/diagnose.md, section 5):
1. Every testable candidate is fitted (shape parameter profiled over its grid) and scored by
   its blocked-CV held-out gain ``1 - RMSE_after / RMSE_before``.
2. The best is accepted only if its held-out SSE reduction beats the ``quantile`` of the
   largest reduction any candidate reaches on circularly shifted residuals (the residual
   left after the model and the best candidate: a noise estimate), its gain exceeds
   ``min_gain`` (1 %: smaller improvements do not change a forecast), and, for effects that
   look like a sensor offset, its size exceeds the zeroing uncertainty.
3. An untestable candidate that could produce the same residual (its declared confounder, or
   its surrogate on assumed channels fitting as well or explaining what the best leaves)
   makes the best ``ambiguous`` and stops the search; the separating test is reported.
4. Accepted effects join the model (shapes re-refined jointly) and the search repeats.
5. After the search, each accepted effect is checked against every other testable candidate
   with the rest of the findings in the model: a rival that beats the null on its own and
   leaves the finding nothing beyond noise makes both ``ambiguous``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from fleetrun.diagnose.contrast import compare
from fleetrun.diagnose.openworld import drift_columns, review, unexplained
from fleetrun.diagnose.recording import Recording
from fleetrun.diagnose.records import Accepted, Finding, Selection, Unexplained
from fleetrun.diagnose.select import (Candidate, block_shape, chosen, cv_fit, effect_of, evaluate_candidate,
                                      fold_ids, full_fit, refine_shape, relaxed_block, shift_null)
from fleetrun.effects import EFFECTS
from fleetrun.fileio import JsonDocument


@dataclass(frozen=True)
class IntegralSpec:
    """What the integrals of diagnosis.json (:mod:`.integrals`) need: ``moving`` (bool per
    sample: turning with the engine on), ``weight`` (target -> rate of the integrated
    quantity, per sample), ``unit`` (of the integral) and ``speed_mps`` (vehicle speed, or
    None)."""
    moving: np.ndarray
    weight: np.ndarray
    unit: str
    speed_mps: np.ndarray | None = None


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
    #: the ``baseline`` part of diagnosis.json this level adds (model, offsets, ...: docs/diagnose.md)
    baseline_info: JsonDocument = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    extra_ambiguity: dict[str, str] = field(default_factory=dict)     # id -> reason (e.g. offset)
    units: str = ""
    #: terms always in the model and refitted in every fold (free calibration constants),
    #: ``[(column, lower, upper), ...]``
    initial_terms: list = field(default_factory=list)
    #: effect id -> smallest size (target units, mean over the samples it acts on) that can be
    #: told from a sensor-zeroing error; smaller fits are rejected
    offset_floor: dict[str, float] = field(default_factory=dict)
    #: what the integrals (:mod:`.integrals`) need
    integral: IntegralSpec | None = None
    #: the recording the problem was built from (None: built in memory, e.g. a test)
    recording: Recording | None = None
    #: the same problem on a coarser grid (:func:`windowed`) where the selection runs, or None
    coarse: "Problem | None" = None

    @property
    def residual(self) -> np.ndarray:
        return self.measured - self.baseline


def _window_mean(x, w: int):
    """Means over consecutive windows of ``w`` samples (the last one may be shorter)."""
    x = np.asarray(x, dtype=float)
    if x.ndim == 0:
        return x
    idx = np.arange(len(x)) // w
    return np.bincount(idx, weights=x) / np.bincount(idx)


def windowed(problem: Problem, w: int) -> Problem:
    """``problem`` on means over windows of ``w`` samples: target, baseline, every column and
    channel (an integral over each window, divided by its length).

    For residuals whose per-sample noise is timing: two drives of the same trace place each
    transient a second or two apart, which a per-second difference turns into noise that a
    window's integral does not have.
    """
    m = lambda x: _window_mean(x, w)  # noqa: E731

    def cand(c):
        column_for = None if c.column_for is None else (lambda sh, f=c.column_for: m(f(sh)))
        return Candidate(c.id, [m(x) for x in c.columns], c.shapes, c.lower, c.upper,
                         column_for=column_for, shape_bounds=c.shape_bounds)

    ig = problem.integral
    if ig is not None:
        ig = replace(ig, moving=m(ig.moving) > 0.5, weight=m(ig.weight),
                     speed_mps=None if ig.speed_mps is None else m(ig.speed_mps))
    return replace(problem, time_s=m(problem.time_s), measured=m(problem.measured), baseline=m(problem.baseline),
                   candidates=[cand(c) for c in problem.candidates],
                   surrogates={k: cand(c) for k, c in problem.surrogates.items()},
                   driver_channels={k: m(v) for k, v in problem.driver_channels.items()},
                   initial_terms=[(m(c), lo, hi) for c, lo, hi in problem.initial_terms], integral=ig, coarse=None)


#: The contrast null's random stream (with ``Settings.seed``), apart from the selection's.
CONTRAST_STREAM = 16


@dataclass
class Settings:
    folds: int = 5
    #: at least this many blocks per fold; more in long recordings so that blocks stay about
    #: ``block_s`` long: far longer than the noise's correlation time, short enough that an
    #: effect confined to the first minutes (a cold start) has data in several blocks
    blocks_per_fold: int = 4
    block_s: float = 120.0
    n_shifts: int = 200
    quantile: float = 0.99
    min_gain: float = 0.01
    max_effects: int = 3
    seed: int = 0
    #: where the rival check would make two physical effects ambiguous, compare them once
    #: more on the rows where their signatures differ most (:mod:`.contrast`;
    #: docs/diagnose-realdata.md, 1i)
    contrast_rivals: bool = False
    #: the contrast null's noise (:data:`fleetrun.diagnose.contrast.NOISE`): "own" (design C),
    #: "both" (design C2, docs/diagnose-realdata.md 1i)
    contrast_noise: str = "own"


def _params(cand: Candidate, shape: dict, coef: float) -> dict:
    effect = EFFECTS[effect_of(cand.id)]
    out = {effect.linear: float(coef)}
    out.update({k: float(v) for k, v in shape.items()})
    names = [p.name for p in effect.parameters if p.name in out]
    # a shape the catalogue entry does not list (a candidate built beyond the catalogue,
    # fleetrun.diagnose.route's profile direction) is reported after the entry's own
    names += [k for k in shape if k not in names]
    return {k: round(out[k], 6) for k in names}


def explanation(effect_id: str, params: dict[str, float], before: float, after: float, units: str) -> str:
    e = EFFECTS[effect_of(effect_id)]
    ps = ", ".join(f"{k} = {v:.3g}" for k, v in params.items())
    text = (f"The residual follows the signature of {e.title} ({e.signature}); adding it with "
            f"{ps} cuts the held-out error from {before:.3g} to {after:.3g} {units}.")
    at_bound = [p.name for p in e.parameters if p.name in params and
                (np.isclose(params[p.name], p.upper, rtol=0.01) or
                 (p.lower != 0 and np.isclose(params[p.name], p.lower, rtol=0.01)))]
    at_bound += [p.name for p in e.shape if p.grid and p.name in params and
                 (params[p.name] >= 0.99 * max(p.grid) or params[p.name] <= 1.01 * min(p.grid))]
    if at_bound:
        text += (f" {', '.join(dict.fromkeys(at_bound))} sits at the edge of its plausible range: the "
                 "data ask for more of this effect than the physics allows, so it is the best "
                 "available description rather than a measurement of it.")
    return text + f" Physics: {e.seed}."


def _ambiguity(best_id, rivals, statuses, ambiguities):
    tests = [EFFECTS[effect_of(best_id)].separating_test] + [
        EFFECTS[effect_of(rid)].separating_test for rid, _ in rivals if effect_of(rid) in EFFECTS]
    test = "; ".join(dict.fromkeys(t for t in tests if t))
    ambiguities.append({"effects": [best_id] + [rid for rid, _ in rivals],
                        "reasons": [why for _, why in rivals], "separating_test": test})
    for cid in [best_id] + [rid for rid, _ in rivals]:
        if cid not in statuses:
            continue
        if statuses[cid]["status"] == "untestable":
            statuses[cid]["could_explain"] = best_id
        else:
            statuses[cid]["status"] = "ambiguous"
            statuses[cid]["separating_test"] = test


def _refine_jointly(r, initial_terms, accepted: list[Accepted], passes: int = 2) -> list[Accepted]:
    """Re-fit the shape parameters of the accepted effects with each other in the model.

    A shape found while another effect was still missing (a warm-up time constant fitted
    before the inertia was in the model) is biased; left so, the misfit it leaves behind can
    be picked up as a spurious further effect. Coordinate passes over the accepted effects.
    """
    accepted = list(accepted)
    if len(accepted) < 2:
        return accepted
    for _ in range(passes):
        for i, a in enumerate(accepted):
            cand = a.cand
            if cand.column_for is None or len(a.shape) != 1:
                continue
            name, value = next(iter(a.shape.items()))
            grid = [sh[name] for sh in cand.shapes]
            index = int(np.argmin(np.abs(np.log(np.asarray(grid) / value))))
            others = list(initial_terms) + [b.term() for j, b in enumerate(accepted) if j != i]
            v, col = refine_shape(r, others, cand, index, name)
            accepted[i] = replace(a, shape={name: v}, column=col)
    return accepted


@dataclass
class _Search:
    """What the selection carries from one step to the next."""

    problem: Problem
    settings: Settings
    rng: np.random.Generator
    folds: np.ndarray
    statuses: dict = field(default_factory=dict)
    accepted: list[Accepted] = field(default_factory=list)
    nuisance: list = field(default_factory=list)      # terms in the model: (column, lower, upper)
    ambiguities: list = field(default_factory=list)
    rounds: list = field(default_factory=list)
    active: list = field(default_factory=list)
    first_threshold: float | None = None
    significant: bool = False
    stopped_untestable: bool = False
    baseline_heldout: float | None = None
    initial_coefficients: list = field(default_factory=list)

    @property
    def r(self) -> np.ndarray:
        return self.problem.residual

    @property
    def k(self) -> int:
        return self.settings.folds

    def model_terms(self, without=None) -> list:
        """The calibration terms and every accepted effect but ``without``."""
        return list(self.problem.initial_terms) + [a.term() for a in self.accepted if a is not without]


def _noise_threshold(s: _Search, terms, column, cand, pool) -> float:
    """Held-out SSE reduction that circularly shifted noise reaches (``quantile`` of the max).

    The noise estimate is what is left after ``terms`` *and* ``column``: shifting the raw
    residual would keep the effect's own structure (e.g. "constant while moving"), which
    the channels still match after a shift.
    """
    cols = [t[0] for t in terms] + [column]
    coefs = full_fit(s.r, cols, [(t[1], t[2]) for t in terms] + [(cand.lower, cand.upper)])
    r_noise = s.r - np.array(cols).T @ coefs
    null = shift_null(r_noise, terms, pool, s.folds, s.k, n_shifts=s.settings.n_shifts, rng=s.rng)
    return null.dsse_threshold(s.settings.quantile)


def _below_offset_floor(s: _Search, best, bev, best_col) -> bool:
    """A fitted constant-while-driving effect smaller than the sensor-zeroing uncertainty."""
    floor = s.problem.offset_floor.get(best.id)
    if floor is None:
        return False
    acts = np.abs(best_col) > 1e-9 * max(np.abs(best_col).max(), 1e-300)
    size = abs(bev.coefficient) * float(np.mean(np.abs(best_col[acts]))) if acts.any() else 0.0
    if size < floor:
        s.statuses[best.id]["note"] = (f"fitted size {size:.3g} {s.problem.units} is below the "
                                       f"sensor-zeroing uncertainty ({floor:.3g})")
        return True
    return False


def _untestable_could_explain(s: _Search, thr: float, thr_dsse: float) -> None:
    """Nothing testable explains the rest: say so if an untestable effect could."""
    p, n = s.problem, len(s.r)
    for uid, sur in p.surrogates.items():
        sev = evaluate_candidate(s.r, s.nuisance, sur, s.folds, s.k)
        if sev.gain > thr and n * (sev.rmse_before ** 2 - sev.rmse_after ** 2) > thr_dsse:
            s.significant = True
            s.ambiguities.append({
                "effects": [uid],
                "reasons": [f"{uid} cannot be tested (missing {', '.join(p.untestable[uid])}); "
                            f"with assumed values it would cut the held-out error by "
                            f"{100 * sev.gain:.0f} %"],
                "separating_test": EFFECTS[uid].separating_test})
            s.statuses[uid]["could_explain"] = "mismatch"


def _untestable_rivals(s: _Search, best, col, thr: float, thr_dsse: float) -> list:
    """Untestable effects (and sensor offsets) that could produce what ``best`` explains."""
    p = s.problem
    rivals = []
    for uid in p.untestable:
        missing = ", ".join(p.untestable[uid])
        if uid in p.surrogates:
            sur = p.surrogates[uid]
            sev = evaluate_candidate(s.r, s.nuisance, sur, s.folds, s.k)
            scol = sur.columns[sev.shape_index]
            b1, a1, _ = cv_fit(s.r, s.nuisance + [(scol, sur.lower, sur.upper)], col,
                               best.lower, best.upper, s.folds, s.k)
            b2, a2, _ = cv_fit(s.r, s.nuisance + [(col, best.lower, best.upper)], scol,
                               sur.lower, sur.upper, s.folds, s.k)
            if sev.gain > thr and b1 - a1 <= thr_dsse:
                rivals.append((uid, f"cannot be tested (missing {missing}) but with assumed "
                                    f"values it fits as well ({sev.gain:.3f})"))
            elif b2 - a2 > thr_dsse:
                rivals.append((uid, f"cannot be tested (missing {missing}) and with assumed "
                                    f"values explains what {best.id} leaves"))
        elif effect_of(best.id) in EFFECTS[uid].confounded_with and p.confound_possible.get(uid, False):
            rivals.append((uid, f"cannot be tested (missing {missing}) and produces a residual "
                                f"like {best.id}'s in such data"))
    if best.id in p.extra_ambiguity:
        rivals.append(("sensor_offset", p.extra_ambiguity[best.id]))
    return rivals


def _forward_step(s: _Search) -> bool:
    """One round of forward selection; False when the search stops."""
    r, n = s.r, len(s.r)
    evals = {c.id: evaluate_candidate(r, s.nuisance, c, s.folds, s.k) for c in s.active}
    best = max(s.active, key=lambda c: evals[c.id].gain)
    bev = evals[best.id]
    if s.baseline_heldout is None:
        s.baseline_heldout = bev.rmse_before      # CV of the baseline (its own terms refitted)
    shape, best_col = chosen(best, bev)
    thr_dsse = _noise_threshold(s, s.nuisance, best_col, best, s.active)
    dsse = n * (bev.rmse_before ** 2 - bev.rmse_after ** 2)
    thr = max(1 - np.sqrt(max(1 - thr_dsse / (n * bev.rmse_before ** 2), 0.0)), s.settings.min_gain) \
        if bev.rmse_before > 0 else s.settings.min_gain
    if s.first_threshold is None:
        s.first_threshold = thr
    s.rounds.append({"threshold_gain": thr, "threshold_dsse": thr_dsse, "dsse": dsse,
                     "gains": {c.id: evals[c.id].gain for c in s.active}})
    for c in s.active:
        s.statuses[c.id] = {"effect": c.id, "status": "rejected",
                            "heldout_gain": round(evals[c.id].gain, 5),
                            "parameters": _params(c, chosen(c, evals[c.id])[0], evals[c.id].coefficient)}
    if _below_offset_floor(s, best, bev, best_col) or not (dsse > thr_dsse and bev.gain > s.settings.min_gain):
        _untestable_could_explain(s, thr, thr_dsse)
        return False
    s.significant = True
    col = best_col
    if best.column_for is not None and len(shape) == 1:
        name = next(iter(shape))
        v, col = refine_shape(r, s.nuisance, best, bev.shape_index, name)
        shape = {name: v}
    rivals = _untestable_rivals(s, best, col, thr, thr_dsse)
    if rivals:
        _ambiguity(best.id, rivals, s.statuses, s.ambiguities)
        # what the residual shows may be an effect that cannot be fitted: nothing fitted
        # now can be trusted to leave only noise behind, so the search stops here
        s.stopped_untestable = True
        return False
    s.accepted.append(Accepted(best, shape, col, bev.rmse_before, bev.rmse_after, bev.gain))
    s.statuses[best.id]["status"] = "accepted"
    s.accepted = _refine_jointly(r, s.problem.initial_terms, s.accepted)
    s.nuisance = s.model_terms()
    s.active = [c for c in s.active if c.id != best.id]
    return True


def _rivals_of(s: _Search, a: Accepted, others: list, pool: list) -> list:
    """Testable candidates of ``pool`` that fit what ``a`` explains about as well: each beats
    the noise null alone, and with it in the model ``a`` adds nothing beyond noise.
    ``(id, reason, candidate, column)`` each."""
    r, n, st = s.r, len(s.r), s.settings
    thr_dsse = _noise_threshold(s, others, a.column, a.cand, pool + [a.cand])
    rivals = []
    for c in pool:
        ev = evaluate_candidate(r, others, c, s.folds, s.k)
        if n * (ev.rmse_before ** 2 - ev.rmse_after ** 2) <= thr_dsse or ev.gain <= st.min_gain:
            continue
        ccol = chosen(c, ev)[1]
        b1, a1, _ = cv_fit(r, others + [(ccol, c.lower, c.upper)], a.column,
                           a.cand.lower, a.cand.upper, s.folds, s.k)
        if b1 - a1 <= thr_dsse:
            rivals.append((c.id, f"fits about as well ({ev.gain:.3f} held-out gain): with "
                                 f"it in the model, {a.id} adds nothing beyond noise", c, ccol))
    return rivals


def _contrast_decides(s: _Search, a: Accepted, others: list, rivals: list) -> tuple[list, tuple | None]:
    """The rivals still tied with ``a`` after comparing each on the rows where their
    signatures differ (:func:`fleetrun.diagnose.contrast.compare`), and the first rival that
    wins over ``a`` there (None if none does; a later winner stays tied; blocks are never
    compared). Each comparison's numbers go to the rival's status (``contrast``, extra key)."""
    n = len(s.r)
    lo_s = max(1, int(0.05 * n))
    # a stream of its own: the contrast must not move the selection's later shift nulls
    shifts = np.random.default_rng([s.settings.seed, CONTRAST_STREAM]).integers(lo_s, n - lo_s, s.settings.n_shifts)
    tied, winner = [], None
    for rival in rivals:
        cand, ccol = rival[2], rival[3]
        if cand.block is not None or a.cand.block is not None:
            tied.append(rival)
            continue
        found = compare(s.r, others, a.term(), (ccol, cand.lower, cand.upper), shifts, s.settings.quantile,
                        s.settings.contrast_noise)
        who = found.winner
        s.statuses[cand.id]["contrast"] = {"against": a.id, "winner": {"a": a.id, "r": cand.id}.get(who),
                                           **found.as_json()}
        if who == "r" and winner is None:
            winner = rival
        elif who != "a":
            tied.append(rival)
    return tied, winner


def _swap(s: _Search, a: Accepted, cand: Candidate, others: list) -> Accepted:
    """``cand`` in ``a``'s place: it won the contrast (``a`` is rejected, with a note)."""
    ev = evaluate_candidate(s.r, others, cand, s.folds, s.k)
    shape, col = chosen(cand, ev)
    s.statuses[a.id]["status"] = "rejected"
    s.statuses[a.id]["note"] = (f"{cand.id} describes the same data and fits better where their "
                                "signatures differ (contrast folds, docs/diagnose.md section 5)")
    s.statuses[cand.id]["status"] = "accepted"
    return Accepted(cand, shape, col, ev.rmse_before, ev.rmse_after, ev.gain)


def _rival_check(s: _Search) -> None:
    """Confounding among testable candidates, judged with everything else in the model.

    A rival R makes an accepted effect A ambiguous when, with the other accepted effects in
    the model, R alone beats the noise null and A adds nothing beyond noise once R is in.
    Judging this only at the end matters: while another effect is still unmodelled, the
    noise estimate holds its structure and every rival looks "as good". With
    ``Settings.contrast_rivals`` a tie is compared once more where the two signatures differ
    (:func:`_contrast_decides`); a rival that wins there takes A's place and is checked in turn.
    """
    taken = {a.id for a in s.accepted}
    remaining = [c for c in s.problem.candidates if c.id not in taken]
    keep = []
    for a in s.accepted:
        others = s.model_terms(without=a)
        rivals = _rivals_of(s, a, others, remaining)
        if rivals and s.settings.contrast_rivals:
            rivals, winner = _contrast_decides(s, a, others, rivals)
            if winner is not None:
                loser, a = a, _swap(s, a, winner[2], others)
                remaining = [c for c in remaining if c.id != a.id]
                rivals, again = _contrast_decides(s, a, others, _rivals_of(s, a, others, remaining))
                rivals += [again] if again is not None else []
                remaining.append(loser.cand)
        if rivals:
            _ambiguity(a.id, [(rid, why) for rid, why, _, _ in rivals], s.statuses, s.ambiguities)
        else:
            keep.append(a)
    s.accepted = keep


def _final_refit(s: _Search) -> tuple[list[Finding], np.ndarray]:
    """Joint refit of every accepted effect on all data: the parameters reported, and the
    fitted effects (calibration constants move with them) in target units."""
    p = s.problem
    findings = []
    fitted = np.zeros(len(s.r))
    if not s.accepted:
        return findings, fitted
    init = list(p.initial_terms)
    cols = [t[0] for t in init] + [a.column for a in s.accepted]
    coefs = full_fit(s.r, cols, [(t[1], t[2]) for t in init]
                     + [(a.cand.lower, a.cand.upper) for a in s.accepted])
    s.initial_coefficients = [float(c) for c in coefs[:len(init)]]
    for col, c in zip(cols[:len(init)], coefs[:len(init)]):
        fitted = fitted + c * col
    s.accepted = [replace(a, coefficient=float(c)) for a, c in zip(s.accepted, coefs[len(init):])]
    for a in s.accepted:
        params = _params(a.cand, a.shape, a.coefficient)
        s.statuses[a.id]["parameters"] = params
        s.statuses[a.id]["heldout_gain"] = round(a.gain, 5)
        text = explanation(a.id, params, a.before, a.after, p.units)
        if a.relaxed is not None:
            text += (f" Sized after its selection: its {a.cand.block.shape[0]} weights refitted with "
                     f"the penalty at {a.relaxed:.3g} x the selection's (least held-out error).")
        findings.append(Finding(a.id, params, round(a.before, 6), round(a.after, 6), text,
                                EFFECTS[effect_of(a.id)].seed))
        fitted = fitted + a.coefficient * a.column
    return findings, fitted


def fitted_on(problem: Problem, selection: Selection) -> np.ndarray:
    """The findings of ``selection`` (made on ``problem.coarse``) and the moves of the
    calibration terms, evaluated on ``problem``'s own samples."""
    fitted = np.zeros(len(problem.time_s))
    for (col, _, _), c in zip(problem.initial_terms, selection.initial_coefficients):
        fitted = fitted + c * col
    by_id = {c.id: c for c in problem.candidates}
    for a in selection.accepted:
        cand = by_id[a.id]
        if cand.column_for is not None and a.shape:
            col = cand.column_for(a.shape)
        else:
            col = cand.columns[cand.shapes.index(a.shape) if a.shape in cand.shapes else 0]
        fitted = fitted + a.coefficient * col
    return fitted


def _relax_blocks(s: _Search) -> bool:
    """Block findings (a road's knots) sized after the selection: their weights refitted with
    the penalty relaxed as :func:`fleetrun.diagnose.select.relaxed_block` chooses, the other
    findings and the calibration terms in the model. What is named does not change; True if
    any finding was refitted."""
    done = False
    for i, a in enumerate(s.accepted):
        if a.cand.block is None or not a.cand.relax:
            continue
        w, factor = relaxed_block(s.r, s.model_terms(without=a), a.cand, s.folds, s.k)
        shape, col, _ = block_shape(a.cand, w)
        s.accepted[i] = replace(a, shape=shape, column=col, relaxed=factor)
        done = True
    return done


def _open_world(s: _Search) -> tuple[list, np.ndarray, "Unexplained", list]:
    """Final findings and their fit, then what they leave (:mod:`.openworld`): physics first,
    the remainder judged after it and never against it. Each demotion of a weak effect
    changes the fit, so the review repeats until nothing more is demoted."""
    descriptions: list = []
    findings, fitted = _final_refit(s)
    while s.accepted and review(s, findings, descriptions):
        findings, fitted = _final_refit(s)
    if _relax_blocks(s):
        findings, fitted = _final_refit(s)
    left = unexplained(s.problem, s.r, fitted, s.accepted, s.settings, rng=s.rng, folds=s.folds)
    return findings, fitted, left, descriptions


def search_folds(problem: Problem, st: Settings) -> np.ndarray:
    """The selection's cross-validation fold of each sample of ``problem`` (:func:`fold_ids`)."""
    duration = float(problem.time_s[-1] - problem.time_s[0])
    per_fold = max(st.blocks_per_fold, int(round(duration / (st.folds * st.block_s))))
    return fold_ids(len(problem.residual), st.folds, per_fold)


def relaxed_fit(problem: Problem, cid: str, settings: Settings | None = None) -> tuple[np.ndarray, float]:
    """The block candidate ``cid`` of ``problem`` refitted as a finding would be
    (:func:`fleetrun.diagnose.select.relaxed_block`) with only the calibration terms in the
    model, whatever its status: what it fits where it is no finding (the background a
    validation takes off). Weights and the penalty factor chosen."""
    st = settings or Settings()
    cand = next(c for c in problem.candidates if c.id == cid)
    return relaxed_block(problem.residual, list(problem.initial_terms), cand, search_folds(problem, st), st.folds)


def _search(problem: Problem, st: Settings) -> tuple[_Search, list, np.ndarray, Unexplained, list]:
    """Forward selection, rival check and the open-world step on ``problem``."""
    s = _Search(problem, st, np.random.default_rng(st.seed), search_folds(problem, st))
    for cid, missing in problem.untestable.items():
        s.statuses[cid] = {"effect": cid, "status": "untestable", "heldout_gain": None,
                           "missing_channels": missing}
    s.nuisance = list(problem.initial_terms)
    s.active = list(problem.candidates)
    for _round in range(st.max_effects):
        if not s.active or not _forward_step(s):
            break
    if s.accepted and not s.stopped_untestable:
        _rival_check(s)
    findings, fitted, left, descriptions = _open_world(s)
    return s, findings, fitted, left, descriptions


def _with_drift(problem: Problem) -> Problem:
    """``problem`` with the drift check's gain and offset as free calibration terms."""
    gain_cols, offset_cols = drift_columns(problem)
    free = [(c, -np.inf, np.inf) for c in gain_cols + offset_cols]
    return replace(problem, initial_terms=list(problem.initial_terms) + free, coarse=None)


def select(problem: Problem, settings: Settings | None = None) -> Selection:
    """Run the selection: physics first, then what it leaves, then the drift check.

    When the drift check fires, the physics is selected once more with the drift's gain and
    offset as free calibration terms (a drifting sensor biases every effect fitted through
    it); the drift stays reported as unexplained (docs/diagnose.md, section 6).
    """
    st = settings or Settings()
    s, findings, fitted, left, descriptions = _search(problem, st)
    baseline_heldout = s.baseline_heldout
    if left.drift is not None and left.drift.significant:
        # findings and statuses from the drift-corrected pass; what is left (with the drift
        # in it) and the baseline's held-out error from the first
        s, findings, fitted, _, descriptions = _search(_with_drift(problem), st)
        # the findings (and the baseline's own calibration) in target units, without the drift
        k = len(problem.initial_terms)
        for (col, _, _), c in zip(s.problem.initial_terms[k:], s.initial_coefficients[k:]):
            fitted = fitted - c * col
        s.initial_coefficients = s.initial_coefficients[:k]
    # each candidate's gain over the baseline alone (round 1), next to its gain in the final
    # round (over the model with the accepted effects): both tell the story
    if s.rounds:
        for cid, g in s.rounds[0]["gains"].items():
            if cid in s.statuses:
                s.statuses[cid]["heldout_gain_vs_baseline"] = round(float(g), 5)
    order = [c.id for c in problem.candidates] + list(problem.untestable)
    # the sensor-drift check is reported under unexplained.drift, not as a candidate effect:
    # a candidate `accepted` is physics in the model (docs/interface.md)
    candidates = [s.statuses[cid] for cid in order if cid in s.statuses]
    return Selection(tuple(findings), candidates, s.ambiguities, descriptions, left,
                     s.significant or bool(s.ambiguities) or left.significant, s.first_threshold,
                     s.rounds, fitted, baseline_heldout, tuple(s.accepted), tuple(s.initial_coefficients))
