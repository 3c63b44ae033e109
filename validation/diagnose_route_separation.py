"""Could a road's grade profile be told apart with a many-parameter description? A measurement.

    python validation/diagnose_route_separation.py

Not a diagnosis: measured after design R (docs/diagnose-realdata.md, 1e) had been run. On the
windows design Wh selects on (the three warm Camry targets against their same-trace
references, noise-weighted 10-s windows), each concealment of 1b-1e is added to the clean
targets' residual and described by blocked cross-validation (the selection's folds: 5 folds of
contiguous ~120-s blocks) with each target's calibration terms always in the model, plus

* one catalogue effect (``road_grade`` constant, ``aero_drag``, ``accessory_load``), or
* the concealed signal's own shape with one coefficient (``known form``: the most any
  description of this concealment could reach), or
* a **road** shared by the three targets: the grade as a piecewise-linear function of the
  distance travelled since each target's start, knots every ``KNOT_M`` metres (one value per
  knot, the same road under every target: the physics of design R's concealment), each knot's
  column the catalogue's grade basis times its hat function.

The road is also fitted with a penalty towards a level road (``RIDGES``). Printed per case:
held-out RMSE gain of each description over the calibration terms alone (and of the
road, ridge 1, over the calibration terms and the drag),
and for the road the fuel it moves (sum of absolute fitted grade fuel) against the concealed.
The clean targets' row is what each description finds in the runs' own difference.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from validation.diagnose_concealed import SIZES, concealed_fuel  # noqa: E402
from validation.diagnose_concealed_joint import DESIGNS, ROUTE_SIZES, _data, _write  # noqa: E402

from fleetrun.diagnose import build  # noqa: E402
from fleetrun.diagnose.engine import Settings, _window_mean  # noqa: E402
from fleetrun.diagnose.select import fold_ids  # noqa: E402
from fleetrun.diagnose.weighting import noise_weights  # noqa: E402

KNOT_M = 1000.0
#: Penalties towards a level road on the knots' grades (relative to their columns' mean
#: squared norm), measured beside the plain fit.
RIDGES = (0.1, 1.0)
DESIGN = "Wh"


def _setup():
    wd = Path(tempfile.mkdtemp())
    pairs = [(_data(t), _data(r)) for t, r in DESIGNS[DESIGN]]
    refs = [_write(rd, rm, wd / f"ref_{rn}.csv") for _, (rn, rd, rm, _) in pairs]
    paths = [_write(td, tm, wd / f"{tn}.csv") for (tn, td, tm, _), _ in pairs]
    probs = [build(p, None, r, "thesis", "auto") for p, r in zip(paths, refs)]
    return pairs, probs


def _coarse(probs):
    """Window each recording's sample-wise column and weight it by its noise (Wh's rows)."""
    sws = []
    for p in probs:
        c = p.coarse
        active = (np.abs(c.baseline) > 0) | (np.abs(c.measured) > 0)
        sws.append(np.sqrt(noise_weights(c.residual, c.baseline, active)))
    w = max(1, int(round(len(probs[0].time_s) / len(probs[0].coarse.time_s))))
    return lambda cols: np.concatenate([_window_mean(x, w) * sw for x, sw in zip(cols, sws)])


def _columns(probs):
    """Per-recording sample-wise columns: calibration terms (each recording's own), the three
    catalogue effects, the road's knots (shared)."""
    n = [len(p.time_s) for p in probs]
    pad = lambda k, x: [x if j == k else np.zeros(n[j]) for j in range(len(probs))]  # noqa: E731
    calib = [pad(k, col) for k, p in enumerate(probs) for col, _, _ in p.initial_terms]
    cat = {cid: [next(c for c in p.candidates if c.id == cid).columns[0] for p in probs]
           for cid in ("road_grade", "aero_drag", "accessory_load")}
    dist = []
    for p in probs:
        t, v = p.time_s, p.driver_channels["speed"]
        dist.append(np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))]))
    knots = np.arange(0.0, max(d[-1] for d in dist) + KNOT_M, KNOT_M)
    road = [[cat["road_grade"][j] * np.maximum(0.0, 1 - np.abs(dist[j] - x) / KNOT_M)
             for j in range(len(probs))] for x in knots]
    return calib, cat, road


def _solve(A, y, ridge):
    """Least squares with ``ridge`` (relative to the mean diagonal) on the columns after the
    calibration terms (``ridge`` is None: plain least squares)."""
    if ridge is None:
        return np.linalg.lstsq(A, y, rcond=None)[0]
    G = A.T @ A
    P = np.zeros(len(G))
    P[ridge[1]:] = ridge[0] * np.trace(G[ridge[1]:, ridge[1]:]) / (len(G) - ridge[1])
    return np.linalg.lstsq(G + np.diag(P + 1e-12 * np.trace(G) / len(G)), A.T @ y, rcond=None)[0]


def _cv(y, X0, X, folds, k, ridge=None):
    """Held-out SSE of y on [X0, X] by folds, and the full-data coefficients of X (``ridge``:
    a penalty towards zero on X's coefficients, relative to their mean diagonal)."""
    A = np.column_stack([X0] + ([X] if X is not None else []))
    rg = None if ridge is None else (ridge, X0.shape[1])
    sse = 0.0
    for f in range(k):
        tr, te = folds != f, folds == f
        b = _solve(A[tr], y[tr], rg)
        sse += float(np.sum((y[te] - A[te] @ b) ** 2))
    b = _solve(A, y, rg)
    return sse, b[X0.shape[1]:]


def measure():
    pairs, probs = _setup()
    W = _coarse(probs)
    calib, cat, road = _columns(probs)
    X0 = np.column_stack([W(c) for c in calib])
    Xc = {cid: W(cols)[:, None] for cid, cols in cat.items()}
    Xr = np.column_stack([W(c) for c in road])
    fine_road = np.array([np.concatenate(c) for c in road])
    r0 = W([p.measured - p.baseline for p in probs])
    n, st = len(r0), Settings()
    dur = float(sum(p.time_s[-1] - p.time_s[0] for p in probs))
    folds = fold_ids(n, st.folds, max(st.blocks_per_fold, int(round(dur / (st.folds * st.block_s)))))
    cases = [("clean", 0.0, None)]
    cases += [(e, s, e) for e, sizes in {**SIZES, **ROUTE_SIZES}.items() for s in sizes]
    rows = []
    for name, size, effect in cases:
        extra = [np.zeros(len(p.time_s)) for p in probs]
        if effect is not None:
            extra = []
            for (tn, td, tm, spec), _ in pairs:
                e, _ = concealed_fuel(effect, size, td, spec)
                y = td["fuel_rate_g_per_s"].to_numpy()
                extra.append(np.maximum(y + e, 0.0) - y)
        y = r0 + W(extra)
        base, _ = _cv(y, X0, None, folds, st.folds)
        gains = {}
        for cid, X in Xc.items():
            sse, _ = _cv(y, X0, X, folds, st.folds)
            gains[cid] = 1 - np.sqrt(sse / base)
        sse, b = _cv(y, X0, Xr, folds, st.folds)
        gains["road"] = 1 - np.sqrt(sse / base)
        moved_fit = float(np.abs(b @ fine_road).sum())
        for lam in RIDGES:
            gains[f"road, ridge {lam:g}"] = 1 - np.sqrt(_cv(y, X0, Xr, folds, st.folds, lam)[0] / base)
        # what the road adds once the drag is in the model (ridge 1 on the knots only)
        with_drag = np.column_stack([X0, Xc["aero_drag"]])
        drag_only, _ = _cv(y, with_drag, None, folds, st.folds)
        gains["road over drag"] = 1 - np.sqrt(_cv(y, with_drag, Xr, folds, st.folds, 1.0)[0] / drag_only)
        # the concealed signal's own shape, one coefficient: what any description could reach
        gains["known form"] = 1 - np.sqrt(_cv(y, X0, W(extra)[:, None], folds, st.folds)[0] / base) \
            if effect is not None else float("nan")
        moved = float(np.abs(np.concatenate(extra)).sum())
        rows.append((name, size, gains, moved, moved_fit))
    return rows, len(road), n


def main() -> int:
    rows, knots, n = measure()
    print(f"design {DESIGN}'s windows ({n}), road knots every {KNOT_M:g} m ({knots} values)\n")
    print("| concealed | size | held-out gain: constant grade | drag | accessory | road | "
          + " | ".join(f"road, ridge {lam:g}" for lam in RIDGES)
          + " | road over drag, ridge 1 | known form | fuel moved: concealed | by the road fit [g] |")
    print("|---" * (10 + len(RIDGES)) + "|")
    for name, size, g, moved, fit in rows:
        print(f"| {name} | {size:g} | {g['road_grade']:.4f} | {g['aero_drag']:.4f} | "
              f"{g['accessory_load']:.4f} | {g['road']:.4f} | "
              + "".join(f"{g[f'road, ridge {lam:g}']:.4f} | " for lam in RIDGES)
              + f"{g['road over drag']:.4f} | {g['known form']:.4f} | {moved:.1f} | {fit:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
