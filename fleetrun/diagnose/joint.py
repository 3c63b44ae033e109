"""Several recordings of one vehicle diagnosed together: one effect, one size, every recording.

A road grade, an extra drag or an accessory load is a property of the vehicle (or of its
road), present on every cycle it drives, and its signature differs from cycle to cycle: drag
grows with the cube of speed (large on a highway cycle), an accessory load with engine-on
time (large where the vehicle idles), a grade with distance and mass. One recording rarely
tells them apart (docs/diagnose-realdata.md, section 1b); several can. Each recording is
built into its own :class:`~fleetrun.diagnose.engine.Problem` exactly as ``fleetrun diagnose``
builds it alone (its own ``--calibrate-on`` reference and residual), and the problems are
joined (:func:`join`): the residuals, baselines and channels one after another, each
candidate effect's column the recordings' columns one after another, so that its linear
parameter and its shape parameter are **one value for all recordings**. An effect that is a
condition of each recording rather than of the vehicle (a cold start's warm-up:
``Effect.per_recording``) is one candidate per recording instead, ``warmup@<recording>``,
with its own size and time constant, zero on the other recordings. The calibration
terms stay each recording's own (each baseline is only known to its own reference's standard
errors). The selection (:func:`fleetrun.diagnose.engine.select`) then runs unchanged on the
joined problem (docs/diagnose.md, "Several recordings of one vehicle").
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from fleetrun.diagnose import _clean, analyse, build, integral_share
from fleetrun.diagnose.engine import IntegralSpec, Problem, Settings, windowed
from fleetrun.diagnose.integrals import integrals, phases
from fleetrun.diagnose.records import Integral
from fleetrun.diagnose.select import PER_RECORDING_SEP, Candidate
from fleetrun.effects import EFFECTS
from fleetrun.diagnose.vehicle import SAME_TRACE_WINDOW_S
from fleetrun.diagnose.weighting import noise_weighted
from fleetrun.diagnose.route import ROAD_KNOT_M, with_grade_profiles, with_road
from fleetrun.errors import InputError, unknown_name_error
from fleetrun.fileio import JsonDocument


@dataclass(frozen=True)
class Piece:
    """Where one recording sits in a joined problem: samples ``start:stop``."""

    name: str
    start: int
    stop: int

    @property
    def span(self) -> slice:
        return slice(self.start, self.stop)


def _cat(arrays) -> np.ndarray:
    return np.concatenate([np.asarray(a, dtype=float) for a in arrays])


def _shared_shapes(cands: Sequence[Candidate]) -> list[dict]:
    """The shape grid every recording's candidate has (a warm-up's grid is cut at half of
    each recording's length)."""
    return [sh for sh in cands[0].shapes if all(sh in c.shapes for c in cands[1:])]


def _joined_candidate(cands: Sequence[Candidate]) -> Candidate:
    shapes = _shared_shapes(cands)
    cols = [_cat(c.columns[c.shapes.index(sh)] for c in cands) for sh in shapes]
    column_for = None
    if all(c.column_for is not None for c in cands):
        column_for = lambda sh, fs=tuple(c.column_for for c in cands): _cat(f(sh) for f in fs)  # noqa: E731
    bounds = None
    if all(c.shape_bounds is not None for c in cands):
        bounds = (max(c.shape_bounds[0] for c in cands), min(c.shape_bounds[1] for c in cands))
    first = cands[0]
    return Candidate(first.id, cols, shapes, first.lower, first.upper, column_for=column_for,
                     shape_bounds=bounds)


def _pad(col, before: int, after: int) -> np.ndarray:
    return np.concatenate([np.zeros(before), np.asarray(col, float), np.zeros(after)])


def _per_recording(cands: Sequence[Candidate], names: Sequence[str], sizes: Sequence[int]) -> list[Candidate]:
    """One candidate per recording (``effect@recording``), zero on the others' samples: an
    effect that is a condition of each recording (:attr:`fleetrun.effects.base.Effect.per_recording`)."""
    out = []
    for k, (c, name) in enumerate(zip(cands, names)):
        before, after = sum(sizes[:k]), sum(sizes[k + 1:])
        column_for = None if c.column_for is None else \
            (lambda sh, f=c.column_for, b=before, a=after: _pad(f(sh), b, a))
        out.append(Candidate(f"{c.id}{PER_RECORDING_SEP}{name}", [_pad(x, before, after) for x in c.columns],
                             list(c.shapes), c.lower, c.upper, column_for=column_for,
                             shape_bounds=c.shape_bounds))
    return out


def _padded_terms(problems: Sequence[Problem]) -> list:
    """Each recording's calibration terms, zero on the other recordings' samples."""
    sizes = [len(p.time_s) for p in problems]
    out = []
    for k, p in enumerate(problems):
        before, after = sum(sizes[:k]), sum(sizes[k + 1:])
        out += [(_pad(col, before, after), lo, hi) for col, lo, hi in p.initial_terms]
    return out


def _check_joinable(problems: Sequence[Problem]) -> None:
    if len(problems) < 2:
        raise InputError("a joint diagnosis needs at least two recordings")
    levels = {p.level for p in problems} | {p.target for p in problems}
    if len(levels) != 2:
        raise InputError("a joint diagnosis needs recordings of one level and one target",
                         hint="diagnose differential and vehicle recordings separately")
    if any(p.surrogates for p in problems):
        raise InputError("a joint diagnosis of recordings with untestable effects' surrogates "
                         "is not supported", hint="diagnose these recordings one at a time")


def _time(problems: Sequence[Problem]) -> np.ndarray:
    """Times one after another: each recording shifted to start one step after the last
    ended."""
    out, end = [], None
    for p in problems:
        t = np.asarray(p.time_s, float)
        step = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
        out.append(t if end is None else t + (end + step - t[0]))
        end = float(out[-1][-1])
    return np.concatenate(out)


def join(problems: Sequence[Problem], names: Sequence[str]) -> tuple[Problem, tuple[Piece, ...]]:
    """One problem from several recordings' problems (same level and target), and where each
    recording sits in it (``names``: one per recording, distinct). A candidate effect is kept
    if every recording can test it; its parameters are shared, except for an effect that is
    a condition of each recording (one candidate per recording). ``coarse`` is not joined
    here (:func:`join_coarse`)."""
    _check_joinable(problems)
    if len(set(names)) != len(names):
        raise InputError(f"a joint diagnosis needs distinct recording names, got {list(names)}",
                         hint="rename the files so that their stems differ")
    ids = [c.id for c in problems[0].candidates if all(any(d.id == c.id for d in p.candidates) for p in problems)]
    sizes = [len(p.time_s) for p in problems]
    candidates = []
    for cid in ids:
        cands = [next(d for d in p.candidates if d.id == cid) for p in problems]
        if EFFECTS[cid].per_recording:
            candidates += _per_recording(cands, names, sizes)
        else:
            candidates.append(_joined_candidate(cands))
    untestable: dict[str, list[str]] = {}
    for p in problems:
        for cid, missing in p.untestable.items():
            untestable.setdefault(cid, []).extend(m for m in missing if m not in untestable.get(cid, []))
    for p, name in zip(problems, names):
        for c in p.candidates:
            if c.id not in ids:
                untestable.setdefault(c.id, []).append(f"a recording where it is testable: not {name}")
    keys = [k for k in problems[0].driver_channels if all(k in p.driver_channels for p in problems)]
    t = _time(problems)
    ig0 = problems[0].integral
    integral = IntegralSpec(moving=np.concatenate([np.asarray(p.integral.moving, bool) for p in problems]),
                            speed_mps=None if any(p.integral.speed_mps is None for p in problems)
                            else _cat(p.integral.speed_mps for p in problems),
                            weight=_cat(p.integral.weight for p in problems), unit=ig0.unit)
    info = {"recordings": [{"recording": name, **p.baseline_info} for p, name in zip(problems, names)]}
    notes = [f"{name}: {n}" for p, name in zip(problems, names) for n in p.notes]
    offset_floor = {}
    for p in problems:
        for k, v in p.offset_floor.items():
            offset_floor[k] = max(v, offset_floor.get(k, v))
    joined = Problem(problems[0].level, problems[0].target, t, _cat(p.measured for p in problems),
                     _cat(p.baseline for p in problems), candidates, untestable, {},
                     {k: v for p in problems for k, v in p.confound_possible.items()},
                     {k: _cat(p.driver_channels[k] for p in problems) for k in keys}, info, notes,
                     {k: v for p in problems for k, v in p.extra_ambiguity.items()}, problems[0].units,
                     _padded_terms(problems), offset_floor, integral)
    ends = np.cumsum([0] + sizes)
    pieces = tuple(Piece(name, int(a), int(b)) for name, a, b in zip(names, ends[:-1], ends[1:]))
    return joined, pieces


#: How the selection weights each recording's windows (``joint_diagnosis(weights=...)``):
#: ``none`` every window alike; ``noise`` by the inverse of its noise variance, estimated per
#: recording (:func:`fleetrun.diagnose.weighting.noise_weighted`).
WEIGHTS = ("none", "noise")


def join_coarse(problems: Sequence[Problem], names: Sequence[str], window: int,
                weights: str = "none") -> Problem:
    """``join`` of the recordings' coarse problems; a recording without one is windowed
    (:func:`fleetrun.diagnose.engine.windowed`) over ``window`` samples. With ``weights``
    ``noise`` each recording's windows are weighted by their own noise before joining."""
    if weights not in WEIGHTS:
        raise unknown_name_error("window weighting", weights, WEIGHTS)
    coarse = [p.coarse if p.coarse is not None else windowed(p, window) for p in problems]
    if weights == "noise":
        coarse = [noise_weighted(c) for c in coarse]
    return join(coarse, names)[0]


def without_warmup(problem: Problem, names: Sequence[str]) -> Problem:
    """``problem`` without the warm-up candidates of the recordings ``names`` (hot starts: a
    cold-start penalty cannot be there, and a slow warm-up would otherwise stand in for a
    constant load, docs/diagnose-realdata.md, 1d)."""
    drop = {f"warmup{PER_RECORDING_SEP}{n}" for n in names}
    missing = drop - {c.id for c in problem.candidates}
    if missing:
        raise InputError(f"no warm-up candidate to drop for {sorted(missing)}",
                         hint="name recordings of this joint problem")
    return replace(problem, candidates=[c for c in problem.candidates if c.id not in drop])


@dataclass(frozen=True)
class JointDiagnosis:
    """The joined problem, the diagnosis.json-shaped result (its ``integrals`` per recording,
    each entry naming its ``recording``), the fitted effects on the joined samples and where
    each recording sits."""

    problem: Problem
    result: JsonDocument
    fitted: np.ndarray
    pieces: tuple[Piece, ...]

    def phase_spans(self, piece: Piece) -> list[tuple[int, int]]:
        """The phases of one recording: index spans into its own samples."""
        p = self.problem
        s = piece.span
        speed = p.integral.speed_mps
        return [tuple(ph.span) for ph in
                phases(p.time_s[s], p.integral.moving[s], None if speed is None else speed[s])]


def piece_integrals(problem: Problem, fitted: np.ndarray, pieces: Sequence[Piece]) -> list[tuple[str, Integral]]:
    """``integrals`` (phases only) of each recording, times relative to its own start: (the
    recording's name, the entry) pairs."""
    out = []
    speed = problem.integral.speed_mps
    for piece in pieces:
        s = piece.span
        t = problem.time_s[s] - problem.time_s[s][0]
        ph = phases(t, problem.integral.moving[s], None if speed is None else speed[s])
        for e in integrals(t, problem.integral.weight[s], problem.measured[s], problem.baseline[s],
                           problem.baseline[s] + fitted[s], ph, []):
            out.append((piece.name, e))
    return out


def joint_diagnosis(recordings: Sequence, references: Sequence, *, physics: str = "thesis",
                    settings: Settings | None = None, residual: str = "auto",
                    window_s: float | None = None, weights: str = "none",
                    hot_starts: Sequence[bool] | None = None,
                    grade_profile: bool = False, road: bool = False,
                    road_refit: bool = True, road_knot_m: float = ROAD_KNOT_M) -> JointDiagnosis:
    """Diagnose ``recordings`` of one vehicle together; ``references[i]`` is the
    ``--calibrate-on`` reference of ``recordings[i]`` (None: none). The selection runs on
    ``window_s`` means (default: the same-trace window,
    :data:`fleetrun.diagnose.vehicle.SAME_TRACE_WINDOW_S`) for every recording, each window
    weighted as ``weights`` says (:data:`WEIGHTS`; docs/diagnose.md, "Several recordings of
    one vehicle"). With ``noise`` the held-out errors and ``baseline.heldout_rmse`` are of
    the weighted windows; the fitted effects, ``after`` and the integrals are in g/s and g
    as without. ``hot_starts[i]`` True declares recording ``i`` a hot start (the engine warm
    from its first second, as the test protocol says): it gets no ``warmup`` candidate
    (:func:`without_warmup`). ``grade_profile`` True adds a grade located along each
    recording's route, ``road_grade@<recording>`` (:func:`fleetrun.diagnose.route.with_grade_profiles`);
    ``road`` True one road under every recording, ``road_grade@road``
    (:func:`fleetrun.diagnose.route.with_road`); ``road_refit`` True sizes a named road with its
    knots refitted, the penalty relaxed as held-out error chooses; ``road_knot_m`` its knot spacing."""
    if len(references) != len(recordings):
        raise InputError("give one reference (or None) per recording")
    if hot_starts is not None and len(hot_starts) != len(recordings):
        raise InputError("give one hot-start flag per recording")
    problems = [build(r, None, ref, physics, residual) for r, ref in zip(recordings, references)]
    names = [Path(r).stem for r in recordings]
    joined, pieces = join(problems, names)
    dt = float(np.median(np.diff(problems[0].time_s)))
    window = max(1, int(round((window_s or SAME_TRACE_WINDOW_S) / dt)))
    joined.coarse = join_coarse(problems, names, window, weights)
    if grade_profile:
        joined = with_grade_profiles(joined, problems, names, window, weights)
    if road:
        joined = with_road(joined, problems, names, window, weights, knot_m=road_knot_m, refit=road_refit)
    hot = [n for n, h in zip(names, hot_starts or []) if h]
    if hot:
        joined = without_warmup(joined, hot)
        joined.coarse = without_warmup(joined.coarse, hot)
    result, fitted = analyse(joined, settings)
    entries = piece_integrals(joined, fitted, pieces)
    result["integrals"] = [{"recording": name, **e.as_json()} for name, e in entries]
    result["unexplained"]["integral_share"] = integral_share([e for _, e in entries])
    result["recording_name"] = ", ".join(names)
    return JointDiagnosis(joined, _clean(result), fitted, pieces)
