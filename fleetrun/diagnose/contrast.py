"""Two physical effects that explain the same thing, compared where their signatures differ.

The rival check (:func:`fleetrun.diagnose.engine._rival_check`) declares an accepted effect A
and a rival R ambiguous when, on the pooled held-out error, each leaves the other nothing
beyond noise. Pooled errors weigh every row alike, and most rows are where the two columns
are nearly proportional: a grade (fuel ~ m g v) and an extra drag (fuel ~ C v^3) are both
large on the highway, and only the slow driving, where a grade still costs fuel per metre and
a drag almost none, tells them apart (docs/diagnose-realdata.md, 1i). This module asks the
question on those rows: the rows are split by the share ``q = |x_A| / (|x_A| + |x_R|)`` of
the two columns into the half where A's signature dominates and the half where R's does;
each model is fitted on one half and predicts the other (**contrast folds**), and the
difference of their held-out errors ``T = SSE_R - SSE_A`` is judged against what it would be
if R (or A) were the truth: that model's fit plus its own residual, circularly shifted (as
the selection's shift null, :func:`fleetrun.diagnose.select.shift_null`). A parametric
bootstrap of a non-nested comparison (Cox 1962, J. R. Stat. Soc. B 24, 406-424: a test of one
separate family of hypotheses against another uses the statistic's distribution under each).
Opt-in: ``Settings(contrast_rivals=True)`` (docs/diagnose.md, section 5).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fleetrun.diagnose.select import _solve_bounded, full_fit
from fleetrun.fileio import JsonDocument

@dataclass(frozen=True)
class Contrast:
    """What :func:`compare` found: ``winner`` ``"a"`` (the accepted effect), ``"r"`` (the rival)
    or None (still tied); the statistic ``T = SSE_R - SSE_A`` on the contrast folds, its null
    quantile with R true (``T_if_r``) and its 1 - quantile with A true (``T_if_a``); the three
    None when the rows do not split into contrast folds."""

    winner: str | None
    T: float | None = None
    T_if_r: float | None = None
    T_if_a: float | None = None

    def as_json(self, digits: int = 6) -> JsonDocument:
        """The numbers for the rival's status in diagnosis.json (none when the rows do not split)."""
        numbers = {"T": self.T, "T_if_r": self.T_if_r, "T_if_a": self.T_if_a}
        return {k: round(v, digits) for k, v in numbers.items() if v is not None}


#: Fold of a row that is never held out (both columns zero there: it says nothing about which).
ALWAYS_TRAIN = -1


def contrast_folds(x_a, x_r) -> np.ndarray | None:
    """Contrast fold (0, 1) of each row, :data:`ALWAYS_TRAIN` where both columns are zero;
    None if the rows do not split (every active row has the same share q).

    Parameters
    ----------
    x_a, x_r : arrays, the two effects' columns on the selection's rows [target units per unit]
    """
    a, b = np.abs(np.asarray(x_a, float)), np.abs(np.asarray(x_r, float))
    total = a + b
    active = total > 1e-12 * max(float(total.max()), 1e-300)
    if active.sum() < 4:
        return None
    q = a[active] / total[active]
    if np.ptp(q) <= 1e-9:
        return None
    upper = q > np.median(q)
    if upper.all() or not upper.any():
        return None
    folds = np.full(len(a), ALWAYS_TRAIN)
    folds[active] = upper.astype(int)
    return folds


def heldout_sse(Y, terms: list, folds: np.ndarray) -> np.ndarray:
    """Held-out SSE over the two contrast folds of the model ``terms`` (``[(column, lower,
    upper), ...]``, every coefficient within its bounds), for each row of ``Y`` (B, n): (B,)."""
    X = np.array([t[0] for t in terms], dtype=float)
    lo = np.array([t[1] for t in terms], dtype=float)
    hi = np.array([t[2] for t in terms], dtype=float)
    Y = np.atleast_2d(Y)
    sse = np.zeros(len(Y))
    for f in (0, 1):
        train, test = folds != f, folds == f
        G = X[:, train] @ X[:, train].T
        c = Y[:, train] @ X[:, train].T
        b = _solve_bounded(np.broadcast_to(G, (len(Y),) + G.shape), c, lo, hi)
        e = Y[:, test] - b @ X[:, test]
        sse += np.einsum("bn,bn->b", e, e)
    return sse


def _statistic(Y, others: list, term_a: tuple, term_r: tuple, folds) -> np.ndarray:
    """``T = SSE_R - SSE_A`` on the contrast folds for each row of ``Y`` (> 0 favours A)."""
    return heldout_sse(Y, others + [term_r], folds) - heldout_sse(Y, others + [term_a], folds)


#: Whose residual the null's shifted noise is (``compare(..., noise=...)``): ``"own"`` each
#: hypothesis's own residual (design C, docs/diagnose-realdata.md 1i); ``"both"`` the residual
#: of the model with both effects in (design C2, 1i), the same noise under either hypothesis.
NOISE = ("own", "both")


def _residual(r, terms: list) -> tuple[np.ndarray, np.ndarray]:
    """The fit of ``terms`` (each coefficient within its bounds) and what it leaves of ``r``."""
    cols = np.array([t[0] for t in terms], dtype=float)
    fit = full_fit(r, list(cols), [(t[1], t[2]) for t in terms]) @ cols
    return fit, r - fit


def _pseudo(r, others: list, term: tuple, shifts, noise=None) -> np.ndarray:
    """Residuals as if ``term`` were the truth: its fit (with ``others``) plus ``noise`` (None:
    its own residual) circularly shifted by each of ``shifts``: (B, n)."""
    fit, e = _residual(r, others + [term])
    e = e if noise is None else noise
    return fit[None, :] + np.stack([np.roll(e, int(k)) for k in shifts])


def compare(r, others: list, term_a: tuple, term_r: tuple, shifts, quantile: float,
            noise: str = "own") -> Contrast:
    """Which of two effects the rows where their signatures differ favour.

    Parameters
    ----------
    r : array, the residual on the selection's rows
    others : list, the model's other terms ``[(column, lower, upper), ...]`` (calibration terms
        and the other findings)
    term_a, term_r : tuple, the accepted effect's and the rival's ``(column, lower, upper)``
    shifts : array of int, circular shifts of the null (the selection's)
    quantile : float, the null's quantile a winner must pass (the selection's, 0.99)
    noise : str, :data:`NOISE`: the null's noise is each hypothesis's own residual, or the
        residual of the model with both effects (what neither describes)

    Returns
    -------
    Contrast: the winner ``"a"``, ``"r"`` or None (neither passes: still ambiguous), T, the
    quantile of T with R true and the 1 - quantile of T with A true.
    """
    if noise not in NOISE:
        raise ValueError(f"noise must be one of {NOISE}, got {noise!r}")
    folds = contrast_folds(term_a[0], term_r[0])
    if folds is None:
        return Contrast(None)
    e = None if noise == "own" else _residual(r, others + [term_a, term_r])[1]
    t = float(_statistic(r, others, term_a, term_r, folds)[0])
    if_r = float(np.quantile(_statistic(_pseudo(r, others, term_r, shifts, e), others, term_a, term_r, folds),
                             quantile))
    if_a = float(np.quantile(_statistic(_pseudo(r, others, term_a, shifts, e), others, term_a, term_r, folds),
                             1.0 - quantile))
    winner = "a" if t > if_r and t >= if_a else "r" if t < if_a and t <= if_r else None
    return Contrast(winner, t, if_r, if_a)
