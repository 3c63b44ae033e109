"""The open world: what the accepted findings leave unexplained, and which findings survive it.

A catalogue effect fitted to physics the catalogue does not hold explains part of it and
beats the noise null; named as "the model leaves out X" it would be a confident wrong
answer. So after the selection (:mod:`.engine`) the remainder ``r - fitted`` is tested:

* **Generic description.** The remainder is fitted by a model that knows no physics: an
  intercept plus a piecewise-linear function of each operating channel (hinges at its
  quantiles) and, for the first two channels, each times a piecewise-linear function of the
  other (:func:`generic_columns`), by the same blocked cross-validation as the candidates.
  Its held-out SSE reduction over the intercept is compared with the reductions
  it reaches on circularly shifted remainders (the same null as the selection's: same
  autocorrelation and distribution, no link to the channels). ``significant`` when it beats
  the ``quantile`` of that null and cuts the held-out error by more than 10 %
  (:data:`UNEXPLAINED_MIN_GAIN`).
  ``noise_rmse`` is the held-out RMSE the generic model leaves: the part no function of the
  recorded channels explains.
* **Findings judged against it.** When something is left, each finding is refitted with the
  generic description of the remainder's significant drivers (all channels, strongest first,
  if none is significant on its own) in the model; a finding that
  then adds nothing beyond noise was a partial description of the unexplained physics and is
  moved to ``descriptions`` ("weak"), not reported as a finding. So is a finding whose
  parameter sits at a bound of its plausible range, or whose column is nearly the same as a
  rival's (``ambiguous``).
"""
from __future__ import annotations

import numpy as np

from fleetrun.diagnose.locate import drivers as find_drivers
from fleetrun.diagnose.locate import segments as find_segments
from fleetrun.diagnose.select import (_circ_corr, _fold_gram, _heldout_sse, cv_fit, full_fit,
                                      shift_null)

#: Hinges per channel of the generic description (a piecewise-linear function of it).
GENERIC_KNOTS = 6
#: Smallest held-out gain of the generic description that counts as something left
#: unexplained: 10 % means a structured part of at least half the size of what it leaves
#: (sqrt(1 / 0.9^2 - 1) = 0.48). Smaller structure (a slightly misfitted shape, errors in the
#: measured channels the baseline uses, a generic model's reach into autocorrelated noise)
#: is not worth a sentence in the report and must not overturn a finding.
UNEXPLAINED_MIN_GAIN = 0.10
#: Columns closer than this (cosine of the angle, after the calibration terms) cannot be told
#: apart by any fit: a finding with such a rival is ambiguous. A rival's columns at the ends
#: of its shape grid do not count (there the rival is itself at a bound: a weak description).
COLLINEAR_COS = 0.995


def _hinges(x: np.ndarray, n_knots: int) -> list[np.ndarray]:
    """``x`` scaled to [0, 1] (first) and hinges ``max(x - q, 0)`` at ``n_knots`` inner
    quantiles, and an indicator of a point mass at the minimum (standstill, straight driving)
    if there is one."""
    span = float(np.ptp(x))
    if span <= 1e-12 * max(1.0, float(np.abs(x).max())):
        return []
    cols = [(x - x.min()) / span]
    at_min = x <= x.min() + 0.02 * span
    if 0.05 < at_min.mean() < 0.95:
        cols.append(at_min.astype(float))
    knots = np.unique(np.quantile(x[~at_min] if (~at_min).sum() > n_knots else x,
                                  np.linspace(0, 1, n_knots + 2)[1:-1]))
    cols.extend(np.maximum(x - q, 0.0) / span for q in knots)
    return cols


def generic_columns(channels: dict, names=None, n_knots: int = GENERIC_KNOTS) -> list[np.ndarray]:
    """A piecewise-linear function of each channel (:func:`_hinges`) and, for the first two
    of ``names``, each one times a piecewise-linear function of the other: losses in a
    differential are often a torque times a function of speed."""
    names = list(names if names is not None else channels)
    per = {name: _hinges(np.asarray(channels[name], dtype=float), n_knots) for name in names}
    cols = [c for name in names for c in per[name]]
    usable = [name for name in names if per[name]]
    if len(usable) >= 2:
        a, b = usable[:2]
        cols.extend(per[a][0] * c for c in per[b])    # x_a (scaled) x f(x_b)
        cols.extend(per[b][0] * c for c in per[a][1:])
    return cols


def _shifted_fold_stats(r, cols, folds, k, shifts):
    """Per shift and fold: ``sum r^2``, ``X^T r`` of the shifted remainder (FFT)."""
    n = len(r)
    r_fft = np.fft.rfft(r)
    masks = [(folds == f).astype(float) for f in range(k)]
    r2_fft = np.fft.rfft(r * r)
    rr = np.stack([_circ_corr(np.fft.rfft(m), r2_fft, n)[shifts] for m in masks], axis=-1)
    c = np.stack([np.stack([_circ_corr(np.fft.rfft(x * m), r_fft, n)[shifts] for x in cols], -1)
                  for m in masks], 1)
    return rr, c                                                   # (B, K), (B, K, p)


def generic_test(r, cols, folds, k, *, n_shifts=200, rng=None):
    """Held-out SSE of the intercept alone and with ``cols``, for the remainder (index 0) and
    ``n_shifts`` circular shifts of it; the columns are unbounded."""
    rng = rng or np.random.default_rng(0)
    n = len(r)
    lo_s = max(1, n // 20)
    shifts = np.r_[0, rng.integers(lo_s, n - lo_s, n_shifts)]
    X = np.array([np.ones(n)] + list(cols))
    rr, c = _shifted_fold_stats(r, X, folds, k, shifts)
    G = _fold_gram(X, folds, k)
    B = len(shifts)
    p = X.shape[0]
    inf = np.full(p, np.inf)
    sse_base = _heldout_sse(np.broadcast_to(G[:, :1, :1], (B, k, 1, 1)), c[..., :1], rr, -inf[:1], inf[:1])
    sse_full = _heldout_sse(np.broadcast_to(G, (B,) + G.shape), c, rr, -inf, inf)
    return sse_base, sse_full


def unexplained(problem, remainder, settings, *, rng, folds) -> dict:
    """The ``unexplained`` block of diagnosis.json for ``remainder`` (docs/interface.md)."""
    ch = problem.driver_channels
    cols = generic_columns(ch)
    n = len(remainder)
    sse_base, sse_full = generic_test(remainder, cols, folds, settings.folds,
                                      n_shifts=settings.n_shifts, rng=rng)
    dsse = sse_base - sse_full
    threshold = float(np.quantile(dsse[1:], settings.quantile))
    gain = 1 - np.sqrt(max(sse_full[0], 0.0) / max(sse_base[0], 1e-300))
    significant = bool(dsse[0] > threshold and gain > UNEXPLAINED_MIN_GAIN)
    rate = n / max(problem.time_s[-1] - problem.time_s[0], 1e-9)
    drv, _ = find_drivers(ch, remainder, rng=rng, smooth_window=max(1, int(rate)),
                          null_residual=remainder)
    segs = find_segments(problem.time_s, remainder) if significant else []
    return {"significant": significant,
            "rmse": round(float(np.sqrt(np.mean(remainder ** 2))), 6),
            "noise_rmse": round(float(np.sqrt(max(sse_full[0], 0.0) / n)), 6),
            "heldout_gain": round(float(gain), 5),
            "segments": segs, "drivers": drv}


def _at_bound(cand, effect, params: dict) -> list[str]:
    """Parameters of a fitted effect at a bound of their plausible range (or at zero)."""
    out = []
    for p in effect.parameters:
        v = params.get(p.name)
        if v is None:
            continue
        if p.grid:
            if v >= 0.99 * max(p.grid) or v <= 1.01 * min(p.grid):
                out.append(p.name)
        elif np.isclose(v, cand.upper, rtol=0.01) or np.isclose(v, cand.lower, rtol=0.01, atol=1e-9):
            out.append(p.name)
    return out


def _collinear_rival(search, a) -> str | None:
    """A testable rival whose best column is nearly ``a``'s (after the calibration terms)."""
    init = [t[0] for t in search.problem.initial_terms]

    def clean(x):
        if not init:
            return x
        A = np.array(init).T
        return x - A @ np.linalg.lstsq(A, x, rcond=None)[0]

    xa = clean(a["column"])
    na = np.linalg.norm(xa)
    for c in search.problem.candidates:
        if c.id == a["cand"].id or na == 0:
            continue
        for x in c.columns[1:-1] if len(c.columns) > 2 else c.columns:
            xc = clean(x)
            nc = np.linalg.norm(xc)
            if nc > 0 and abs(xa @ xc) / (na * nc) > COLLINEAR_COS:
                return c.id
    return None


def _survives(search, a, generic) -> bool:
    """Does ``a`` still add more than noise with the generic description in the model?"""
    r, st = search.r, search.settings
    terms = search.model_terms(without=a) + [(g, -np.inf, np.inf) for g in generic]
    cand = a["cand"]
    before, after, _ = cv_fit(r, terms, a["column"], cand.lower, cand.upper, search.folds, st.folds)
    cols = [t[0] for t in terms] + [a["column"]]
    coefs = full_fit(r, cols, [(t[1], t[2]) for t in terms] + [(cand.lower, cand.upper)])
    r_noise = r - np.array(cols).T @ coefs
    null = shift_null(r_noise, terms, [cand], search.folds, st.folds, n_shifts=st.n_shifts,
                      rng=search.rng)
    gain = 1 - np.sqrt(max(after, 0.0) / max(before, 1e-300))
    return bool(before - after > null.dsse_threshold(st.quantile) and gain > st.min_gain)


def _demote(search, a, status: str, reason: str, descriptions: list) -> None:
    cid = a["cand"].id
    entry = search.statuses[cid]
    entry["status"] = status
    entry["note"] = reason
    descriptions.append({"effect": cid, "status": status, "parameters": entry.get("parameters", {}),
                         "heldout_rmse_before": round(a["before"], 6),
                         "heldout_rmse_after": round(a["after"], 6), "reason": reason})


def review(search, findings: list, left: dict, descriptions: list) -> bool:
    """Judge the accepted effects in the open world against ``left`` (the ``unexplained``
    block of the model with them); demoted effects go to ``descriptions`` and out of
    ``search.accepted``. True if any was demoted."""
    from fleetrun.effects import EFFECTS

    generic = []
    if left["significant"]:
        # the channels the remainder follows; if none does on its own beyond the drivers'
        # null (a remainder that follows several channels at once), all of them, strongest first
        names = [d["channel"] for d in left["drivers"] if d["significant"]] or \
            [d["channel"] for d in left["drivers"]]
        generic = generic_columns(search.problem.driver_channels, names)
    keep = []
    by_id = {f["effect"]: f for f in findings}
    for a in search.accepted:
        cid = a["cand"].id
        bound = _at_bound(a["cand"], EFFECTS[cid], by_id[cid]["parameters"])
        rival = _collinear_rival(search, a)
        if a.get("coefficient", 1.0) == 0.0:
            _demote(search, a, "ambiguous", "weak: refitted together with the other findings "
                    "its size is zero", descriptions)
        elif bound:
            _demote(search, a, "ambiguous", f"weak: {', '.join(bound)} at the edge of its "
                    "plausible range; the data ask for more (or less) of this effect than the "
                    "physics allows, so it describes the mismatch rather than measures it",
                    descriptions)
        elif rival:
            _demote(search, a, "ambiguous", f"its column is nearly the same as {rival}'s in "
                    "this recording: no fit can tell them apart", descriptions)
        elif generic and not _survives(search, a, generic):
            _demote(search, a, "ambiguous", "weak: a mismatch outside the catalogue remains, "
                    "and with it described generically this effect adds nothing beyond noise; "
                    "it is a partial description of that mismatch, not a finding", descriptions)
        else:
            keep.append(a)
    demoted = len(keep) < len(search.accepted)
    search.accepted = keep
    return demoted
