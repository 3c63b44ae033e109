"""Benchmark heavy- against light-duty simulation speed per vehicle-cycle (issue 21).

    python benchmarks/bench_heavy_vs_light.py [--vehicles 200] [--repeat 3] [--cycles HWFET,HD-UDDS,UDDS]

The example fleet's light-duty types (inputs/example_fleet.xlsx, duty LD) and its medium and
heavy diesel types (MD/HD), each repeated to ``--vehicles`` rows with test weight and road load
varied by up to +-10 % (bench_simulate.make_fleet's rule), simulated in one ``simulate`` call per
cycle (arrays over vehicles, as the fleet runner does), mode ``auto`` with a warm map cache.
Reported: best of ``--repeat`` wall times, microseconds per vehicle-cycle, and the heavy / light
ratio per cycle. On UDDS the heavy vehicles fall behind the trace and are re-driven (their
real cost on a light-duty cycle); HWFET and HD-UDDS both duty classes can follow.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile


sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
# this checkout's fleetrun, not an installed copy (as bench_fastsim.py)
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from bench_simulate import CLOCKS, best_of, machine, varied as fleet_of  # noqa: E402

from fleetrun.cycles import load_cycle  # noqa: E402
from fleetrun.resources import inputs_dir  # noqa: E402
from fleetrun.simulation import simulate  # noqa: E402
from fleetrun.workbook.reader import read_fleet  # noqa: E402


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vehicles", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--cycles", default="HWFET,HD-UDDS,UDDS")
    parser.add_argument("--clock", choices=sorted(CLOCKS), default="wall",
                        help="wall clock or this process's CPU time (steadier on a shared machine)")
    args = parser.parse_args(argv)
    vehicles = read_fleet(inputs_dir() / "example_fleet.xlsx").vehicles
    groups = {"light": [v for v in vehicles if v.duty_class == "LD" and v.fuel != "electric"],
              "heavy": [v for v in vehicles if v.duty_class in ("MD", "HD") and v.fuel == "diesel"]}
    fleets = {k: fleet_of(types, args.vehicles) for k, types in groups.items()}
    print(f"{machine()}\n{len(groups['light'])} light and {len(groups['heavy'])} heavy types, {args.vehicles} rows "
          f"each, best of {args.repeat} ({args.clock} clock)")
    print("| cycle | light us/vehicle-cycle | heavy us/vehicle-cycle | heavy / light | heavy rows re-driven |")
    print("|---|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as cache:
        for name in args.cycles.split(","):
            cycle = load_cycle(name)
            per = {}
            for kind, fleet in fleets.items():
                result = simulate(fleet, cycle, cache_dir=cache)   # builds the maps (cold), not timed
                per[kind] = best_of(lambda: simulate(fleet, cycle, cache_dir=cache), args.repeat, args.clock) / len(fleet) * 1e6
                behind = float((result.shortfall_time_s > 0).mean())
            print(f"| {name} | {per['light']:.0f} | {per['heavy']:.0f} | {per['heavy'] / per['light']:.2f} | {behind:.0%} |")


if __name__ == "__main__":
    main()
