"""A road grade located along the route: one profile per recording (issue 16, design G).

The catalogue's ``road_grade`` is one constant grade (:func:`fleetrun.effects.vehicle.grade_extra_fuel`).
A real road's grade is a function of distance: its fuel shows where the vehicle is on the
slope. :func:`with_grade_profiles` adds to a joint problem (:mod:`.joint`), for each recording,
a candidate ``road_grade@<recording>``: the catalogue's grade basis (extra fuel per % of grade
while the wheels are driven) times the shape :func:`fleetrun.effects.vehicle.route_grade_shape`
of the recording's own distance (the integral of its speed), with the amplitude in % as the
linear parameter (``road_grade``'s ``grade_pct`` and bounds) and the direction of the modes'
weights as a shape parameter on a fixed grid (:func:`half_sphere_directions`, not refined).
Opt-in (``joint_diagnosis(grade_profile=True)``); docs/diagnose-realdata.md, 1e.

:func:`with_road` describes instead **one road under every recording** (each driven over it
from its start): the grade piecewise linear in distance with a knot every ``ROAD_KNOT_M``, one
candidate ``road_grade@road`` whose knot grades are fitted together (a block candidate,
:class:`fleetrun.diagnose.select.Candidate`), penalised towards a level road. Opt-in
(``joint_diagnosis(road=True)``); docs/diagnose-realdata.md, 1f. Once named, its knots are
refitted with the penalty relaxed (``road_refit``, default True; 1g-1h).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Sequence

import numpy as np

from fleetrun.diagnose.engine import Problem, windowed
from fleetrun.diagnose.select import PER_RECORDING_SEP, Candidate
from fleetrun.diagnose.weighting import noise_weighted
from fleetrun.effects.vehicle import route_grade_shape

#: Elevation modes of the profile (k = 1..K) and directions of their weights on the grid.
PROFILE_MODES = 3
PROFILE_DIRECTIONS = 32
GRADE_ID = "road_grade"
#: Knot spacing [m] of the shared road's grade and the ridge on its knots' grades (relative to
#: the mean diagonal of their Gram matrix), fixed in docs/diagnose-realdata.md, 1f; the spacing
#: 1,000 m there (designs L, Lr), 500 m since design Lr5 (1h) met its pre-registered target.
ROAD_KNOT_M = 500.0
ROAD_PENALTY = 1.0
#: Factors of ``ROAD_PENALTY`` tried when a named road is sized (its knots refitted after the
#: selection, the factor with the least held-out error kept; 1: the selection's, 0: none),
#: fixed in docs/diagnose-realdata.md, 1g, before it was measured.
ROAD_RELAX = (1.0, 1 / 3, 0.1, 1 / 30, 0.01, 0.0)
ROAD_ID = f"{GRADE_ID}{PER_RECORDING_SEP}road"


def half_sphere_directions(n: int = PROFILE_DIRECTIONS) -> np.ndarray:
    """``n`` unit vectors in 3-D with first component >= 0, spread evenly (Fibonacci points).

    The sign of the profile is the linear parameter's, so half of the sphere suffices.
    """
    i = np.arange(n) + 0.5
    z = 1.0 - i / n                                   # first component in (0, 1)
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    phi = i * np.pi * (3.0 - np.sqrt(5.0))            # golden angle
    return np.column_stack([z, r * np.cos(phi), r * np.sin(phi)])


def _distance(problem: Problem) -> np.ndarray:
    """Distance travelled since the recording's start [m] (trapezoidal integral of its speed)."""
    t = np.asarray(problem.time_s, float)
    v = np.asarray(problem.driver_channels["speed"], float)
    return np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])


def _profile_candidate(problem: Problem, name: str) -> Candidate:
    """``road_grade@name`` on one recording's own samples."""
    grade = next(c for c in problem.candidates if c.id == GRADE_ID)
    distance = _distance(problem)
    dirs = half_sphere_directions()
    cols = [grade.columns[0] * route_grade_shape(distance, u) for u in dirs]
    return Candidate(f"{GRADE_ID}{PER_RECORDING_SEP}{name}", cols,
                     [{"direction": float(j)} for j in range(len(dirs))], grade.lower, grade.upper)


def _padded(c: Candidate, before: int, after: int) -> Candidate:
    pad = lambda x: np.concatenate([np.zeros(before), x, np.zeros(after)])  # noqa: E731
    return replace(c, columns=[pad(x) for x in c.columns])


def with_grade_profiles(joined: Problem, problems: Sequence[Problem], names: Sequence[str],
                        window: int, weights: str) -> Problem:
    """``joined`` (and its ``coarse``) with one ``road_grade@<name>`` candidate per recording.

    The coarse columns are windowed and weighted exactly as :func:`.joint.join_coarse` treats
    the recordings' other columns (same windows, the same recording's noise weights).
    """
    fine = [_profile_candidate(p, n) for p, n in zip(problems, names)]
    coarse = [_coarse_like(p, c, window, weights) for p, c in zip(problems, fine)]
    sizes = [len(p.time_s) for p in problems]
    csizes = [len(c.columns[0]) for c in coarse]
    add = [_padded(c, sum(sizes[:k]), sum(sizes[k + 1:])) for k, c in enumerate(fine)]
    cadd = [_padded(c, sum(csizes[:k]), sum(csizes[k + 1:])) for k, c in enumerate(coarse)]
    out = replace(joined, candidates=list(joined.candidates) + add, coarse=None)
    out.coarse = replace(joined.coarse, candidates=list(joined.coarse.candidates) + cadd)
    return out


def _coarse_like(problem: Problem, cand: Candidate, window: int, weights: str) -> Candidate:
    """``cand`` (on ``problem``'s samples) windowed and weighted as :func:`.joint.join_coarse`
    treats the recording's own columns (same windows, the same noise weights)."""
    p = replace(problem, candidates=[cand], coarse=None)
    q = windowed(p, window) if problem.coarse is None else \
        replace(problem.coarse, candidates=[windowed(p, _window_of(problem)).candidates[0]])
    if len(q.candidates[0].columns[0]) != len(q.time_s):
        raise ValueError(f"{cand.id}: windows do not match the recording's coarse problem")
    if weights == "noise":
        q = noise_weighted(q)
    return q.candidates[0]


def road_knots(problems: Sequence[Problem], knot_m: float = ROAD_KNOT_M) -> np.ndarray:
    """Knot positions [m] from 0 past the longest recording's distance."""
    longest = max(float(_distance(p)[-1]) for p in problems)
    return np.arange(0.0, longest + knot_m, knot_m)


def _road_block(problem: Problem, knots: np.ndarray) -> list[np.ndarray]:
    """The catalogue's grade basis times each knot's hat function of the distance travelled."""
    grade = next(c for c in problem.candidates if c.id == GRADE_ID).columns[0]
    d = _distance(problem)
    step = float(knots[1] - knots[0]) if len(knots) > 1 else 1.0
    return [grade * np.maximum(0.0, 1.0 - np.abs(d - x) / step) for x in knots]


def _block_candidate(block: np.ndarray, lower: float, upper: float, penalty: float,
                     relax: tuple[float, ...] = ()) -> Candidate:
    column_for = lambda sh, b=block: np.einsum("i,in->n", [sh[f"w{i}"] for i in range(len(b))], b)  # noqa: E731
    return Candidate(ROAD_ID, [block.sum(axis=0)], [{}], lower, upper, column_for=column_for,
                     block=block, penalty=penalty, relax=relax)


def with_road(joined: Problem, problems: Sequence[Problem], names: Sequence[str], window: int,
              weights: str, knot_m: float = ROAD_KNOT_M, penalty: float = ROAD_PENALTY,
              refit: bool = True) -> Problem:
    """``joined`` (and its ``coarse``) with the candidate ``road_grade@road``: one road under
    every recording, its grade at knots every ``knot_m`` fitted together (``grade_pct``: the
    steepest knot's grade; ``w0``, ``w1``, ...: each knot's grade over it), penalised by
    ``penalty`` towards a level road. ``refit`` True: once named, its knots are refitted with
    the penalty relaxed by the factors :data:`ROAD_RELAX` (the one with the least held-out
    error kept, :func:`fleetrun.diagnose.select.relaxed_block`)."""
    relax = ROAD_RELAX if refit else ()
    grade = next(c for c in problems[0].candidates if c.id == GRADE_ID)
    knots = road_knots(problems, knot_m)
    fine, coarse = [], []
    for p in problems:
        cols = _road_block(p, knots)
        tmp = Candidate(ROAD_ID, cols, [{"knot": float(k)} for k in range(len(cols))], grade.lower, grade.upper)
        fine.append(np.array(cols))
        coarse.append(np.array(_coarse_like(p, tmp, window, weights).columns))
    out = replace(joined, candidates=list(joined.candidates)
                  + [_block_candidate(np.hstack(fine), grade.lower, grade.upper, penalty, relax)], coarse=None)
    out.coarse = replace(joined.coarse, candidates=list(joined.coarse.candidates)
                         + [_block_candidate(np.hstack(coarse), grade.lower, grade.upper, penalty, relax)])
    return out


def _window_of(problem: Problem) -> int:
    """Samples per window of a recording's own coarse problem."""
    return max(1, int(round(len(problem.time_s) / len(problem.coarse.time_s))))
