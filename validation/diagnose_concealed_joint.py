"""One effect concealed in several real Camry recordings, diagnosed jointly: does it get named?

    python validation/diagnose_concealed_joint.py [--design J1|J2|J3|W|W2|Wh|J3h|G|L|Lr|Lr5|C|C2] [--out DIR] [--why]

A grade, an extra drag or an accessory load is a property of the vehicle and acts on every
cycle it drives, with a different signature on each (drag ~ v^3, large on HWFET and US06; an
accessory load ~ engine-on time, large at idle; a grade ~ distance and mass). The Argonne 2018
Camry was driven over four recordings (inputs/dyno: cold UDDS, hot UDDS, HWFET x 2, US06 x 2).
The same effect at the same size is concealed in each target recording with
:func:`diagnose_concealed.concealed_fuel` (the simulation with the effect minus without), and
the targets are diagnosed together (:func:`fleetrun.diagnose.joint.joint_diagnosis`: one
parameter set for all recordings). The designs were fixed before any result was seen:

* ``J1`` (each target against the model calibrated on the hot UDDS, as ``fleetrun diagnose
  --calibrate-on`` does): targets the cold UDDS recording (same-trace residual against the hot
  UDDS), HWFET and US06 (no same-trace reference: residual against the calibrated simulation).
* ``J2`` (a same-trace reference on every cycle): the cold UDDS recording against the hot
  UDDS, the second HWFET against the first (61811013, split at 780 s), the second US06 against
  the first (61811014, split at 690 s); each target's reference is its ``--calibrate-on``.

Sizes, concealment and scoring are those of validation/diagnose_concealed.py: named as a
finding; its fuel over all targets, less what the same effect fits on the clean targets when
it is no finding there, within 25 % of the concealed fuel; the phase-fuel error the
concealment adds (per phase of every target) at least halved; the clean targets give no
finding but ``warmup``.
"""
from __future__ import annotations

import argparse
import re
import sys
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from validation.diagnose_concealed import (COMPARED, SIZE_TOLERANCE, SIZES, _effect_fuel, _write,  # noqa: E402
                                          concealed_fuel, road_profile_grade)

from fleetrun.diagnose.engine import Settings, relaxed_fit  # noqa: E402
from fleetrun.diagnose.joint import joint_diagnosis  # noqa: E402
from fleetrun.diagnose.route import ROAD_ID, ROAD_KNOT_M  # noqa: E402
from fleetrun.diagnose.select import effect_of  # noqa: E402
from fleetrun.effects import EFFECTS  # noqa: E402
from fleetrun.diagnose.recording import load_recording  # noqa: E402
from fleetrun.resources import inputs_dir  # noqa: E402
from fleetrun.workbook.vehicle_file import read_vehicle_toml  # noqa: E402

#: Where the second run of a two-run recording starts [s] (inputs/dyno/PROVENANCE.md).
SECOND_RUN_S = {"camry2018_hwfet": 780.0, "camry2018_us06": 690.0,
                "camry2018_udds_cold": 1960.0}   # in the engine-off soak (1368-1994 s)
#: design -> [(target, reference)]: a stem, or (stem, "first"/"second") for one run of it
DESIGNS = {
    "J1": [("camry2018_udds_cold", "camry2018_udds_hot"), ("camry2018_hwfet", "camry2018_udds_hot"),
           ("camry2018_us06", "camry2018_udds_hot")],
    "J2": [("camry2018_udds_cold", "camry2018_udds_hot"),
           (("camry2018_hwfet", "second"), ("camry2018_hwfet", "first")),
           (("camry2018_us06", "second"), ("camry2018_us06", "first"))],
    # chosen after J1 and J2 had been measured: warm runs only (no cold start in any target)
    "J3": [(("camry2018_udds_cold", "second"), "camry2018_udds_hot"),
           (("camry2018_hwfet", "second"), ("camry2018_hwfet", "first")),
           (("camry2018_us06", "second"), ("camry2018_us06", "first"))],
}
# pre-registered (docs/diagnose-realdata.md, 1d): J3's and J2's recordings, noise-weighted windows
DESIGNS["W"] = DESIGNS["J3"]
DESIGNS["W2"] = DESIGNS["J2"]
#: design -> window weighting of fleetrun.diagnose.joint.joint_diagnosis
WEIGHTING = {"W": "noise", "W2": "noise"}
# chosen after W had been measured (not blind): W with every target declared a hot start
DESIGNS["Wh"] = DESIGNS["J3"]
WEIGHTING["Wh"] = "noise"
# its control (also after W): J3 declared hot starts, windows unweighted
DESIGNS["J3h"] = DESIGNS["J3"]
#: designs whose targets are all declared hot starts (no warm-up candidate)
HOT_STARTS = {"Wh", "J3h"}
# pre-registered (docs/diagnose-realdata.md, 1e): Wh with a grade located along each target's
# route (fleetrun.diagnose.route)
DESIGNS["G"] = DESIGNS["J3"]
WEIGHTING["G"] = "noise"
HOT_STARTS.add("G")
#: designs with a distance-located grade profile per target (``joint_diagnosis(grade_profile=True)``)
GRADE_PROFILE = {"G"}
# pre-registered (docs/diagnose-realdata.md, 1f): Wh with one road under every target
DESIGNS["L"] = DESIGNS["J3"]
WEIGHTING["L"] = "noise"
HOT_STARTS.add("L")
#: designs with one road under every target (``joint_diagnosis(road=True)``)
ROAD = {"L"}
# pre-registered (docs/diagnose-realdata.md, 1g): L with a named road sized after its selection
DESIGNS["Lr"] = DESIGNS["J3"]
WEIGHTING["Lr"] = "noise"
HOT_STARTS.add("Lr")
ROAD.add("Lr")
#: designs whose named road is refitted with the penalty relaxed (``road_refit=True``); its
#: background on the clean targets is the same refit there (:func:`_background`)
ROAD_REFIT = {"Lr"}
# pre-registered after Lr (docs/diagnose-realdata.md, 1h): Lr with a knot every 500 m
DESIGNS["Lr5"] = DESIGNS["J3"]
WEIGHTING["Lr5"] = "noise"
HOT_STARTS.add("Lr5")
ROAD.add("Lr5")
ROAD_REFIT.add("Lr5")
#: design -> the road's knot spacing [m] where it is not fleetrun.diagnose.route.ROAD_KNOT_M
#: (500 m since Lr5)
ROAD_KNOT = {"L": 1000.0, "Lr": 1000.0}
# pre-registered (docs/diagnose-realdata.md, 1i): Wh with a tie between two physical effects
# compared once more on the rows where their signatures differ (Settings.contrast_rivals)
DESIGNS["C"] = DESIGNS["J3"]
WEIGHTING["C"] = "noise"
HOT_STARTS.add("C")
# pre-registered after C (not blind; docs/diagnose-realdata.md, 1i): C with the null's noise the
# residual of the model with both effects
DESIGNS["C2"] = DESIGNS["J3"]
WEIGHTING["C2"] = "noise"
HOT_STARTS.add("C2")
#: design -> the contrast null's noise (Settings.contrast_noise) for designs whose rival check
#: compares ties on contrast folds (fleetrun.diagnose.contrast)
CONTRAST = {"C": "own", "C2": "both"}


#: Design R (docs/diagnose-realdata.md, 1e): a real road's grade profile scaled by f, run
#: with designs Wh and G; scored as ``road_grade`` by the fuel it moves (its absolute sum).
ROUTE_SIZES = {"road_profile": (0.5, 1.0)}
#: Design L's cases: the six, R's two, and the road driven the other way (not looked at
#: before L was registered)
L_SIZES = {**SIZES, **ROUTE_SIZES, "road_profile_reversed": (0.35, 0.7)}
SCORED_AS = {"road_profile": "road_grade", "road_profile_reversed": "road_grade"}
MOVED = {"road_profile", "road_profile_reversed"}


@dataclass(frozen=True)
class JointCase:
    effect: str
    size: float
    share_of_fuel: float
    findings: tuple[str, ...]
    concealed_g: float
    fitted_raw_g: float          # the named effect's fuel over all targets
    fitted_g: float              # less its fit on the clean targets when no finding there
    phase_error_before_g: float
    phase_error_after_g: float
    parameters: dict
    #: the first round's two best held-out gains and the ambiguities reported (why not named)
    why: str = ""

    @property
    def named(self) -> bool:
        return SCORED_AS.get(self.effect, self.effect) in self.findings

    @property
    def size_ok(self) -> bool:
        return self.named and abs(self.fitted_g / self.concealed_g - 1) <= SIZE_TOLERANCE

    @property
    def phases_ok(self) -> bool:
        return self.phase_error_after_g <= 0.5 * self.phase_error_before_g


def _data(spec_stem):
    """Time, speed, fuel of one recording or one run of it, and its sidecar text."""
    stem, run = (spec_stem, None) if isinstance(spec_stem, str) else spec_stem
    dyno = inputs_dir() / "dyno"
    df = load_recording(dyno / f"{stem}.csv").data[["time_s", "vehicle_speed_mps", "fuel_rate_g_per_s"]]
    if run is not None:
        second = df["time_s"] >= SECOND_RUN_S[stem]
        df = df[second if run == "second" else ~second].copy()
        df["time_s"] = df["time_s"] - df["time_s"].iloc[0]
    name = stem if run is None else f"{stem}_{run}"
    return name, df.reset_index(drop=True), (dyno / f"{stem}.toml").read_text(), read_vehicle_toml(dyno / f"{stem}.toml")


def _phase_masks(d) -> list[np.ndarray]:
    """Boolean masks over the joined samples, one per phase of every target."""
    out = []
    n = len(d.problem.time_s)
    for piece in d.pieces:
        for a, b in d.phase_spans(piece):
            m = np.zeros(n, bool)
            m[piece.start + a:piece.start + b] = True
            out.append(m)
    return out


def run(design: str, workdir=None, sizes=SIZES, road: bool = False,
        settings: Settings | None = None) -> tuple[dict, list[JointCase]]:
    """The clean targets' diagnosis and the scored cases of ``design``; ``road`` True adds the
    road under every target as the library now builds it (knots every
    :data:`fleetrun.diagnose.route.ROAD_KNOT_M`, refitted once named) to any design;
    ``settings`` the selection's (default ``Settings()``)."""
    workdir = Path(workdir or tempfile.mkdtemp())
    refit = design in ROAD_REFIT or road
    if design in CONTRAST:
        settings = replace(settings or Settings(), contrast_rivals=True, contrast_noise=CONTRAST[design])
    pairs = [(_data(t), _data(r)) for t, r in DESIGNS[design]]
    refs = [_write(rd, rm, workdir / f"ref_{rn}.csv") for _, (rn, rd, rm, _) in pairs]
    clean_paths = [_write(td, tm, workdir / f"{tn}.csv") for (tn, td, tm, _), _ in pairs]
    kw = {"weights": WEIGHTING.get(design, "none"),
          "hot_starts": [True] * len(pairs) if design in HOT_STARTS else None,
          "grade_profile": design in GRADE_PROFILE, "road": design in ROAD or road,
          "road_refit": refit, "road_knot_m": ROAD_KNOT.get(design, ROAD_KNOT_M), "settings": settings}
    clean = joint_diagnosis(clean_paths, refs, **kw)
    clean_ids = [f["effect"] for f in clean.result["findings"]]
    if refit:
        # the penalty factor the road's refit keeps on the clean targets (its background)
        clean.result["road_background_factor"] = relaxed_fit(clean.problem.coarse, ROAD_ID, settings)[1]
        bg = _background(clean, ROAD_ID, True, settings)
        # and what that fit puts into the phases (sum over phases of |its phase sum| [g]): the
        # phase-fuel error a named road's background alone leaves
        clean.result["road_background_phase_g"] = sum(abs(float(bg[m].sum())) for m in _phase_masks(clean))
    dt = np.gradient(clean.problem.time_s)
    total = float(np.sum(clean.problem.measured * dt))
    masks = _phase_masks(clean)
    cases = []
    for effect, these in sizes.items():
        for size in these:
            extras, param, paths = [], None, []
            for (tn, td, tm, spec), _ in pairs:
                extra, param = concealed_fuel(effect, size, td, spec)
                hidden = td.copy()
                # a descent cannot take the measured fuel below zero (design R; the other
                # concealments only add fuel, so nothing changes for them)
                hidden["fuel_rate_g_per_s"] = np.maximum(td["fuel_rate_g_per_s"] + extra, 0.0)
                extras.append((hidden["fuel_rate_g_per_s"] - td["fuel_rate_g_per_s"]).to_numpy())
                sub = workdir / f"{effect}_{size:g}"
                sub.mkdir(exist_ok=True)
                paths.append(_write(hidden, tm, sub / f"{tn}.csv"))
            extra = np.concatenate(extras)
            d = joint_diagnosis(paths, refs, **kw)
            found = tuple(f["effect"] for f in d.result["findings"])
            # the effect's findings: itself, or per target (road_grade@<target>, design G)
            scored = SCORED_AS.get(effect, effect)
            ids = [i for i in found if effect_of(i) == scored]
            names = tuple(dict.fromkeys(scored if i in ids else i for i in found))
            bg = np.zeros(len(extra))
            for i in ids:
                if i not in clean_ids:
                    bg = bg + _background(clean, i, refit, settings)
            # what the diagnosis adds over the clean diagnosis, less the effect's clean background
            added = (d.fitted - clean.fitted) * dt - bg
            before = sum(abs(float((extra * dt)[m].sum())) for m in masks)
            after = sum(abs(float((extra * dt - added)[m].sum())) for m in masks)
            raw = float(sum(_fuel_of(d, i).sum() for i in ids))
            concealed = float((extra * dt).sum())
            if effect in MOVED:
                # the fuel the grade moves: sums of absolute fuel per sample
                fit = sum((_fuel_of(d, i) for i in ids), np.zeros(len(extra)))
                raw, concealed = float(np.abs(fit).sum()), float(np.abs(extra * dt).sum())
                bg = np.zeros(len(extra)) if not ids else bg
                moved_bg = float(np.abs(bg).sum())
            params = {i: f["parameters"] for f in d.result["findings"] for i in ids if f["effect"] == i}
            params = next(iter(params.values())) if list(params) == [effect] else params
            less = (moved_bg if effect in MOVED else float(bg.sum())) if ids else 0.0
            cases.append(JointCase(effect, size, concealed / total, names,
                                   concealed, raw, raw - less if ids else 0.0,
                                   before, after, {"concealed": param, **params}, _why(d.result)))
    return clean.result, cases


def _fuel_of(d, cid: str, findings_only: bool = True) -> np.ndarray:
    """Fuel [g] per sample of the candidate ``cid`` (an effect id, or ``effect@recording``)
    at its fitted parameters: as a finding, or (``findings_only`` False) as the candidate's
    own fit whatever its status."""
    if cid in EFFECTS:
        return _effect_fuel(d, cid, findings_only)
    pool = d.result["findings"] if findings_only else d.result["candidates"]
    f = next((x for x in pool if x["effect"] == cid and x.get("parameters")), None)
    if f is None:
        return np.zeros(len(d.problem.time_s))
    cand = next(c for c in d.problem.candidates if c.id == cid)
    e = EFFECTS[effect_of(cid)]
    shape = {k: float(f["parameters"][k]) for k in cand.shapes[0]} if cand.shapes[0] else {}
    if cand.block is not None:
        # a block candidate (one road's knots): its weights are the parameters w0, w1, ...
        shape = {f"w{i}": float(f["parameters"][f"w{i}"]) for i in range(cand.block.shape[0])}
    if shape and cand.column_for is not None:
        col = cand.column_for(shape)
    else:
        col = cand.columns[cand.shapes.index(shape) if shape in cand.shapes else 0]
    return f["parameters"][e.linear] * col * np.gradient(d.problem.time_s)


def _background(clean, cid: str, refit: bool, settings: Settings | None = None) -> np.ndarray:
    """Fuel [g] per sample that ``cid`` fits on the clean targets, where it is no finding: its
    own fit there (the candidate table's parameters), or for a block refitted after its
    selection (``refit``) the same refit on the clean targets
    (:func:`fleetrun.diagnose.engine.relaxed_fit`: the penalty chosen by held-out error there)."""
    cand = next(c for c in clean.problem.candidates if c.id == cid)
    if not refit or cand.block is None:
        return _fuel_of(clean, cid, False)
    w, _ = relaxed_fit(clean.problem.coarse, cid, settings)
    return cand.column_for({f"w{i}": float(x) for i, x in enumerate(w)}) * np.gradient(clean.problem.time_s)


def _why(result: dict) -> str:
    """The first selection round's two best held-out gains and the ambiguities reported (and
    the penalty factor a refitted road kept)."""
    rounds = result["method"]["rounds"]
    gains = sorted(rounds[0]["gains"].items(), key=lambda kv: -kv[1])[:2] if rounds else []
    amb = "; ".join(" / ".join(a["effects"]) for a in result["ambiguities"])
    relaxed = [m.group(1) for f in result["findings"]
               for m in [re.search(r"penalty at (\S+) x the selection's", f["explanation"])] if m]
    nan = float("nan")
    contrasts = "; ".join(f"contrast {c['effect']} vs {c['contrast']['against']}: T {c['contrast'].get('T', nan):.4g} "
                          f"(R true, 0.99: {c['contrast'].get('T_if_r', nan):.4g}; A true, 0.01: "
                          f"{c['contrast'].get('T_if_a', nan):.4g}) -> {c['contrast']['winner'] or 'tie'}"
                          for c in result["candidates"] if c.get("contrast"))
    return (", ".join(f"{k} {v:.4f}" for k, v in gains) + (f"; ambiguous: {amb}" if amb else "")
            + (f"; refitted at {relaxed[0]} x the penalty" if relaxed else "") + (f"; {contrasts}" if contrasts else ""))


def table(design: str, clean: dict, cases: list[JointCase]) -> str:
    lines = [f"design {design}: clean targets jointly: findings "
             f"{[(f['effect'], f['parameters']) for f in clean['findings']] or 'none'}; candidates "
             f"{[(c['effect'], c['status']) for c in clean['candidates']]}; unexplained significant "
             f"{clean['unexplained']['significant']}"
             + (f"; the road refitted on them keeps {clean['road_background_factor']:.3g} x the penalty, "
                f"puts {clean['road_background_phase_g']:.1f} g into the phases (sum of absolute phase sums)"
                if "road_background_factor" in clean else ""), "",
             "| concealed | size | share of fuel | findings | concealed g | named effect's g (raw) | "
             "less clean background g | phase error g before -> after | parameter (concealed / fitted) | "
             "first round's best gains; ambiguities |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for c in cases:
        fitted = {k: v for k, v in c.parameters.items() if k != "concealed"}
        lines.append(f"| {c.effect} | {c.size:g} | {100 * c.share_of_fuel:.1f} % | "
                     f"{', '.join(c.findings) or 'none'} | {c.concealed_g:.1f} | {c.fitted_raw_g:.1f} | "
                     f"{c.fitted_g:.1f} | {c.phase_error_before_g:.1f} -> {c.phase_error_after_g:.1f} | "
                     f"{c.parameters['concealed']:.3g} / {fitted} | {c.why} |")
    ok = sum(c.named and c.size_ok and c.phases_ok for c in cases)
    lines.append(f"\n{ok}/{len(cases)} named, sized within 25 % and with the phase error at least halved")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- why


@dataclass(frozen=True)
class JointSeparation:
    """The three vehicle effects' columns on the clean targets' joined 10-s windows (each
    recording's calibration terms and the named warm-ups partialled out): cosines, what each
    fits alone on the clean targets [g over all targets], its standard error alone and
    jointly with the other two, and what it fits on each target alone (scaled to all targets'
    column, so the numbers compare)."""

    cosines: tuple[tuple[str, str, float], ...]
    noise_g_per_s: float
    alone_g: dict
    alone_se_g: dict
    joint_se_g: dict
    per_recording_g: dict


def separation(design: str, workdir=None) -> JointSeparation:
    workdir = Path(workdir or tempfile.mkdtemp())
    pairs = [(_data(t), _data(r)) for t, r in DESIGNS[design]]
    refs = [_write(rd, rm, workdir / f"ref_{rn}.csv") for _, (rn, rd, rm, _) in pairs]
    paths = [_write(td, tm, workdir / f"{tn}.csv") for (tn, td, tm, _), _ in pairs]
    clean = joint_diagnosis(paths, refs, weights=WEIGHTING.get(design, "none"),
                            hot_starts=[True] * len(pairs) if design in HOT_STARTS else None,
                            grade_profile=design in GRADE_PROFILE)
    J = clean.problem.coarse   # weighted rows where the design weights its windows
    cols = {c.id: c.columns[0] for c in J.candidates if c.id in COMPARED}
    warm = [next(c for c in J.candidates if c.id == f["effect"]).column_for({"tau_s": f["parameters"]["tau_s"]})
            for f in clean.result["findings"] if f["effect"].startswith("warmup")]
    A = np.array([c for c in [t[0] for t in J.initial_terms] + warm if np.any(c)]).T
    P = {k: cols[k] - A @ np.linalg.lstsq(A, cols[k], rcond=None)[0] for k in COMPARED}
    r = J.residual - A @ np.linalg.lstsq(A, J.residual, rcond=None)[0]
    window = float(np.median(np.diff(J.time_s)))
    grams = {k: float(cols[k].sum() * window) for k in COMPARED}
    X = np.array([P[k] for k in COMPARED]).T
    e = r - X @ np.linalg.lstsq(X, r, rcond=None)[0]
    rho = max(float(np.corrcoef(e[:-1], e[1:])[0, 1]), 0.0)
    s2 = float(np.var(e)) * (1 + rho) / (1 - rho)
    cov = np.linalg.inv(X.T @ X) * s2
    ends = np.cumsum([0] + [p.stop - p.start for p in clean.pieces])
    ends = np.round(ends / (len(clean.problem.time_s) / len(J.time_s))).astype(int)
    per = {k: tuple(_alone(P[k][a:b], cols[k][a:b], r[a:b]) * grams[k] for a, b in zip(ends[:-1], ends[1:]))
           for k in COMPARED}
    return JointSeparation(tuple((a, b, float(P[a] @ P[b] / np.sqrt((P[a] @ P[a]) * (P[b] @ P[b]))))
                                 for i, a in enumerate(COMPARED) for b in COMPARED[i + 1:]),
                           float(np.std(e)), {k: float(P[k] @ r / (P[k] @ P[k]) * grams[k]) for k in COMPARED},
                           {k: float(np.sqrt(s2 / (P[k] @ P[k])) * grams[k]) for k in COMPARED},
                           {k: float(np.sqrt(cov[i, i]) * grams[k]) for i, k in enumerate(COMPARED)}, per)


def _alone(x: np.ndarray, raw: np.ndarray, r: np.ndarray) -> float:
    """Least-squares coefficient of ``x`` on ``r``; NaN where the calibration terms take
    (almost) all of the column (an accessory load against a recording's own idle offset)."""
    return float(x @ r / (x @ x)) if x @ x > 1e-6 * (raw @ raw) else float("nan")


def separation_table(design: str, sep: JointSeparation) -> str:
    lines = [f"design {design}, clean targets: cosines " + ", ".join(f"{a}/{b} {c:.3f}" for a, b, c in sep.cosines)
             + f"; window noise {sep.noise_g_per_s:.4f} g/s", "",
             "| effect | clean, alone [g] | se alone [g] | se jointly [g] | each target alone [g] |",
             "|---|---|---|---|---|"]
    lines += [f"| {k} | {sep.alone_g[k]:.1f} | {sep.alone_se_g[k]:.1f} | {sep.joint_se_g[k]:.1f} | "
              + " / ".join(f"{x:.1f}" for x in sep.per_recording_g[k]) + " |" for k in COMPARED]
    return "\n".join(lines)


# ----------------------------------------------------------------------------- knot ceiling


def knot_ceiling(spacings=(1000.0, 500.0, 250.0), design: str = "Lr") -> list[tuple]:
    """How much of a concealed road's fuel moved a road of knots can carry at all: the
    concealed fuel alone (noise-free, after the zero floor) fitted by least squares, unpenalised,
    on every target's 1-Hz samples by the road's knot columns at each spacing (the catalogue's
    grade basis times each knot's hat function of distance) with the calibration terms in;
    and by the catalogue's grade basis times the true grade (one scale). Rows: (case, size,
    concealed moved [g], {spacing: relative moved}, basis x true grade relative moved)."""
    workdir = Path(tempfile.mkdtemp())
    pairs = [(_data(t), _data(r)) for t, r in DESIGNS[design]]
    refs = [_write(rd, rm, workdir / f"ref_{rn}.csv") for _, (rn, rd, rm, _) in pairs]
    paths = [_write(td, tm, workdir / f"{tn}.csv") for (tn, td, tm, _), _ in pairs]
    clean = joint_diagnosis(paths, refs, weights=WEIGHTING[design], hot_starts=[True] * len(pairs))
    p = clean.problem
    dt, terms = np.gradient(p.time_s), np.array([t[0] for t in p.initial_terms])
    grade = next(c for c in p.candidates if c.id == "road_grade").columns[0]
    spans = [piece.span for piece in clean.pieces]
    dist = [np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
            for v, t in ((p.driver_channels["speed"][s], p.time_s[s]) for s in spans)]
    rows = []
    for effect in sorted(MOVED):
        for size in L_SIZES[effect]:
            extra, true_grade = [], []
            for (tn, td, tm, spec), _ in pairs:
                e, _ = concealed_fuel(effect, size, td, spec)
                fuel = td["fuel_rate_g_per_s"].to_numpy()
                extra.append(np.maximum(fuel + e, 0.0) - fuel)
                true_grade.append(size * road_profile_grade(td["time_s"].to_numpy(), td["vehicle_speed_mps"].to_numpy(),
                                                            reversed_=effect.endswith("reversed")))
            x = np.concatenate(extra)
            moved = float(np.abs(x * dt).sum())
            carried = {}
            for km in spacings:
                knots = np.arange(0.0, max(d[-1] for d in dist) + km, km)
                block = np.hstack([np.array([grade[s] * np.maximum(0.0, 1 - np.abs(d - k) / km) for k in knots])
                                   for s, d in zip(spans, dist)])
                cols = np.vstack([terms, block])
                b = np.linalg.lstsq(cols.T, x, rcond=None)[0]
                carried[km] = float(np.abs(b[len(terms):] @ block * dt).sum()) / moved - 1
            col = grade * np.concatenate(true_grade)
            basis = float(np.abs((col @ x) / (col @ col) * col * dt).sum()) / moved - 1
            rows.append((effect, size, moved, carried, basis))
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--design", choices=sorted(DESIGNS), action="append")
    ap.add_argument("--out", default=None)
    ap.add_argument("--route", action="store_true", help="design R: a real road's grade profile "
                    "concealed (run with --design Wh --design G)")
    ap.add_argument("--road", action="store_true", help="add the road under every target (500-m "
                    "knots, refitted once named) to the designs given")
    ap.add_argument("--seed", type=int, default=None, help="the shift null's seed (Settings.seed)")
    ap.add_argument("--block-s", type=float, default=None, help="cross-validation block length [s]")
    ap.add_argument("--ceiling", action="store_true", help="only the share of a concealed road's "
                    "fuel moved that knots at 1000 / 500 / 250 m carry (noise-free)")
    ap.add_argument("--why", action="store_true", help="only the separation of the three effects' "
                    "columns on the clean targets")
    args = ap.parse_args(argv)
    if args.ceiling:
        for effect, size, moved, carried, basis in knot_ceiling():
            print(f"{effect} f = {size:g}: concealed moved {moved:.1f} g; knots "
                  + ", ".join(f"{km:.0f} m {100 * v:+.1f} %" for km, v in carried.items())
                  + f"; grade basis x true grade {100 * basis:+.1f} %")
        return 0
    for design in args.design or sorted(DESIGNS):
        if args.why:
            print(separation_table(design, separation(design)), "\n", flush=True)
            continue
        out = Path(args.out) / design if args.out else None
        if out:
            out.mkdir(parents=True, exist_ok=True)
        sizes = ROUTE_SIZES if args.route else L_SIZES if design in ROAD else SIZES
        st = Settings(**{k: v for k, v in (("seed", args.seed), ("block_s", args.block_s)) if v is not None})
        clean, cases = run(design, out, sizes, road=args.road, settings=st)
        print(table(design + (" with the road" if args.road else ""), clean, cases), flush=True)
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
