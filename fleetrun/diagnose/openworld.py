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
from fleetrun.diagnose.records import Drift, Unexplained
from fleetrun.diagnose.select import _circ_corr, _fold_gram, _heldout_sse, effect_of

#: Hinges per channel of the generic description (a piecewise-linear function of it).
GENERIC_KNOTS = 6
#: Tikhonov term of the generic description's fit, relative to the mean diagonal of its Gram
#: matrix: a hinge that only a few samples of one fold reach (a rare wide turn) would
#: otherwise get an arbitrary coefficient from the other folds and wreck that fold's error.
GENERIC_RIDGE = 1e-3
#: Smallest held-out gain of the generic description (on what is left beyond the form
#: allowance, :func:`form_columns`) that counts as something left unexplained: 5 % means a
#: structured part of at least a third of the size of what it leaves
#: (sqrt(1 / 0.95^2 - 1) = 0.33). Smaller structure (errors in the measured channels the
#: baseline uses, a generic model's reach into autocorrelated noise) is not worth a sentence.
UNEXPLAINED_MIN_GAIN = 0.05
#: Largest change of an accepted effect's exponent on speed or torque that counts as a small
#: form mismatch (:func:`form_columns`): n^0.6 for n^(2/3) is 0.07. Larger allowances absorb
#: a torque share lost at every speed into a mesh friction's form (measured with
#: validation/diagnose_perturbed.py: 0.2 let 4 of 10 such recordings pass as explained).
FORM_EXPONENT = 0.1
#: Inner knots of the piecewise-linear gain and offset of the drift check.
DRIFT_KNOTS = 7
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


def generic_columns(channels: dict[str, np.ndarray], names=None, n_knots: int = GENERIC_KNOTS) -> list[np.ndarray]:
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
    sse_full = _heldout_sse(np.broadcast_to(G, (B,) + G.shape), c, rr, -inf, inf, GENERIC_RIDGE)
    return sse_base, sse_full


def _lag(x: np.ndarray, tau_s: float, dt_s: float) -> np.ndarray:
    """First-order lag of ``x`` (time constant ``tau_s``), started at ``x[0]``."""
    from scipy.signal import lfilter

    a = 1.0 - np.exp(-dt_s / tau_s)
    return lfilter([a], [1.0, a - 1.0], x, zi=[(1 - a) * x[0]])[0]


def _log_tilt(x: np.ndarray) -> np.ndarray:
    """``log(|x| / median |x|)`` with ``|x|`` floored at 5 % of its largest value."""
    ax = np.abs(np.asarray(x, dtype=float))
    top = float(ax.max()) if ax.size else 0.0
    if top <= 0:
        return np.zeros_like(ax)
    ax = np.maximum(ax, 0.05 * top)
    return np.log(ax / np.median(ax))


def form_columns(problem, accepted) -> list[tuple[np.ndarray, float, float]]:
    """What a small form mismatch of each accepted effect could leave in the remainder.

    For an effect whose fitted contribution is ``f`` (target units), first-order
    perturbations of its form (docs/diagnose.md, "Form mismatch"):

    * a lag or a different derivative filter: ``lag(f, 0.3 s) - f`` and ``lag(f, 1 s) - f``,
      each with a weight in [0, 1] (a lag of up to that time constant);
    * a different exponent on speed or torque (``n^0.6`` for ``n^(2/3)``, a torque share that
      is not exactly proportional): ``f log(n / median n)``, ``f log(T / median T)``, weights
      within +-:data:`FORM_EXPONENT` (``f n^d ~ f (1 + d log n)``);
    * a different time constant or speed scale: the difference of the column at 1.1 and
      1/1.1 times its shape parameter, times the coefficient, weight within +-1.5 (the shape
      parameter off by up to ~30 %).

    Returned as model terms ``(column, lower, upper)``. Each is zero wherever the effect is,
    and bounded to a small perturbation, so a cause outside the catalogue that an accepted
    effect resembles only in part is not absorbed by them.
    """
    t = problem.time_s
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    ch = problem.driver_channels
    cols = []
    for a in accepted:
        if not a.coefficient:
            continue
        f = a.coefficient * a.column
        cols += [(_lag(f, 0.3, dt) - f, 0.0, 1.0), (_lag(f, 1.0, dt) - f, 0.0, 1.0)]
        cols += [(f * _log_tilt(ch[name]), -FORM_EXPONENT, FORM_EXPONENT)
                 for name in ("speed", "torque") if name in ch]
        if a.cand.column_for is not None and len(a.shape) == 1:
            (name, value), = a.shape.items()
            up = a.cand.column_for({name: value * 1.1})
            down = a.cand.column_for({name: value / 1.1})
            if len(up) == len(f):
                cols.append((a.coefficient * (up - down), -1.5, 1.5))
    return [c for c in cols if np.any(c[0] != 0) and np.all(np.isfinite(c[0]))]


def _project_out(r: np.ndarray, terms: list[tuple[np.ndarray, float, float]]) -> np.ndarray:
    """``r`` minus its least-squares fit on the bounded ``terms`` ``(column, lower, upper)``."""
    if not terms:
        return r
    from fleetrun.diagnose.select import full_fit

    cols = [t[0] for t in terms]
    b = full_fit(r, cols, [(t[1], t[2]) for t in terms])
    return r - np.array(cols).T @ b


def _generic_verdict(remainder, cols, folds, settings, rng) -> tuple[bool, float, float]:
    """Does the generic description ``cols`` beat the shift null on ``remainder``? The
    verdict, its held-out gain and the held-out SSE it leaves."""
    sse_base, sse_full = generic_test(remainder, cols, folds, settings.folds,
                                      n_shifts=settings.n_shifts, rng=rng)
    dsse = sse_base - sse_full
    threshold = float(np.quantile(dsse[1:], settings.quantile))
    gain = 1 - np.sqrt(max(sse_full[0], 0.0) / max(sse_base[0], 1e-300))
    return bool(dsse[0] > threshold and gain > UNEXPLAINED_MIN_GAIN), float(gain), float(max(sse_full[0], 0.0))


def drift_columns(problem, n_knots: int = DRIFT_KNOTS) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """A sensor gain and offset piecewise linear in time (``n_knots`` inner knots), as their
    effect on the target: ``baseline x h_k(t)`` (gain) and ``h_k(t)`` (offset), with
    ``h_0 = t / T`` and ``h_k = max(t / T - k / (n_knots + 1), 0)``."""
    t = problem.time_s - problem.time_s[0]
    span = max(float(t[-1]), 1e-9)
    u = t / span
    hinges = [u] + [np.maximum(u - k / (n_knots + 1), 0.0) for k in range(1, n_knots + 1)]
    return [problem.baseline * h for h in hinges], hinges


def drift_check(problem, remainder, settings, *, rng, folds) -> Drift:
    """``sensor_drift``: is what the physics leaves a slowly changing gain or offset of the
    target's sensor? Tested like the generic description (blocked CV against the shift
    null); the fitted drift is located in time where it does 10-90 % of its moving."""
    gain_cols, offset_cols = drift_columns(problem)
    significant, gain, _ = _generic_verdict(remainder, gain_cols + offset_cols, folds, settings, rng)
    A = np.array([np.ones(len(remainder))] + gain_cols + offset_cols).T
    b = np.linalg.lstsq(A, remainder, rcond=None)[0]
    k = len(gain_cols)
    hinges = np.array(offset_cols).T
    g = hinges @ b[1:1 + k]
    o = hinges @ b[1 + k:]
    scale = float(np.median(np.abs(problem.baseline))) or 1.0
    moving = np.abs(np.diff(g * scale + o))
    cum = np.r_[0.0, np.cumsum(moving)]
    t = problem.time_s - problem.time_s[0]
    if cum[-1] > 0:
        start, end = (float(t[np.searchsorted(cum, q * cum[-1])]) for q in (0.1, 0.9))
    else:
        start = end = 0.0
    return Drift(significant, gain, float(g[np.argmax(np.abs(g))]), float(o[np.argmax(np.abs(o))]),
                 start, end)


def unexplained(problem, residual, fitted, accepted, settings, *, rng, folds) -> Unexplained:
    """The ``unexplained`` block of diagnosis.json (docs/diagnose.md): the remainder
    ``residual - fitted`` by its size, judged against what a small form mismatch of the
    ``accepted`` effects could leave, and the drift check."""
    ch = problem.driver_channels
    remainder = residual - fitted
    n = len(remainder)
    cols = generic_columns(ch)
    beyond_form = _project_out(remainder, form_columns(problem, accepted))
    significant, gain, sse_left = _generic_verdict(beyond_form, cols, folds, settings, rng)
    drift = drift_check(problem, beyond_form, settings, rng=rng, folds=folds)
    noise2 = sse_left / n
    structured = float(np.mean(residual ** 2)) - noise2
    if structured > 0.01 * noise2:
        energy_share = min(max(float(np.mean(remainder ** 2)) - noise2, 0.0) / structured, 1.0)
        form_share = max(float(np.mean(remainder ** 2) - np.mean(beyond_form ** 2)), 0.0) / structured
    else:     # no structured mismatch to begin with: no share to report
        energy_share = form_share = None
    significant = significant or drift.significant
    rate = n / max(problem.time_s[-1] - problem.time_s[0], 1e-9)
    drv, _ = find_drivers(ch, remainder, rng=rng, smooth_window=max(1, int(rate)),
                          null_residual=remainder)
    segs = find_segments(problem.time_s, remainder) if significant else []
    return Unexplained(significant, float(np.sqrt(np.mean(remainder ** 2))), float(np.sqrt(noise2)),
                       gain, energy_share, None if form_share is None else min(form_share, 1.0),
                       segs, drv, drift)


def _at_bound(cand, effect, params: dict) -> list[str]:
    """Parameters of a fitted effect at a bound of their plausible range (or at zero)."""
    out = []
    for p in effect.parameters:
        v = params.get(p.name)
        if v is None:
            continue
        if p.grid:
            # below the grid the refinement may go down to the parameter's own lower bound
            # (a Camry's cold start fades in ~25 s, under the 30-s grid start): only there
            # is it at the edge
            low = cand.shape_bounds[0] if cand.shape_bounds else min(p.grid)
            if v >= 0.99 * max(p.grid) or v <= 1.01 * low:
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

    xa = clean(a.column)
    na = np.linalg.norm(xa)
    for c in search.problem.candidates:
        if c.id == a.id or na == 0 or c.block is not None:
            # a block (a road's knots) is no single column: the rival check judges it
            continue
        for x in c.columns[1:-1] if len(c.columns) > 2 else c.columns:
            xc = clean(x)
            nc = np.linalg.norm(xc)
            if nc > 0 and abs(xa @ xc) / (na * nc) > COLLINEAR_COS:
                return c.id
    return None


def _demote(search, a, status: str, reason: str, descriptions: list) -> None:
    entry = search.statuses[a.id]
    entry["status"] = status
    entry["note"] = reason
    descriptions.append({"effect": a.id, "status": status, "parameters": entry.get("parameters", {}),
                         "heldout_rmse_before": round(a.before, 6),
                         "heldout_rmse_after": round(a.after, 6), "reason": reason})


def review(search, findings: list, descriptions: list) -> bool:
    """Judge the accepted physics on its own terms; demoted effects go to ``descriptions``
    and out of ``search.accepted``. True if any was demoted.

    An effect is demoted only if its refitted size is zero, a parameter sits at the edge of
    its plausible range (it describes the mismatch rather than measures it), or another
    physical effect's column is nearly the same (no fit can tell them apart). What the
    physics leaves is judged afterwards (:func:`unexplained`) and never demotes an effect:
    a flexible generic description can always absorb a physical one.
    """
    from fleetrun.effects import EFFECTS

    keep = []
    by_id = {f.effect: f for f in findings}
    for a in search.accepted:
        bound = _at_bound(a.cand, EFFECTS[effect_of(a.id)], by_id[a.id].parameters)
        rival = _collinear_rival(search, a)
        if a.coefficient == 0.0:
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
        else:
            keep.append(a)
    demoted = len(keep) < len(search.accepted)
    search.accepted = keep
    return demoted
