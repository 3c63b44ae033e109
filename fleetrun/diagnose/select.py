"""Which candidate physics the residual asks for: blocked cross-validation and a shift null.

The residual ``r = measured - baseline`` is fitted by each candidate as ``r ~ N b_N + x b``:
``N`` are columns already in the model (accepted effects), ``x`` the candidate's effect on
the target per unit of its linear parameter (one column per value of its shape parameter).

* **Held-out error** is blocked cross-validation in time: the recording is cut into ``K``
  contiguous folds; each fold is predicted from a fit on the others. Contiguous folds keep
  the autocorrelated noise of a fold out of its own fit.
* **Significance**: the residual is circularly shifted against the channels (the shift
  keeps its autocorrelation and its distribution but breaks any link to the physics) and
  every candidate is refitted; the largest gain over all candidates and shape values is
  recorded. A candidate is accepted only if its gain beats the ``quantile`` of that maximum.
  All fold statistics for every shift come from FFT cross-correlations, so 200 shifts cost
  little more than one fit.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np


#: Separates an effect id from the recording it is fitted to in a candidate id
#: (``warmup@run2``: an effect with its own parameters per recording, :mod:`.joint`).
PER_RECORDING_SEP = "@"


def effect_of(candidate_id: str) -> str:
    """The catalogue effect id of a candidate id (``warmup@run2`` -> ``warmup``)."""
    return candidate_id.split(PER_RECORDING_SEP, 1)[0]


@dataclass
class Candidate:
    """One effect as the selection sees it."""

    id: str
    columns: list[np.ndarray]            # one column per shape value (len 1: no shape)
    shapes: list[dict[str, float]]       # the shape parameters of each column: name -> value
    lower: float
    upper: float
    column_for: Callable[[dict], np.ndarray] | None = None  # column for any shape (refinement)
    shape_bounds: tuple[float, float] | None = None  # where refinement may go past the grid
    status: str = "pending"
    note: str = ""
    #: several columns fitted together, (p, n): a description with p linear parameters (a
    #: road's grade at its knots, :mod:`fleetrun.diagnose.route`), each kept within
    #: [lower, upper] and penalised towards zero by ``penalty`` times the mean diagonal of the
    #: block's Gram matrix (ridge). ``columns`` is then the block's sum (a proxy only) and
    #: ``column_for`` the block's combination at the weights ``{"w0": ..., ...}``.
    block: np.ndarray | None = None
    penalty: float = 0.0
    #: a block's post-selection refit (:func:`relaxed_block`): once the block is a finding, its
    #: weights are refitted with ``penalty`` times each of these factors and the one with the
    #: least held-out error is kept (empty: sized at its selection penalty)
    relax: tuple[float, ...] = ()


@dataclass
class CVResult:
    rmse_before: float
    rmse_after: float
    gain: float                          # 1 - after / before
    shape_index: int
    coefficient: float                   # fitted on all data
    #: a block candidate's weights fitted on all data (None otherwise)
    weights: np.ndarray | None = None


def fold_ids(n: int, k: int, blocks_per_fold: int = 1) -> np.ndarray:
    """Fold of each sample: ``k * blocks_per_fold`` contiguous blocks dealt to the folds in turn.

    Blocks (not samples) are held out, so autocorrelated noise in a held-out block is not in
    the fit that predicts it (blocks are much longer than the noise's correlation time). With
    more than one block per fold, an effect confined to part of the recording (a warm-up in
    the first minutes) still has data in every training set.
    """
    nb = k * blocks_per_fold
    return np.minimum((np.arange(n) * nb) // n, nb - 1) % k


def _solve_bounded(G, c, lo, hi, ridge: float = 1e-12):
    """Least squares from normal equations with every coefficient kept in [lo, hi].

    ``G`` (..., p, p), ``c`` (..., p), ``lo``/``hi`` (p,). Greedy active set, vectorised over
    the leading axes: solve, fix the coefficients that left their bounds at the bound, re-solve
    the rest; at most p passes. Exact for one bounded coefficient; for several it never
    releases a bound again, which is fine for the 1-4 columns used here. ``ridge``: the
    Tikhonov term relative to the mean diagonal of ``G`` (1e-12: only against singularity).
    """
    p = G.shape[-1]
    lo = np.broadcast_to(np.asarray(lo, dtype=float), (p,))
    hi = np.broadcast_to(np.asarray(hi, dtype=float), (p,))
    eye = np.eye(p)
    scale = np.trace(G, axis1=-2, axis2=-1)[..., None, None] / p
    ridge = (ridge * scale + 1e-300) * eye
    fixed = np.zeros(c.shape, bool)
    val = np.zeros(c.shape)
    b = None
    for _ in range(p + 1):
        A = np.where(fixed[..., None, :], 0.0, G)
        A = np.where(fixed[..., :, None], eye, A)
        rhs = c - np.einsum("...ij,...j->...i", np.where(fixed[..., None, :], G, 0.0), val)
        rhs = np.where(fixed, val, rhs)
        b = np.linalg.solve(A + np.where(fixed[..., :, None], 0.0, ridge), rhs[..., None])[..., 0]
        viol = ~fixed & ((b < lo) | (b > hi))
        if not viol.any():
            break
        val = np.where(viol, np.clip(b, lo, hi), val)
        fixed = fixed | viol
    return np.where(fixed, val, b)


def _penalised(G, start, penalty: float):
    """``G`` (..., p, p) with ``penalty`` times the mean diagonal of its block ``start:`` added
    to that block's diagonal (a ridge on a block candidate's weights)."""
    if not penalty:
        return G
    idx = np.arange(start, G.shape[-1])
    d = G[..., idx, idx]
    G = np.array(G, dtype=float, copy=True)
    G[..., idx, idx] = d + penalty * d.mean(axis=-1, keepdims=True)
    return G


def _heldout_sse(G_f, c_f, rr_f, lo, hi, ridge: float = 1e-12, penalty: float = 0.0, start: int = 0):
    """Sum over folds of the held-out SSE; stats per fold on the last-but-one axes.

    ``G_f`` (..., K, p, p), ``c_f`` (..., K, p), ``rr_f`` (..., K); bounds (p,); ``ridge`` as
    in :func:`_solve_bounded`; ``penalty`` on the columns ``start:`` as in :func:`_penalised`.
    """
    if G_f.shape[-1] == 0:
        return rr_f.sum(axis=-1)
    G_tr = _penalised(G_f.sum(axis=-3, keepdims=True) - G_f, start, penalty)
    c_tr = c_f.sum(axis=-2, keepdims=True) - c_f
    b = _solve_bounded(G_tr, c_tr, lo, hi, ridge)
    sse = rr_f - 2 * np.einsum("...p,...p->...", b, c_f) + np.einsum("...p,...pq,...q->...", b, G_f, b)
    return sse.sum(axis=-1)


def _fold_gram(cols: np.ndarray, folds: np.ndarray, k: int) -> np.ndarray:
    """(K, p, p) Gram matrices of the columns ``cols`` (p, n) per fold."""
    p = cols.shape[0]
    out = np.zeros((k, p, p))
    for f in range(k):
        m = folds == f
        out[f] = cols[:, m] @ cols[:, m].T
    return out


def _split(nuisance):
    """Columns and bounds of the model terms ``[(column, lower, upper), ...]``."""
    cols = [t[0] for t in nuisance]
    lo = np.array([t[1] for t in nuisance], dtype=float)
    hi = np.array([t[2] for t in nuisance], dtype=float)
    return cols, lo, hi


def cv_fit(r, nuisance: list[tuple], x: np.ndarray, lo: float, hi: float, folds, k, penalty: float = 0.0):
    """Held-out SSE with and without ``x`` (the ``nuisance`` terms always in), and the full fit.

    ``nuisance``: the terms already in the model, ``[(column, lower, upper), ...]``. ``x``: one
    column (n,) or a block candidate's columns (p, n), each coefficient within [``lo``, ``hi``]
    and penalised by ``penalty`` (:func:`_penalised`; 0: none).
    """
    ncols, nlo, nhi = _split(nuisance)
    added = np.atleast_2d(x)
    q, p = len(ncols), added.shape[0]
    cols = np.vstack([np.array(ncols, dtype=float).reshape(q, len(r)), added])
    los, his = np.r_[nlo, np.full(p, lo)], np.r_[nhi, np.full(p, hi)]
    G_f = _fold_gram(cols, folds, k)
    c_f = np.array([cols[:, folds == f] @ r[folds == f] for f in range(k)])
    rr_f = np.array([r[folds == f] @ r[folds == f] for f in range(k)])
    sse_after = _heldout_sse(G_f, c_f, rr_f, los, his, penalty=penalty, start=q)
    sse_before = _heldout_sse(G_f[:, :q, :q], c_f[:, :q], rr_f, nlo, nhi) if q else rr_f.sum()
    b = _solve_bounded(_penalised(G_f.sum(0), q, penalty), c_f.sum(0), los, his)
    return float(sse_before), float(sse_after), b


def relaxed_block(r, nuisance: list[tuple], cand: Candidate, folds, k) -> tuple[np.ndarray, float]:
    """A block candidate's weights refitted after its selection (a relaxed ridge).

    The ridge that keeps a block's many weights from fitting noise while it is *selected*
    also shrinks them once it is chosen. Refitted on the same support with ``cand.penalty``
    times each factor of ``cand.relax`` (1 = the selection's penalty, 0 = none), the ``nuisance``
    terms in the model, the factor with the least blocked-CV held-out SSE on ``folds`` is kept
    (the first on a tie); the truth is never consulted. The relaxed lasso's two-stage idea
    (Meinshausen 2007, Comput. Stat. Data Anal. 52, 374-393) with a ridge in place of the
    lasso. Returns the full-data weights at that factor and the factor. docs/diagnose.md, 7b;
    docs/diagnose-realdata.md, 1g.
    """
    best = None
    for factor in cand.relax or (1.0,):
        _, after, b = cv_fit(r, nuisance, cand.block, cand.lower, cand.upper, folds, k, cand.penalty * factor)
        if best is None or after < best[0]:
            best = (after, b[len(nuisance):], float(factor))
    return best[1], best[2]


def _circ_corr(a_fft, r_fft, n):
    """``sum_t a_t r_{t-s}`` for every shift s (circular), from precomputed FFTs."""
    return np.fft.irfft(a_fft * np.conj(r_fft), n)


@dataclass
class NullDistribution:
    shifts: np.ndarray
    max_gain: np.ndarray           # (B,) largest relative gain over all candidates/shapes per shift
    max_dsse: np.ndarray           # (B,) largest held-out SSE reduction per shift
    gains: dict[str, np.ndarray] = field(default_factory=dict)   # id -> (B,) best gain of that candidate

    def threshold(self, quantile: float) -> float:
        return float(np.quantile(self.max_gain, quantile))

    def dsse_threshold(self, quantile: float) -> float:
        return float(np.quantile(self.max_dsse, quantile))


def shift_null(r, nuisance: list[tuple], candidates: list[Candidate], folds, k, *,
               n_shifts=200, rng=None, min_shift_frac=0.05) -> NullDistribution:
    """Gains every candidate reaches on circularly shifted residuals (the noise-only null)."""
    rng = rng or np.random.default_rng(0)
    n = len(r)
    lo_s = max(1, int(min_shift_frac * n))
    shifts = rng.integers(lo_s, n - lo_s, n_shifts)
    r_fft = np.fft.rfft(r)
    r2_fft = np.fft.rfft(r * r)
    masks = [(folds == f).astype(float) for f in range(k)]
    rr = np.stack([_circ_corr(np.fft.rfft(m), r2_fft, n)[shifts] for m in masks], axis=-1)  # (B,K)
    ncols, nlo, nhi = _split(nuisance)
    nq = len(ncols)
    if nq:
        N = np.array(ncols)
        GN = _fold_gram(N, folds, k)                                              # (K,q,q)
        cN = np.stack([np.stack([_circ_corr(np.fft.rfft(N[i] * masks[f]), r_fft, n)[shifts]
                                 for i in range(nq)], -1) for f in range(k)], 1)  # (B,K,q)
        sse_before = _heldout_sse(np.broadcast_to(GN, (len(shifts),) + GN.shape), cN, rr, nlo, nhi)
    else:
        sse_before = rr.sum(-1)
    max_gain = np.full(len(shifts), -np.inf)
    max_dsse = np.full(len(shifts), -np.inf)
    gains = {}
    for cand in candidates:
        best = np.full(len(shifts), -np.inf)
        if cand.block is not None:
            g = _block_null_gain(cand, N if nq else np.zeros((0, n)), cN if nq else None, r_fft, masks,
                                 shifts, rr, sse_before, (nlo, nhi), folds, k)
            best, dsse = g
            max_dsse = np.maximum(max_dsse, dsse)
            gains[cand.id] = best
            max_gain = np.maximum(max_gain, best)
            continue
        for x in cand.columns:
            cx = np.stack([_circ_corr(np.fft.rfft(x * m), r_fft, n)[shifts] for m in masks], -1)  # (B,K)
            if nq:
                cols = np.vstack([N, x[None]])
                G_f = _fold_gram(cols, folds, k)
                c_f = np.concatenate([cN, cx[..., None]], -1)
                G_b = np.broadcast_to(G_f, (len(shifts),) + G_f.shape)
            else:
                xx = np.array([x[folds == f] @ x[folds == f] for f in range(k)])
                G_b = np.broadcast_to(xx[:, None, None], (len(shifts), k, 1, 1))
                c_f = cx[..., None]
            sse_after = _heldout_sse(G_b, c_f, rr, np.r_[nlo, cand.lower], np.r_[nhi, cand.upper])
            g = 1 - np.sqrt(np.maximum(sse_after, 0) / np.maximum(sse_before, 1e-300))
            best = np.maximum(best, g)
            max_dsse = np.maximum(max_dsse, sse_before - sse_after)
        gains[cand.id] = best
        max_gain = np.maximum(max_gain, best)
    return NullDistribution(shifts, max_gain, max_dsse, gains)


def block_shape(cand: Candidate, weights) -> tuple[dict[str, float], np.ndarray, float]:
    """A block candidate at fitted ``weights`` as one column: the weights scaled to a largest
    magnitude of 1 (the shape ``{"w0": ..., ...}``), its column, and the scale (the linear
    parameter)."""
    w = np.asarray(weights, dtype=float)
    scale = float(np.max(np.abs(w))) if w.size else 0.0
    u = w / scale if scale > 0 else w
    shape = {f"w{i}": float(x) for i, x in enumerate(u)}
    return shape, cand.column_for(shape), scale


def chosen(cand: Candidate, ev: CVResult) -> tuple[dict[str, float], np.ndarray]:
    """The shape and column of ``cand`` its evaluation ``ev`` chose."""
    if cand.block is not None:
        shape, col, _ = block_shape(cand, ev.weights)
        return shape, col
    return dict(cand.shapes[ev.shape_index]), cand.columns[ev.shape_index]


def _block_null_gain(cand, N, cN, r_fft, masks, shifts, rr, sse_before, bounds, folds, k):
    """Gain and held-out SSE reduction of a block candidate on every shifted residual."""
    n = len(masks[0])
    q, p = N.shape[0], cand.block.shape[0]
    cx = np.stack([np.stack([_circ_corr(np.fft.rfft(x * m), r_fft, n)[shifts] for m in masks], -1)
                   for x in cand.block], -1)                                          # (B,K,p)
    c_f = np.concatenate([cN, cx], -1) if q else cx
    G_f = _fold_gram(np.vstack([N, cand.block]), folds, k)
    G_b = np.broadcast_to(G_f, (len(shifts),) + G_f.shape)
    lo, hi = np.r_[bounds[0], np.full(p, cand.lower)], np.r_[bounds[1], np.full(p, cand.upper)]
    sse_after = _heldout_sse(G_b, c_f, rr, lo, hi, penalty=cand.penalty, start=q)
    g = 1 - np.sqrt(np.maximum(sse_after, 0) / np.maximum(sse_before, 1e-300))
    return g, sse_before - sse_after


def evaluate_candidate(r, nuisance, cand: Candidate, folds, k) -> CVResult:
    """Best shape value by held-out error; coefficient refitted on all data."""
    if cand.block is not None:
        before, after, b = cv_fit(r, nuisance, cand.block, cand.lower, cand.upper, folds, k, cand.penalty)
        n = len(r)
        rb, ra = np.sqrt(before / n), np.sqrt(max(after, 0.0) / n)
        w = b[len(nuisance):]
        return CVResult(rb, ra, 1 - ra / rb if rb > 0 else 0.0, 0, block_shape(cand, w)[2], w)
    best = None
    for i, x in enumerate(cand.columns):
        before, after, b = cv_fit(r, nuisance, x, cand.lower, cand.upper, folds, k)
        if best is None or after < best[1]:
            best = (before, after, b, i)
    before, after, b, i = best
    n = len(r)
    rb, ra = np.sqrt(before / n), np.sqrt(max(after, 0.0) / n)
    return CVResult(rb, ra, 1 - ra / rb if rb > 0 else 0.0, i, float(b[-1]))


def refine_shape(r, nuisance, cand: Candidate, index: int, name: str) -> tuple[float, np.ndarray]:
    """Refine a profiled shape parameter between its grid neighbours (full-data SSE, log scale).

    The grid step (~30 %) would otherwise limit how well the parameter is recovered.
    """
    from scipy.optimize import minimize_scalar

    grid = [s[name] for s in cand.shapes]
    # between the grid neighbours; at an end of the grid, one grid step beyond it (within
    # the shape parameter's bounds), so a value just past the last grid point is reachable
    step = grid[1] / grid[0] if len(grid) > 1 else 1.0
    b_lo, b_hi = cand.shape_bounds or (grid[0], grid[-1])
    lo = grid[index - 1] if index > 0 else max(b_lo, grid[0] / step)
    hi = grid[index + 1] if index < len(grid) - 1 else min(b_hi, grid[-1] * step)

    ncols, nlo, nhi = _split(nuisance)

    def sse(logv):
        x = cand.column_for({name: float(np.exp(logv))})
        cols = np.array(ncols + [x])
        b = _solve_bounded(cols @ cols.T, cols @ r, np.r_[nlo, cand.lower], np.r_[nhi, cand.upper])
        e = r - b @ cols
        return float(e @ e)

    if hi <= lo:
        return float(grid[index]), cand.columns[index]
    res = minimize_scalar(sse, bounds=(np.log(lo), np.log(hi)), method="bounded",
                          options={"xatol": 1e-3})
    v = float(np.exp(res.x))
    return v, cand.column_for({name: v})


def full_fit(r, cols: list[np.ndarray], bounds: list[tuple[float, float]]) -> np.ndarray:
    """Least squares of ``r`` on ``cols`` with every coefficient kept within its bounds."""
    from scipy.optimize import lsq_linear

    A = np.array(cols).T
    lo = [b[0] for b in bounds]
    hi = [b[1] for b in bounds]
    return lsq_linear(A, r, bounds=(lo, hi), method="bvls").x
