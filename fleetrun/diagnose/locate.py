"""Where the residual lives: segments in time and the operating channels it follows.

Both are judged against the same circular-shift null as the selection, so autocorrelated
sensor noise (which makes any short stretch of residual look like a pattern) does not
produce segments or drivers by itself.
"""
from __future__ import annotations

import numpy as np

from fleetrun.diagnose.records import DriverLink, Segment
from fleetrun.diagnose.select import _circ_corr


def smooth(x: np.ndarray, window: int) -> np.ndarray:
    """Centred moving average (window in samples, at least 1)."""
    window = max(1, int(window))
    if window == 1:
        return np.asarray(x, dtype=float)
    k = np.ones(window) / window
    pad = window // 2
    xp = np.pad(np.asarray(x, dtype=float), (pad, window - 1 - pad), mode="edge")
    return np.convolve(xp, k, mode="valid")


def segments(time_s: np.ndarray, r: np.ndarray, *, n_blocks: int = 60, share_target: float = 0.6,
             noise: np.ndarray | None = None, smooth_s: float | None = None,
             max_segments: int = 6) -> list[Segment]:
    """Contiguous time spans that hold most of the residual's systematic energy.

    The residual is first averaged over ``smooth_s`` (default: 1 % of the recording, at least
    10 s) so that sensor noise, fast or autocorrelated, averages out and what remains is the
    systematic part. The recording is cut into ``n_blocks`` equal blocks; a block's energy is
    its mean squared smoothed residual minus the noise floor (the same quantity for
    ``noise``, the residual left after the accepted effects, or the median block when no
    effect was accepted). Blocks are taken largest first until ``share_target`` of the
    excess energy is covered; neighbours merge. ``share`` is each segment's part of the total
    excess energy.
    """
    n = len(r)
    duration = float(time_s[-1] - time_s[0]) or 1.0
    smooth_s = smooth_s or max(10.0, 0.01 * duration)
    win = max(1, int(round(smooth_s * n / duration)))
    rs = smooth(r, win)
    edges = np.linspace(0, n, n_blocks + 1).astype(int)
    e = np.array([np.mean(rs[a:b] ** 2) if b > a else 0.0 for a, b in zip(edges[:-1], edges[1:])])
    if noise is not None:
        floor = float(np.mean(smooth(noise, win) ** 2))
    else:
        floor = float(np.median(e))
    excess = np.maximum(e - floor, 0.0) * np.diff(edges)
    total = excess.sum()
    if total <= 0:
        return []
    order = np.argsort(excess)[::-1]
    chosen = np.zeros(n_blocks, bool)
    acc = 0.0
    for i in order:
        if acc >= share_target * total or excess[i] <= 0:
            break
        chosen[i] = True
        acc += excess[i]
    segs = []
    i = 0
    while i < n_blocks:
        if chosen[i]:
            j = i
            while j + 1 < n_blocks and chosen[j + 1]:
                j += 1
            a, b = edges[i], edges[j + 1] - 1
            segs.append(Segment(start_s=float(time_s[a]), end_s=float(time_s[b]),
                                share=float(excess[i:j + 1].sum() / total)))
            i = j + 1
        else:
            i += 1
    segs.sort(key=lambda s: -s.share)
    return segs[:max_segments]


def _eta2(r: np.ndarray, bins: np.ndarray, nb: int) -> float:
    """Correlation ratio: share of the residual variance explained by the bin means."""
    cnt = np.bincount(bins, minlength=nb)
    s = np.bincount(bins, weights=r, minlength=nb)
    ok = cnt > 0
    mean = r.mean()
    between = np.sum(cnt[ok] * (s[ok] / cnt[ok] - mean) ** 2)
    total = np.sum((r - mean) ** 2)
    return float(between / total) if total > 0 else 0.0


def _eta2_shifted(r: np.ndarray, bins: np.ndarray, nb: int, shifts: np.ndarray) -> np.ndarray:
    """:func:`_eta2` of ``np.roll(r, s)`` for every ``s`` in ``shifts``, from FFTs.

    The bin sums of the shifted residual are circular cross-correlations of each bin's
    indicator with ``r``; the mean and the total variance do not change with the shift.
    """
    n = len(r)
    cnt = np.bincount(bins, minlength=nb)
    mean = r.mean()
    total = np.sum((r - mean) ** 2)
    if total <= 0:
        return np.zeros(len(shifts))
    r_fft = np.fft.rfft(r)
    between = np.zeros(len(shifts))
    for i in np.flatnonzero(cnt > 0):
        sums = _circ_corr(np.fft.rfft((bins == i).astype(float)), r_fft, n)[shifts]
        between += cnt[i] * (sums / cnt[i] - mean) ** 2
    return between / total


def bins(x: np.ndarray, nb: int, resolution: float = 0.02) -> tuple[np.ndarray, int]:
    """Quantile bins, merged where two edges are closer than ``resolution`` of the range.

    Without the merge, a channel that sits at one value for a long time (a torque floor, a
    standstill) is split into bins by its own sensor noise; the baseline uses the same noisy
    channel, so its noise shows up in the residual and the bins would "explain" it
    (errors in variables). Bins wider than the noise cannot.
    """
    lo, hi = np.quantile(x, [0.01, 0.99])
    if hi <= lo:
        lo, hi = float(np.min(x)), float(np.max(x))
    step = resolution * max(hi - lo, 1e-12)
    at_min = x <= np.min(x) + step
    if at_min.mean() > 0.3 and (~at_min).sum() > nb:
        # a point mass at the minimum (straight driving: no wheel-speed difference; standstill):
        # its own bin, quantile bins for the rest
        q = np.r_[np.min(x) + step, np.quantile(x[~at_min], np.linspace(0, 1, nb)[1:-1])]
    else:
        q = np.quantile(x, np.linspace(0, 1, nb + 1)[1:-1])
    edges = []
    for e in q:
        if not edges or e - edges[-1] >= step:
            edges.append(e)
    edges = np.array(edges)
    return np.searchsorted(edges, x, side="right"), len(edges) + 1


def drivers(channels: dict[str, np.ndarray], r: np.ndarray, *, n_bins: int = 12,
            n_shifts: int = 200, quantile: float = 0.99, rng=None,
            smooth_window: int = 1, null_residual: np.ndarray | None = None) -> tuple[list[DriverLink], bool]:
    """How strongly the residual follows each channel, and whether any does beyond noise.

    Strength is the correlation ratio (eta^2) of the (lightly smoothed) residual over quantile
    bins of the channel: it catches non-monotonic links (e.g. only at low speed). Each
    channel's strength is compared with the largest strength any channel reaches on
    circularly shifted residuals; ``significant`` is true if one beats that null's quantile.
    ``null_residual`` (default ``r``) is what gets shifted: the residual left after the
    accepted effects is the better noise estimate, since shifting a residual that still holds
    a slow effect keeps its structure and inflates the null.
    """
    rng = rng or np.random.default_rng(1)
    rs = smooth(r, smooth_window)
    n = len(r)
    usable = {}
    for name, x in channels.items():
        x = np.asarray(x, dtype=float)
        if x.shape != r.shape or np.ptp(x) <= 1e-12 * max(1.0, np.abs(x).max()):
            continue
        usable[name] = bins(x, n_bins)
    if not usable:
        return [], False
    shifts = rng.integers(max(1, n // 20), max(2, n - n // 20), n_shifts)
    rn = rs if null_residual is None else smooth(null_residual, smooth_window)
    null_max = np.max([_eta2_shifted(rn, b, nb, shifts) for b, nb in usable.values()], axis=0)
    thr = float(np.quantile(null_max, quantile))
    out = []
    for name, (b, nb) in usable.items():
        st = _eta2(rs, b, nb)
        out.append(DriverLink(channel=name, strength=round(st, 4), significant=bool(st > thr),
                              null_threshold=round(thr, 4)))
    out.sort(key=lambda d: -d.strength)
    return out, any(d.significant for d in out)


def binned_profile(x: np.ndarray, r: np.ndarray, n_bins: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """Bin centres (median of x) and mean residual per quantile bin, for plots."""
    b, nb = bins(np.asarray(x, float), n_bins)
    cnt = np.bincount(b, minlength=nb)
    ok = cnt > 0
    xm = np.array([np.median(x[b == i]) for i in range(nb) if cnt[i] > 0])
    rm = (np.bincount(b, weights=r, minlength=nb)[ok] / cnt[ok])
    return xm, rm
