"""The quantity that matters: the target integrated over phases and located segments.

Per-second errors of a dynamometer or rig recording are dominated by transients; a budget
cares about fuel (or energy) over a phase. A recording is cut into **phases** at every
standstill (or engine-off) stretch longer than :data:`GAP_S`, and each driving phase that
follows a recognised EPA cycle is cut again at the cycle's bag boundaries
(:data:`BAG_BOUNDARIES_S`, e.g. UDDS at 505 s). For each phase and each located segment the
integral of the target is reported: measured, model before and model after the findings
(fuel in g at vehicle level; output energy in kJ at differential level, torque times wheel
speed).
"""
from __future__ import annotations

import numpy as np

from fleetrun.cycles import ftp_bag1_end_s, load_cycle
from fleetrun.diagnose.records import Integral, Phase, Segment

#: A standstill or engine-off stretch longer than this [s] separates two phases (a soak).
GAP_S = 60.0
#: Bag boundaries [s from the cycle's start] of the EPA cycles fleetrun recognises in a
#: recording: UDDS bag 1 (the transient phase of the FTP-75, 0-505 s) and bag 2 (505-1369 s),
#: 40 CFR 86.137 and 40 CFR 86 Appendix I (a).
BAG_BOUNDARIES_S = {"UDDS": (ftp_bag1_end_s(),)}
#: Largest RMS speed difference [m/s] between a phase and a cycle over its first bag for the
#: phase to count as that cycle (drivers follow the trace within about +-2 mph, 40 CFR 86.115).
MATCH_RMS_MPS = 1.0
#: Speed [m/s] below which a vehicle counts as standing.
STILL_MPS = 0.1


def _runs(mask: np.ndarray):
    """(start, stop) index pairs of the runs of True in ``mask``."""
    m = np.r_[False, np.asarray(mask, bool), False]
    d = np.diff(m.astype(int))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def align(time_s, speed_mps, ref_time_s, ref_speed_mps, *, span_s=None, search_s=5.0):
    """Where ``ref`` (a cycle or another recording) starts in ``time_s``, and how well the
    two speed traces agree: ``(offset, rms)``, ``ref``'s t = 0 at recording time ``offset``.

    The first launches are aligned (the idle before a launch may be part of a soak), then the
    offset is refined within ``search_s`` (1-s steps) to the smallest RMS speed difference
    over the overlap (or its first ``span_s`` seconds). None if either never moves.
    """
    t, v = np.asarray(time_s, float), np.asarray(speed_mps, float)
    rt = np.asarray(ref_time_s, float) - ref_time_s[0]
    rv = np.asarray(ref_speed_mps, float)
    moving, r_moving = np.flatnonzero(v > STILL_MPS), np.flatnonzero(rv > STILL_MPS)
    if not len(moving) or not len(r_moving):
        return None
    launch = float(t[moving[0]] - rt[r_moving[0]])
    best = None
    for offset in launch + np.arange(-search_s, search_s + 0.5):
        end = offset + (span_s if span_s is not None else rt[-1])
        sel = (t >= max(offset, t[0])) & (t <= min(end, offset + rt[-1]))
        if sel.sum() < 2:
            continue
        rms = float(np.sqrt(np.mean((v[sel] - np.interp(t[sel] - offset, rt, rv)) ** 2)))
        if best is None or rms < best[1]:
            best = (float(offset), rms)
    return best


def cycle_offset(time_s, speed_mps, cycle) -> float | None:
    """Recording time of ``cycle``'s t = 0 if the recording follows it over its first bag
    (RMS speed difference within :data:`MATCH_RMS_MPS`), else None."""
    boundary = BAG_BOUNDARIES_S[cycle.name][0]
    if time_s[-1] - time_s[0] < boundary:
        return None
    found = align(time_s, speed_mps, cycle.time_s, cycle.speed_mps, span_s=boundary)
    if found is None or found[1] > MATCH_RMS_MPS or time_s[-1] < found[0] + boundary:
        return None
    return found[0]


def driving_stretches(time_s, moving) -> tuple[list, list]:
    """Index spans between the standstill (or engine-off) runs longer than :data:`GAP_S`,
    and those runs."""
    t = np.asarray(time_s, float)
    n = len(t)
    gaps = [(int(a), int(b)) for a, b in _runs(~np.asarray(moving, bool)) if t[b - 1] - t[a] > GAP_S]
    edges = sorted({0, n} | {i for gap in gaps for i in gap})
    return [(a, b) for a, b in zip(edges[:-1], edges[1:]) if (a, b) not in gaps], gaps


def _epa_cycles():
    return [load_cycle(name) for name in BAG_BOUNDARIES_S]


def phases(time_s, moving, speed_mps=None) -> list[Phase]:
    """Phases of a recording: index spans with a ``label``.

    ``moving``: True where the vehicle (or pinion) turns and the engine runs; a run of False
    longer than :data:`GAP_S` is its own (``standstill``) phase. ``speed_mps`` (vehicle speed,
    optional) lets driving phases be matched with the EPA cycles of :data:`BAG_BOUNDARIES_S`.
    """
    t = np.asarray(time_s, float)
    stretches, gaps = driving_stretches(t, moving)
    cycles = _epa_cycles() if speed_mps is not None else []
    out = [Phase(span=gap, label="standstill") for gap in gaps]
    for a, b in stretches:
        out.extend(_bags(t, speed_mps, a, b, cycles))
    return sorted(out, key=lambda p: p.span[0])


def _bags(t, speed_mps, a, b, cycles) -> list[Phase]:
    """A driving phase, cut at the bag boundaries of the first EPA cycle it follows."""
    for cycle in cycles:
        offset = cycle_offset(t[a:b], speed_mps[a:b], cycle)
        if offset is None:
            continue
        spans, start = [], a
        for k, bound in enumerate(BAG_BOUNDARIES_S[cycle.name]):
            cut = a + int(np.searchsorted(t[a:b], offset + bound))
            spans.append(Phase(span=(start, cut), label=f"{cycle.name} bag {k + 1}"))
            start = cut
        spans.append(Phase(span=(start, b), label=f"{cycle.name} bag {len(spans) + 1}"))
        return [s for s in spans if s.span[1] > s.span[0]]
    return [Phase(span=(a, b), label="driving")]


def integrals(time_s, weight, measured, before, after, phase_list: list[Phase],
              segments: list[Segment]) -> list[Integral]:
    """``integrals`` of diagnosis.json: per phase, then per located segment.

    ``weight`` converts the target into a rate of the integrated quantity (1 for a fuel rate
    in g/s; output speed / 1000 for a torque in N m, giving kJ); integrals use each sample's
    own time step (rectangle rule on the uniform grid).
    """
    t = np.asarray(time_s, float)
    dt = np.gradient(t) if len(t) > 1 else np.ones(1)
    w = np.asarray(weight, float) * dt
    m, bf, af = (np.asarray(x, float) * w for x in (measured, before, after))

    def entry(a, b, kind, label):
        end = t[b] if b < len(t) else t[-1]
        return Integral(start_s=round(float(t[a]), 3), end_s=round(float(end), 3),
                        measured=round(float(m[a:b].sum()), 4), before=round(float(bf[a:b].sum()), 4),
                        after=round(float(af[a:b].sum()), 4), kind=kind, label=label)

    out = [entry(*p.span, kind="phase", label=p.label) for p in phase_list]
    for seg in segments:
        a = int(np.searchsorted(t, seg.start_s))
        b = int(np.searchsorted(t, seg.end_s, side="right"))
        if b > a:
            out.append(entry(a, b, kind="segment", label=f"located segment ({100 * seg.share:.0f} %)"))
    return out
