"""Benchmark ``fleetrun.simulation.simulate``: UDDS vehicle-cycle simulations per second.

    python benchmarks/bench_simulate.py                         # 1,000 vehicles, all modes
    python benchmarks/bench_simulate.py --vehicles 1000 --modes auto --cycle UDDS
    python benchmarks/bench_simulate.py --markdown docs/benchmarks-simulation.md
    python benchmarks/bench_simulate.py --fleet cars --modes auto --single 1 --block-steps 22000

Two ways of calling it:
- fleet: all vehicles in one ``simulate`` call (arrays over vehicles), as the fleet runner does;
- one at a time: ``simulate([vehicle], cycle)`` in a Python loop.

Vehicles are the example fleet's 23 types (inputs/example_fleet.xlsx) repeated, each copy with
its test weight and road-load coefficients varied by up to +-10 % (seeded), so no two rows are
equal; their final-drive ratios are the types' own (23 distinct differentials). The map3d cache
is built in a fresh temporary directory first ("cold", reported separately) and then warm.
Every timing is the best of --repeat runs (the machine is shared; the best is the least
disturbed). One process, one thread: numpy's element-wise operations do not use threads.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import sys
import tempfile
import time

import numpy as np

from fleetrun import __version__
from fleetrun.cycles import load_cycle
from fleetrun.workbook.reader import read_fleet
from fleetrun.resources import inputs_dir
from fleetrun.simulation import simulate

FASTSIM_PER_CORE = 90.0  # the reference: FASTSim, UDDS vehicle-cycles per second per core


def make_fleet(n: int, seed: int = 0, kind: str = "example"):
    """``example``: the example fleet's 23 types (LD, MD, HD; the heavy ones fall behind on
    UDDS accelerations and are re-driven); ``cars``: the four light-duty example vehicles of
    fleetrun.testing.vehicles (all follow the trace)."""
    if kind == "cars":
        from fleetrun.testing.vehicles import AWD, CAMRY, CIVIC, F150
        types = [F150, CAMRY, CIVIC, AWD]
    else:
        types = read_fleet(inputs_dir() / "example_fleet.xlsx").vehicles
    return varied(types, n, seed)


def varied(types, n: int, seed: int = 0):
    """``n`` vehicles cycling through ``types``, each with its weight and road-load
    coefficients scaled by its own factor in 0.9-1.1 (physically distinct vehicles)."""
    rng = np.random.default_rng(seed)
    fleet = []
    for i in range(n):
        v = types[i % len(types)]
        f = rng.uniform(0.9, 1.1, 4)
        fleet.append(dataclasses.replace(
            v, vehicle_id=f"{v.vehicle_id}-{i}", test_weight_kg=v.test_weight_kg * f[0],
            coastdown_A_lbf=v.coastdown_A_lbf * f[1], coastdown_B_lbf_per_mph=v.coastdown_B_lbf_per_mph * f[2],
            coastdown_C_lbf_per_mph2=v.coastdown_C_lbf_per_mph2 * f[3]))
    return fleet


# --clock: "wall" (time.perf_counter) or "cpu" (time.process_time: this process's CPU time, which
# other jobs on a shared machine do not inflate by taking the core; cache sharing still may)
CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}


def best_of(fn, repeat, clock: str = "wall"):
    timer = CLOCKS[clock]
    best = float("inf")
    for _ in range(repeat):
        t0 = timer()
        fn()
        best = min(best, timer() - t0)
    return best


def run(vehicles: int, modes, cycle_name: str, repeat: int, single: int, kind: str = "example"):
    cycle = load_cycle(cycle_name)
    fleet = make_fleet(vehicles, kind=kind)
    rows = []
    with tempfile.TemporaryDirectory() as cache:
        for mode in modes:
            t0 = time.perf_counter()
            simulate(fleet, cycle, mode=mode, cache_dir=cache)
            cold = time.perf_counter() - t0
            t_fleet = best_of(lambda: simulate(fleet, cycle, mode=mode, cache_dir=cache), repeat)
            few = fleet[:single]
            t_single = best_of(lambda: [simulate([v], cycle, mode=mode, cache_dir=cache) for v in few], max(1, repeat // 2))
            rows.append(dict(mode=mode, cold_s=cold, fleet_s=t_fleet, fleet_rate=vehicles / t_fleet,
                             single_rate=len(few) / t_single))
    return rows


def machine() -> str:
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return (f"{platform.processor() or platform.machine()}, {os.cpu_count()} logical CPUs, Python "
            f"{platform.python_version()}, numpy {np.__version__}, fleetrun {__version__}; "
            f"load average at start {load:.2f}")


def markdown(rows, args, info) -> str:
    lines = [
        "# Benchmark: drive-cycle simulation",
        "",
        f"`python benchmarks/bench_simulate.py --vehicles {args.vehicles} --cycle {args.cycle} "
        f"--fleet {args.fleet} --repeat {args.repeat}` on {info}.",
        "",
        f"{args.cycle} vehicle-cycle simulations per second (one process, one core; best of {args.repeat}).",
        "",
        f"| mode | {args.vehicles:,} vehicles in one call | one vehicle per call | first call (builds/loads maps) |",
        "|---|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(f"| {r['mode']} | {r['fleet_rate']:,.0f} /s ({r['fleet_s']:.3f} s) | {r['single_rate']:,.0f} /s "
                     f"| {r['cold_s']:.2f} s |")
    lines.append("")
    lines.append(f"For scale: FASTSim about {FASTSIM_PER_CORE:.0f} per second per core (the issue's figure).")
    return "\n".join(lines) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--vehicles", type=int, default=1000)
    p.add_argument("--modes", nargs="+", default=["auto", "map2d", "direct"])
    p.add_argument("--cycle", default="UDDS")
    p.add_argument("--fleet", choices=["example", "cars"], default="example",
                   help="example: the example fleet's 23 LD/MD/HD types; cars: four light-duty cars")
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--single", type=int, default=200, help="vehicles timed one per call")
    p.add_argument("--markdown", help="also write the table here (Markdown)")
    p.add_argument("--block-steps", type=int, help="vehicles x steps per block (fleetrun.simulation.BLOCK_STEPS)")
    args = p.parse_args(argv)
    if args.block_steps:
        import fleetrun.simulation
        fleetrun.simulation.BLOCK_STEPS = args.block_steps
    info = machine()
    rows = run(args.vehicles, args.modes, args.cycle, args.repeat, args.single, args.fleet)
    text = markdown(rows, args, info)
    sys.stdout.write(text)
    if args.markdown:
        with open(args.markdown, "w", encoding="utf-8") as fh:
            fh.write(text)


if __name__ == "__main__":
    main()
