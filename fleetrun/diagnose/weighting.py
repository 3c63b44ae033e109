"""Windows weighted by their noise: where a same-trace residual says most.

A same-trace residual (a recording minus a repeat of the same speed trace,
:func:`fleetrun.diagnose.vehicle.same_trace`) is noisier where the fuel flow is high: two
drives place each transient a second or two apart, and the fuel meter's own noise grows with
the flow. Measured on the Argonne Camry pair (docs/diagnose-realdata.md, 1b): 0.024 g/s per
10-s window at idle, about 0.09 g/s while driving. Ordinary least squares gives every window
the same say; weighting each by the inverse of its noise variance (generalised least squares
with a diagonal covariance) lets the quiet windows say what they can: an accessory load, for
example, adds fuel at idle, where a grade and a drag add none (docs/diagnose-realdata.md, 1d).

The weighted problem is the same problem with every row (target, baseline, each candidate's
columns, the calibration terms) multiplied by the square root of its weight: the selection's
least-squares fits, held-out errors and shift null then run on weighted rows unchanged. The
weights are estimated from the recording's own residual, by level of the reference's fuel,
robustly (a median absolute deviation per level bin), so a slow effect in the residual moves
them little.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from fleetrun.diagnose.engine import Problem
from fleetrun.diagnose.select import Candidate

#: Level bins (quantiles of the reference's fuel) in which the noise scale is estimated.
NOISE_BINS = 5
#: No bin's noise scale is taken below this share of the largest bin's: a nearly constant
#: stretch (an idle held by the engine's controller) must not take all the weight.
MIN_SCALE_SHARE = 0.1
#: Normal-consistency factor of the median absolute deviation (Gaussian noise: MAD x 1.4826 = sigma).
MAD_TO_SIGMA = 1.4826


def noise_weights(residual, level, active, bins: int = NOISE_BINS) -> np.ndarray:
    """Inverse noise variance of each sample (mean 1 over ``active``; 1 elsewhere).

    Parameters
    ----------
    residual : array
        Measured minus baseline, per sample [target units].
    level : array
        What the noise grows with, per sample (the reference's fuel rate [g/s]).
    active : bool array
        Samples that carry information (the engine runs); the others get weight 1.
    bins : int
        Quantile bins of ``level`` over ``active`` in which the noise scale (1.4826 x median
        absolute deviation of ``residual``) is estimated; between the bins' median levels the
        scale is interpolated linearly, beyond them held.

    Returns
    -------
    array
        Weights >= 0, mean 1 over ``active``.
    """
    residual, level, active = (np.asarray(residual, float), np.asarray(level, float),
                               np.asarray(active, bool))
    if active.sum() < 2 * bins:
        return np.ones(len(residual))
    lv, rr = level[active], residual[active]
    edges = np.quantile(lv, np.linspace(0.0, 1.0, bins + 1))
    idx = np.clip(np.searchsorted(edges, lv, side="right") - 1, 0, bins - 1)
    used = [k for k in range(bins) if np.any(idx == k)]
    centre = np.array([float(np.median(lv[idx == k])) for k in used])
    scale = np.array([MAD_TO_SIGMA * float(np.median(np.abs(rr[idx == k] - np.median(rr[idx == k]))))
                      for k in used])
    top = float(scale.max())
    if top <= 0:
        return np.ones(len(residual))
    scale = np.maximum(scale, MIN_SCALE_SHARE * top)
    order = np.argsort(centre)
    w = np.where(active, 1.0 / np.interp(level, centre[order], scale[order]) ** 2, 0.0)
    return np.where(active, w / w[active].mean(), 1.0)


def reweighted(problem: Problem, weights) -> Problem:
    """``problem`` with every row multiplied by ``sqrt(weights)``: target, baseline, each
    candidate's columns (and its ``column_for``), its surrogates and the calibration terms.

    Least squares on the result is weighted least squares on ``problem``; coefficients keep
    their meaning (and bounds). The driver channels and the integral specification are left
    as they are: they describe the recording, not the fit."""
    sw = np.sqrt(np.asarray(weights, float))

    def cand(c: Candidate) -> Candidate:
        column_for = None if c.column_for is None else (lambda sh, f=c.column_for: sw * f(sh))
        return Candidate(c.id, [sw * x for x in c.columns], c.shapes, c.lower, c.upper,
                         column_for=column_for, shape_bounds=c.shape_bounds)

    return replace(problem, measured=sw * problem.measured, baseline=sw * problem.baseline,
                   candidates=[cand(c) for c in problem.candidates],
                   surrogates={k: cand(c) for k, c in problem.surrogates.items()},
                   initial_terms=[(sw * c, lo, hi) for c, lo, hi in problem.initial_terms], coarse=None)


def noise_weighted(problem: Problem) -> Problem:
    """``problem`` reweighted by :func:`noise_weights` of its own residual, with the baseline
    (the reference's fuel on a same-trace residual) as the level and the samples where either
    the baseline or the measurement is non-zero (the engine runs) as active."""
    active = (np.abs(problem.baseline) > 0) | (np.abs(problem.measured) > 0)
    return reweighted(problem, noise_weights(problem.residual, problem.baseline, active))
