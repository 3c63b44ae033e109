"""Benchmark: the thesis model, vectorised vs one point at a time (issue: 1e6 points < 1 s).

    python benchmarks/bench_map.py [--points 1000000] [--loop-points 2000]

Evaluates LD_RWD (thesis B.2) at random (torque fraction, speed) points in one call, then a
sample one point per call, and reports points per second and the speed-up.
"""
import argparse
import time

import numpy as np

from fleetrun.differential import efficiency


def best_of(fn, repeat=3):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--loop-points", type=int, default=2000)
    parser.add_argument("--configuration", default="LD_RWD")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    tf = rng.uniform(0, 1, args.points)
    n = rng.uniform(0, 4000, args.points)
    efficiency(args.configuration, tf[:10], n[:10], 3.73)  # load models, warm caches
    t_vec = best_of(lambda: efficiency(args.configuration, tf, n, 3.73))
    k = args.loop_points
    t_loop = best_of(lambda: [efficiency(args.configuration, tf[i], n[i], 3.73) for i in range(k)], repeat=1)
    per_point_loop = t_loop / k
    print(f"{args.configuration}: {args.points:,} points in one call: {t_vec:.3f} s "
          f"({args.points / t_vec:,.0f} points/s)")
    print(f"one point per call: {per_point_loop * 1e6:.1f} us/point "
          f"({1 / per_point_loop:,.0f} points/s); {args.points:,} points would take {per_point_loop * args.points:.0f} s")
    print(f"speed-up of the vectorised call: {per_point_loop * args.points / t_vec:,.0f}x")


if __name__ == "__main__":
    main()
