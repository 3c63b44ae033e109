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


def half_sphere_directions(n: int = PROFILE_DIRECTIONS) -> np.ndarray:
    """``n`` unit vectors in 3-D with first component >= 0, spread evenly (Fibonacci points).

    The sign of the profile is the linear parameter's, so half of the sphere suffices.
    """
    i = np.arange(n) + 0.5
    z = 1.0 - i / n                                   # first component in (0, 1)
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    phi = i * np.pi * (3.0 - np.sqrt(5.0))            # golden angle
    return np.column_stack([z, r * np.cos(phi), r * np.sin(phi)])


def _profile_candidate(problem: Problem, name: str) -> Candidate:
    """``road_grade@name`` on one recording's own samples."""
    grade = next(c for c in problem.candidates if c.id == GRADE_ID)
    t = np.asarray(problem.time_s, float)
    v = np.asarray(problem.driver_channels["speed"], float)
    distance = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
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
    coarse = []
    for p, c in zip(problems, fine):
        q = windowed(replace(p, candidates=[c], coarse=None), window) if p.coarse is None else \
            replace(p.coarse, candidates=[windowed(replace(p, candidates=[c], coarse=None),
                                                   _window_of(p)).candidates[0]])
        if len(q.candidates[0].columns[0]) != len(q.time_s):
            raise ValueError(f"{c.id}: windows do not match the recording's coarse problem")
        if weights == "noise":
            q = noise_weighted(q)
        coarse.append(q.candidates[0])
    sizes = [len(p.time_s) for p in problems]
    csizes = [len(c.columns[0]) for c in coarse]
    add = [_padded(c, sum(sizes[:k]), sum(sizes[k + 1:])) for k, c in enumerate(fine)]
    cadd = [_padded(c, sum(csizes[:k]), sum(csizes[k + 1:])) for k, c in enumerate(coarse)]
    out = replace(joined, candidates=list(joined.candidates) + add, coarse=None)
    out.coarse = replace(joined.coarse, candidates=list(joined.coarse.candidates) + cadd)
    return out


def _window_of(problem: Problem) -> int:
    """Samples per window of a recording's own coarse problem."""
    return max(1, int(round(len(problem.time_s) / len(problem.coarse.time_s))))
