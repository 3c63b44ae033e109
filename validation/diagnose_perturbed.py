"""Shares of issue 16 on rig recordings whose true forms are not the catalogue's.

    python validation/diagnose_perturbed.py [--seeds 10] [--duration 1800] [--json FILE]

Recordings from :mod:`fleetrun.testing.recordings`: every hidden catalogue effect computed
with a perturbed true form (``PERTURBED_FORMS``: step switching, a plain central-difference
acceleration through a shaft lag, a warm-up with a second time constant, film and windage
exponents off the catalogue's, a lagged wheel-speed difference, a hypoid's sliding speed off
by 15 %), AR(1) sensor noise with a coefficient drawn from 0.9-0.98, random sensor offsets,
two rigs. Cases: each of the eight effects alone, pairs, noise only, two untestable cases
(a missing channel), and four causes outside the catalogue (a torque share, a load-squared
loss, a heat-soak loss, an output-transducer gain drift). Prints the table that
docs/diagnose.md and the README quote; tests/test_diagnose_perturbed.py asserts the shares.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fleetrun.diagnose import diagnose  # noqa: E402
from fleetrun.testing.recordings import (OUT_OF_CATALOGUE, PERTURBED_PARAMETER_RANGES,  # noqa: E402
                                         drift_case, perturbed_case, unknown_case)

SINGLE_EFFECTS = list(PERTURBED_PARAMETER_RANGES)
#: Pairs are drawn from the six effects of issue 5 (as in tests/test_diagnose.py).
PAIR_EFFECTS = SINGLE_EFFECTS[:6]
UNTESTABLE = (("cornering", {"wheel_speeds": False}), ("oil_warmup", {"ambient_column": False}))
OUT_CAUSES = list(OUT_OF_CATALOGUE) + ["gain_drift"]
#: Held-out error at the noise floor: within this factor of what no function of the channels
#: explains (the unexplained block's noise_rmse).
NOISE_FLOOR_FACTOR = 1.15
#: Parameter tolerance of issue 16 ("parameters within 25 %").
PARAMETER_TOLERANCE = 0.25


@dataclass(frozen=True)
class Outcome:
    """One recording's verdicts."""

    kind: str            # single, pair, noise, untestable, outside
    label: str
    seed: int
    named_first: bool    # single: the hidden effect is the first finding
    parameters_ok: bool  # single: its parameters within 25 %
    heldout_ok: bool     # single: held-out error halved or at the noise floor
    all_named: bool      # pair: both among the findings
    quiet: bool          # noise/untestable: no finding
    unexplained: bool    # unexplained.significant
    drift: bool          # the sensor_drift check fired
    energy_share: float
    heldout_gain: float  # the generic description's held-out gain on what is left
    seconds: float


def _single(truth, res) -> tuple[bool, bool, bool]:
    (eid, params), = truth
    f = res["findings"]
    if not f or f[0]["effect"] != eid:
        return False, False, False
    err = max(abs(f[0]["parameters"][k] / v - 1) for k, v in params.items())
    after, before = f[0]["heldout_rmse_after"], f[0]["heldout_rmse_before"]
    floor = NOISE_FLOOR_FACTOR * res["unexplained"]["noise_rmse"]
    return True, err <= PARAMETER_TOLERANCE, after <= 0.5 * before or after <= floor


def _cases(seeds: int):
    for eid in SINGLE_EFFECTS:
        for seed in range(seeds):
            yield "single", eid, seed, lambda e=eid, s=seed: perturbed_case([e], s)
    for seed in range(seeds):
        pair = [str(x) for x in np.random.default_rng(seed).choice(PAIR_EFFECTS, 2, replace=False)]
        yield "pair", "+".join(pair), 100 + seed, lambda p=pair, s=seed: perturbed_case(p, 100 + s)
    for seed in range(seeds):
        yield "noise", "noise only", 200 + seed, lambda s=seed: perturbed_case([], 200 + s)
    for i, (eid, kw) in enumerate(UNTESTABLE):
        for seed in range(max(1, seeds // 2)):
            yield ("untestable", f"{eid} (no {next(iter(kw))[:-1].replace('_', ' ')})", 300 + seed,
                   lambda e=eid, k=kw, s=seed: perturbed_case([e], 300 + s, **k))
    for cause in OUT_CAUSES:
        for seed in range(seeds):
            make = (lambda s=seed: drift_case(s)) if cause == "gain_drift" else \
                (lambda c=cause, s=seed: unknown_case(c, s))
            yield "outside", cause, seed, make


def run(seeds: int = 10, workdir=None, kinds=None, progress=False) -> list[Outcome]:
    """Diagnose every case; the outcomes in order."""
    workdir = Path(workdir or tempfile.mkdtemp())
    out = []
    for kind, label, seed, make in _cases(seeds):
        if kinds and kind not in kinds:
            continue
        t0 = time.perf_counter()
        rec = make()
        res = diagnose(rec.write(workdir / "case.csv"), write=False)
        named = params = heldout = False
        if kind == "single":
            named, params, heldout = _single(rec.truth["effects"], res)
        found = {f["effect"] for f in res["findings"]}
        truth = {e for e, _ in rec.truth["effects"]}
        u = res["unexplained"]
        out.append(Outcome(kind, label, seed, named, params, heldout, truth <= found,
                           not res["findings"], bool(u["significant"]),
                           bool(u.get("drift", {}).get("significant")), float(u["energy_share"]),
                           float(u["heldout_gain"]), time.perf_counter() - t0))
        if progress:
            print(asdict(out[-1]), flush=True)
    return out


def shares(outcomes: list[Outcome]) -> dict[str, tuple[int, int]]:
    """The issue's shares as (hits, cases)."""
    def count(sel, pred):
        xs = [o for o in outcomes if sel(o)]
        return sum(pred(o) for o in xs), len(xs)

    inside = lambda o: o.kind in ("single", "pair", "noise")  # noqa: E731
    return {
        "single effect named first": count(lambda o: o.kind == "single", lambda o: o.named_first),
        "single: parameters within 25 %": count(lambda o: o.kind == "single", lambda o: o.parameters_ok),
        "single: held-out error halved or at the noise floor":
            count(lambda o: o.kind == "single", lambda o: o.heldout_ok),
        "pair: both named": count(lambda o: o.kind == "pair", lambda o: o.all_named),
        "noise only: no finding": count(lambda o: o.kind == "noise", lambda o: o.quiet),
        "untestable: no finding": count(lambda o: o.kind == "untestable", lambda o: o.quiet),
        "in catalogue: unexplained.significant false": count(inside, lambda o: not o.unexplained),
        "outside the catalogue: unexplained.significant true":
            count(lambda o: o.kind == "outside", lambda o: o.unexplained),
        "gain drift: sensor_drift fires": count(lambda o: o.label == "gain_drift", lambda o: o.drift),
        "in catalogue: sensor_drift fires": count(inside, lambda o: o.drift),
    }


def table(outcomes: list[Outcome]) -> str:
    lines = ["| share | measured |", "|---|---|"]
    for name, (hit, n) in shares(outcomes).items():
        lines.append(f"| {name} | {hit}/{n} ({100 * hit / max(n, 1):.0f} %) |")
    lines += ["", "| case | cases | named first / both / quiet | unexplained significant |", "|---|---|---|---|"]
    for label in dict.fromkeys(o.label for o in outcomes):
        xs = [o for o in outcomes if o.label == label]
        kind = xs[0].kind
        hit = sum(o.named_first if kind == "single" else o.all_named if kind == "pair" else o.quiet
                  for o in xs) if kind != "outside" else None
        lines.append(f"| {label} | {len(xs)} | {'-' if hit is None else hit} | "
                     f"{sum(o.unexplained for o in xs)} |")
    total = sum(o.seconds for o in outcomes)
    lines.append(f"\n{len(outcomes)} recordings, {total:.0f} s ({total / max(len(outcomes), 1):.1f} s each)")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--kinds", default="", help="comma list of single,pair,noise,untestable,outside")
    ap.add_argument("--json", default=None, help="also write the outcomes as JSON")
    ap.add_argument("--progress", action="store_true")
    args = ap.parse_args(argv)
    outcomes = run(args.seeds, kinds=[k for k in args.kinds.split(",") if k] or None,
                   progress=args.progress)
    print(table(outcomes))
    if args.json:
        Path(args.json).write_text(json.dumps([asdict(o) for o in outcomes], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
