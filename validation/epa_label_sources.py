"""Where the real label route's misses come from, and the fixes pre-registered for them
(docs/validation-epa.md "Where the label route's misses come from", issue 22 fifth round):

    PYTHONPATH=. python validation/epa_label_sources.py [--cache FILE]

On the Test Car List vehicles joined to one real MY2022 label (validation/epa_labels.py), pairs
merged, physics + technology held out by manufacturer (validation/epa_one_number.prepare):

(a) one measured FTP (R0, the share form) and the label's own unadjusted city figure (UCity) as
    that FTP (A1);
(b) the chain C0 (whole-mpg label) -> C1 (unrounded) -> C2 (the label formula of the label's own
    UCity / UHighway) -> C3 (of the vehicle's own FTP / HWFET), each through the label route L1,
    and the misses of C1 by the first step that removes them;
(c) F1 / F1g (the label's city and highway figures), F2 / F2g (a global split h of the label's
    correction between city and highway), F3 (a global bias c of the label against the formula).

Every global constant is fitted on the other manufacturers (22 folds, one per manufacturer, and
the 5 folds of validation/fleet_error.py); nothing per vehicle.
"""
from __future__ import annotations

import argparse
import pickle
import sys
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from epa_labels import joined, labels_of, load_labels, prepared  # noqa: E402
from epa_one_number import SHARE_GRID, TESTS, derived_label, label_set  # noqa: E402
from fleet_error import folds_of  # noqa: E402

from fleetrun.physics import epa_label  # noqa: E402
from fleetrun.simulation import measured  # noqa: E402

H_GRID = np.round(np.arange(0.0, 1.501, 0.05), 2)
C_GRID = np.round(np.arange(-0.03, 0.03001, 0.0025), 4)
WITHIN = 0.05
#: a label is "not the formula of its own UCity / UHighway" beyond this relative difference
FORMULA_GAP = 0.005


def label_columns(lab) -> pd.DataFrame:
    """Per vehicle of ``lab`` (epa_labels.labels_of): the mean over its matched label rows of
    city08U, highway08U, comb08U, comb08, city08, highway08, UCity, UHighway (NaN without a label)."""
    by_id = load_labels().set_index("id")
    cols = ["city08U", "highway08U", "comb08U", "comb08", "city08", "highway08", "UCity", "UHighway"]
    ids = lab.label_ids.fillna("").astype(str)
    rows = [by_id.loc[[int(i) for i in x.split()], cols].mean().to_numpy() if x.strip() else np.full(len(cols), np.nan)
            for x in ids]
    return pd.DataFrame(np.array(rows, float), index=lab.index, columns=cols)


def scaled(err, k_ftp, k_hwfet, k_us06):
    """Errors (vehicles x FTP, HWFET, US06) after dividing each test's predicted mpg by its scale."""
    k = np.c_[k_ftp, k_hwfet, k_us06]
    return (1.0 + err[list(TESTS)].to_numpy()) / k - 1.0


def loss(e, cols=(1, 2)):
    """Squared log errors of the columns ``cols`` (default HWFET and US06), NaN skipped."""
    return float(np.nansum(np.log1p(e[:, list(cols)]) ** 2))


def fit(tables, folds, cols=(1, 2)):
    """Per held-out fold: the table (one per parameter) with the least loss on the other folds;
    returns the held-out errors and the chosen parameter indices."""
    out, chosen = np.full(tables[0].shape, np.nan), []
    for g in np.unique(folds):
        train = folds != g
        best = int(np.argmin([loss(t[train], cols) for t in tables]))
        chosen.append(best)
        out[~train] = tables[best][~train]
    return out, chosen


def share_tables(err, k):
    """L1-type tables over SHARE_GRID: FTP and HWFET by k, US06 by k^s."""
    return [scaled(err, k, k, k ** s) for s in SHARE_GRID]


def cells(e, rows) -> str:
    parts = []
    for j, t in enumerate(TESTS):
        x = e[rows, j]
        x = x[np.isfinite(x)]
        parts.append(f"{t} n={x.size} mean {x.mean():+.2%} med|e| {np.median(np.abs(x)):.2%} "
                     f"within 5 % {np.mean(np.abs(x) <= WITHIN):.1%}")
    return " | ".join(parts)


def hit(e, j=1):
    return np.abs(e[:, j]) <= WITHIN


class Setup:
    """The prepared held-out errors, the joined labels and the folds."""

    def __init__(self, r, lab):
        self.err = r["err"][list(TESTS)]
        self.paired, self.r = r["paired"], r
        self.idx = self.err.index
        self.lab = lab
        self.used = lab.used.to_numpy()
        self.cols = label_columns(lab)
        mf = r["manufacturer"]
        five = pd.Series(mf).map(folds_of(pd.DataFrame({"manufacturer": mf}))).to_numpy()
        self.folds = {"22 folds": mf, "5 folds": five}
        self.meas = np.c_[[self.paired[t].to_numpy()[self.idx] for t in TESTS]].T
        self.pred = self.meas * (1.0 + self.err.to_numpy())
        self.set = label_set(None)
        self.groups = np.where(self.used, lab.label_ids.astype(str).to_numpy(), None)

    def label_k(self, label, groups=None):
        """The L1 scale of a combined label (measured.label_scale, the list's model year)."""
        return measured.label_scale(np.where(self.used, label, np.nan), self.pred[:, 0], self.pred[:, 1],
                                    label_set=self.set, groups=groups)

    def route(self, tables, cols=(1, 2), rows=None):
        """{split: (held-out errors, chosen indices)} over the two fold splits, fitted and kept on
        ``rows`` (default the vehicles joined to one label)."""
        rows = self.used if rows is None else rows
        out = {}
        for name, folds in self.folds.items():
            out[name] = fit([np.where(rows[:, None], t, np.nan) for t in tables], folds, cols)
        return out

    def report(self, name, res, grid=None, rows=None):
        """Lines: the route's held-out cells per split on ``rows`` (default: the used vehicles)."""
        rows = self.used if rows is None else rows
        lines = []
        for split, (e, chosen) in res.items():
            pick = "" if grid is None else f"; chosen {grid[min(chosen)]}..{grid[max(chosen)]}"
            lines.append(f"{name} [{split}]: {cells(e, rows)}{pick}")
        return lines


def one_ftp_lines(s: Setup) -> list[str]:
    """(a) R0: the measured FTP, the share fitted held out on all vehicles with an FTP; A1: the
    label's UCity as the measured FTP (the model type's unadjusted city figure)."""
    k = 1.0 + s.err["FTP"].to_numpy()
    everyone = np.isfinite(k)
    r0 = s.route([scaled(s.err, k, k ** x, k ** x) for x in SHARE_GRID], rows=everyone)
    lines = s.report("R0 one measured FTP, all vehicles", r0, SHARE_GRID, rows=everyone)
    lines += s.report("R0 one measured FTP, the label route's vehicles", r0, SHARE_GRID)
    ku = s.pred[:, 0] / s.cols.UCity.to_numpy()
    a1 = s.route([scaled(s.err, ku, ku ** x, ku ** x) for x in SHARE_GRID])
    lines += s.report("A1 the label's UCity as the measured FTP", a1, SHARE_GRID)
    return lines, r0, a1


def chain_labels(s: Setup) -> dict:
    """The chain's combined labels per vehicle (NaN where not joined)."""
    c = s.cols
    return {"C0 comb08 (whole mpg)": c.comb08.to_numpy(),
            "C1 comb08U (unrounded)": c.comb08U.to_numpy(),
            "C2 formula of the label's UCity / UHighway": epa_label.combined_label_mpg(
                c.UCity.to_numpy(), c.UHighway.to_numpy(), s.set),
            "C3 formula of the vehicle's own FTP / HWFET": derived_label(s.paired, s.idx)}


def chain_lines(s: Setup) -> tuple[list[str], dict]:
    """(b) The substitution chain through L1, and the misses of C1 by the first step removing them."""
    lines, res = [], {}
    for name, label in chain_labels(s).items():
        res[name] = s.route(share_tables(s.err, s.label_k(label)))
        lines += s.report(name, res[name], SHARE_GRID)
    lines += attribution_lines(s, res)
    return lines, res


def attribution_lines(s: Setup, res) -> list[str]:
    """The C1 HWFET misses (22 folds) by the first later step that puts them within 5 %, the
    rounding's effect (C0 against C1), and the counts behind the steps."""
    names = list(res)
    h = {n: hit(res[n]["22 folds"][0]) for n in names}
    u = s.used
    miss = u & ~h[names[1]]
    by = {"inversion (C2)": miss & h[names[2]], "configuration (C3, not C2)": miss & ~h[names[2]] & h[names[3]],
          "physics ratio (missed by C3 too)": miss & ~h[names[2]] & ~h[names[3]]}
    lines = [f"C1 HWFET misses {miss.sum()} of {u.sum()} ({miss.sum() / u.sum():.1%}); by the first step within 5 %: "
             + ", ".join(f"{k} {v.sum()} ({v.sum() / u.sum():.1%} of the vehicles)" for k, v in by.items())]
    lines.append(f"  C1 misses that C3 alone removes: {(miss & h[names[3]]).sum()}; C1 misses C2 removes but C3 "
                 f"does not: {(miss & h[names[2]] & ~h[names[3]]).sum()}")
    lines.append(f"rounding: C0 hits / C1 misses {(u & h[names[0]] & ~h[names[1]]).sum()}, C0 misses / C1 hits "
                 f"{(u & ~h[names[0]] & h[names[1]]).sum()}")
    lines += count_lines(s, h, names)
    return lines


def count_lines(s: Setup, h, names) -> list[str]:
    """How many labels are not the formula of their own unadjusted figures, how many are another
    configuration's, and the physics' HWFET / FTP ratio against the measured one."""
    u, c = s.used, s.cols
    comb = chain_labels(s)[names[2]]
    not_formula = u & (np.abs(comb / c.comb08U.to_numpy() - 1.0) > FORMULA_GAP)
    other = u & ((np.abs(c.UCity.to_numpy() / s.meas[:, 0] - 1.0) > WITHIN)
                 | (np.abs(c.UHighway.to_numpy() / s.meas[:, 1] - 1.0) > WITHIN))
    miss = u & ~h[names[1]]
    lines = [f"labels not the formula of their own UCity / UHighway (> {FORMULA_GAP:.1%}): {not_formula.sum()} "
             f"of {u.sum()}, of them C1 misses {(not_formula & miss).sum()} ({(not_formula & miss).sum() / max(not_formula.sum(), 1):.1%}); "
             f"the others miss {(~not_formula & u & miss).sum()} of {(~not_formula & u).sum()}"]
    lines.append(f"labels of another configuration (UCity or UHighway > 5 % from the vehicle's FTP or HWFET): "
                 f"{other.sum()}, of them C1 misses {(other & miss).sum()}; the others miss {(~other & u & miss).sum()} "
                 f"of {(~other & u).sum()}")
    ratio = (1.0 + s.err["HWFET"].to_numpy()) / (1.0 + s.err["FTP"].to_numpy()) - 1.0
    lines.append("physics' held-out HWFET / FTP ratio against the measured, joined vehicles: within 1 / 2 / 5 %: "
                 + " / ".join(f"{np.mean(np.abs(ratio[u]) <= t):.1%}" for t in (0.01, 0.02, 0.05))
                 + f"; median |.| {np.median(np.abs(ratio[u])):.2%}; C3 misses {(u & ~h[names[3]]).sum()}, "
                 f"their median |ratio error| {np.median(np.abs(ratio[u & ~h[names[3]]])):.2%}")
    return lines


def formula_scale(s: Setup, figure, kind, test, groups=None):
    """k that makes the label formula ``kind`` (city / highway) of the simulated ``test`` mpg
    (column 0 FTP, 1 HWFET) divided by k give ``figure``; with ``groups``, the vehicles of one
    group share k (`measured.figure_scale`, as `simulate` applies it)."""
    return measured.figure_scale(np.where(s.used, np.asarray(figure, float), np.nan), s.pred[:, test], kind,
                                 label_set=s.set, groups=groups)


def split_scale(s: Setup, label, h, groups=None):
    """F2: k such that FTP / k and HWFET / k^h give the combined label through the formulas (the
    group mean of the label fuel per mile with ``groups``): `measured.label_scale` as `simulate`
    applies it with models/technology.toml ``[label_split]``."""
    return measured.label_scale(np.where(s.used, label, np.nan), s.pred[:, 0], s.pred[:, 1], label_set=s.set,
                                groups=groups, highway_share=h)


def split_tables(s: Setup, label, groups=None):
    """F2's tables over H_GRID x SHARE_GRID and their (h, s)."""
    grid, tables = [], []
    for h in H_GRID:
        kf = split_scale(s, label, h, groups)
        tables += [scaled(s.err, kf, kf ** h, kf ** x) for x in SHARE_GRID]
        grid += [(float(h), float(x)) for x in SHARE_GRID]
    return tables, grid


def split_lines(s: Setup, name, label, groups=None) -> list[str]:
    """F2 (F2g with ``groups``) held out, and its (h, s) fitted on all manufacturers (the value
    to store)."""
    tables, grid = split_tables(s, label, groups)
    lines = s.report(f"{name} global split h (h, s)", s.route(tables), grid)
    best = int(np.argmin([loss(np.where(s.used[:, None], t, np.nan)) for t in tables]))
    stored = (measured.label_split().highway_share, measured.label_split().transfer_share)
    kf = split_scale(s, label, stored[0], groups)
    e = np.where(s.used[:, None], scaled(s.err, kf, kf ** stored[0], kf ** stored[1]), np.nan)
    return lines + [f"{name} (h, s) fitted on all manufacturers: {grid[best]}",
                    f"{name} with the stored (h, s) {stored} (models/technology.toml): {cells(e, s.used)}"]


def split_other_labels(s: Setup) -> list[str]:
    """F2 held out with the label printed in whole mpg (comb08) and with the derived label of the
    vehicle's own tests (C3)."""
    lines = []
    for name, label in (("F2 whole mpg (comb08)", s.cols.comb08.to_numpy()),
                        ("F2 derived label (C3)", derived_label(s.paired, s.idx))):
        lines += split_lines(s, name, label)
        lines += split_lines(s, name + " groups", label, s.groups)
    return lines


def fix_lines(s: Setup) -> list[str]:
    """(c) L1 and G1 (the baselines), F1 / F1g, F2 / F2g, F3 held out."""
    comb = s.cols.comb08U.to_numpy()
    lines = []
    for g_name, groups in (("", None), ("g", s.groups)):
        k = s.label_k(comb, groups)
        base = "L1 per vehicle" if groups is None else "G1 group scale"
        lines += s.report(base, s.route(share_tables(s.err, k)), SHARE_GRID)
        kc = formula_scale(s, s.cols.city08U, "city", 0, groups)
        kh = formula_scale(s, s.cols.highway08U, "highway", 1, groups)
        lines += s.report(f"F1{g_name} city and highway labels", s.route([scaled(s.err, kc, kh, k ** x) for x in SHARE_GRID]),
                          SHARE_GRID)
        lines += split_lines(s, f"F2{g_name}", comb, groups)
    grid = [(c, x) for c in C_GRID for x in SHARE_GRID]
    tables = []
    for c in C_GRID:
        k = s.label_k(comb / (1.0 + c))
        tables += share_tables(s.err, k)
    lines += s.report("F3 global label bias (c, s)", s.route(tables), grid)
    return lines + split_other_labels(s)


BLEND_H = np.round(np.arange(0.4, 0.801, 0.05), 2)
BLEND_W = np.round(np.arange(0.0, 1.001, 0.1), 1)
BLEND_S = np.round(np.arange(0.3, 0.601, 0.01), 2)


def blend_lines(s: Setup) -> list[str]:
    """F5 / F5g (second round): HWFET log scale w log k_H + (1 - w) h log k, FTP by k_C, US06 by
    k^s; (h, w, s) fitted held out; against F2 / F2g on the same grid of h and s. Also with the
    three figures in whole mpg as printed (city08, highway08, comb08)."""
    lines = []
    for name, groups, cols in (("F5", None, ("comb08U", "city08U", "highway08U")),
                               ("F5g", s.groups, ("comb08U", "city08U", "highway08U")),
                               ("F5 whole mpg", None, ("comb08", "city08", "highway08")),
                               ("F5g whole mpg", s.groups, ("comb08", "city08", "highway08"))):
        comb = s.cols[cols[0]].to_numpy()
        kc = formula_scale(s, s.cols[cols[1]], "city", 0, groups)
        kh = formula_scale(s, s.cols[cols[2]], "highway", 1, groups)
        tables, grid = [], []
        for h in BLEND_H:
            k = split_scale(s, comb, h, groups)
            for w in BLEND_W:
                hw = np.exp(w * np.log(kh) + (1 - w) * h * np.log(k))
                tables += [scaled(s.err, kc, hw, k ** x) for x in BLEND_S]
                grid += [(float(h), float(w), float(x)) for x in BLEND_S]
        lines += s.report(f"{name} blend (h, w, s)", s.route(tables), grid)
        best = int(np.argmin([loss(np.where(s.used[:, None], t, np.nan)) for t in tables]))
        lines.append(f"{name} (h, w, s) fitted on all manufacturers: {grid[best]}")
        zero = [i for i, g in enumerate(grid) if g[1] == 0.0]
        lines += s.report(f"{name} with w = 0 (F2's HWFET, F1's FTP)", s.route([tables[i] for i in zero]),
                          [grid[i] for i in zero])
        lines.append(f"{name} as `simulate` applies it (measured.cycle_factors, stored constants): "
                     + cells(stored_factors_errors(s, groups, cols), s.used))
    return lines


def stored_factors_errors(s: Setup, groups=None, cols=("comb08U", "city08U", "highway08U")):
    """Errors after `measured.cycle_factors` with the label's combined, city and highway figures
    (the stored constants of models/technology.toml); US06 takes the factor of other cycles."""
    figures = {"measured_ftp_mpg": np.full(len(s.used), np.nan)}
    for name, col in zip(("label_combined_mpg", "label_city_mpg", "label_highway_mpg"), cols):
        figures[name] = np.where(s.used, s.cols[col].to_numpy(), np.nan)
    f = measured.cycle_factors(figures, s.pred[:, 0], s.pred[:, 1], [2022] * len(s.used), groups)
    return np.where(s.used[:, None], (1.0 + s.err[list(TESTS)].to_numpy()) / f - 1.0, np.nan)


def load(cache=None):
    """The Setup, from ``cache`` (a pickle of (r, lab), development) when it exists."""
    if cache and Path(cache).exists():
        r, lab = pickle.loads(Path(cache).read_bytes())
    else:
        r, table = prepared()
        lab = labels_of(r, table, joined())
        if cache:
            Path(cache).write_bytes(pickle.dumps((r, lab)))
    return Setup(r, lab)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", help="pickle of the held-out predictions and the join (development)")
    ap.add_argument("--part", choices=("all", "a", "b", "c", "blend"), default="all")
    args = ap.parse_args(argv)
    s = load(args.cache)
    print(f"{s.used.sum()} of {len(s.used)} vehicles joined to one label, {np.isfinite(s.meas[s.used, 2]).sum()} with US06",
          flush=True)
    if args.part in ("all", "a"):
        for text in one_ftp_lines(s)[0]:
            print(text, flush=True)
    if args.part in ("all", "b"):
        for text in chain_lines(s)[0]:
            print(text, flush=True)
    if args.part in ("all", "c"):
        for text in fix_lines(s):
            print(text, flush=True)
    if args.part in ("all", "blend"):
        for text in blend_lines(s):
            print(text, flush=True)


if __name__ == "__main__":
    main()
