"""FASTSim 3.1 beside fleetrun, in one process: UDDS vehicle-cycle simulations per second, one core.

    pip install fastsim==3.1.0
    OMP_NUM_THREADS=1 python benchmarks/bench_fastsim.py [--repeat 5] [--fastsim-runs 30]

- FASTSim 3.1: its own 2012 Ford Fusion (``Vehicle.from_resource("2012_Ford_Fusion.yaml")``)
  over its own UDDS (``Cycle.from_resource("udds.csv")``), ``SimDrive(veh, cyc).walk()`` in a
  loop, per-step history off (``set_save_interval(None)``: FASTSim's fastest setting); the
  rate is runs / time of the best of ``--repeat`` batches of ``--fastsim-runs``.
- fleetrun: 1,000 light-duty cars (``bench_simulate.make_fleet(1000, kind="cars")``: the four
  example cars of fleetrun.testing.vehicles with varied weight and road load) over UDDS in one
  ``simulate`` call (mode auto = map3d, warm map cache), best of ``--repeat``.

The two timings alternate batch by batch, so a load change on the shared machine hits both.
The ratio is the figure to compare (README, docs/benchmarks-simulation.md). ``--clock cpu``
times both by this process's CPU time instead of the wall clock (FASTSim runs in the same
thread): steadier when other jobs share the cores.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench_simulate import CLOCKS, machine, make_fleet  # noqa: E402

from fleetrun.cycles import load_cycle  # noqa: E402
from fleetrun.simulation import simulate  # noqa: E402


def fastsim_runner():
    """A function that drives FASTSim's 2012 Ford Fusion over UDDS once (history off)."""
    import fastsim as fsim

    veh = fsim.Vehicle.from_resource("2012_Ford_Fusion.yaml")
    veh.set_save_interval(None)
    cyc = fsim.Cycle.from_resource("udds.csv")

    def once():
        sd = fsim.SimDrive(veh, cyc)
        sd.walk()
        return sd
    return once, fsim.__version__


def measure(repeat: int, fastsim_runs: int, vehicles: int = 1000, technology: str | None = None,
            clock: str = "wall"):
    once, version = fastsim_runner()
    once()                                                   # warm up (loads, JIT-free Rust)
    fleet = make_fleet(vehicles, kind="cars")
    if technology:   # the technology classes' physics on every car (docs/simulation.md "Technology")
        fleet = [dataclasses.replace(v, technology=technology) for v in fleet]
    cycle = load_cycle("UDDS")
    best_fs, best_fr = float("inf"), float("inf")
    timer = CLOCKS[clock]
    with tempfile.TemporaryDirectory() as cache:
        simulate(fleet, cycle, cache_dir=cache)              # builds the maps once
        for _ in range(repeat):
            t0 = timer()
            for _ in range(fastsim_runs):
                once()
            best_fs = min(best_fs, (timer() - t0) / fastsim_runs)
            t0 = timer()
            simulate(fleet, cycle, cache_dir=cache)
            best_fr = min(best_fr, (timer() - t0) / vehicles)
    return dict(fastsim_version=version, fastsim_rate=1.0 / best_fs, fleetrun_rate=1.0 / best_fr,
                ratio=best_fs / best_fr, vehicles=vehicles)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--fastsim-runs", type=int, default=30)
    p.add_argument("--technology", help="technology column for every fleetrun car, e.g. "
                   "start_stop,mild_hybrid_48v,atkinson,cylinder_deactivation,turbo")
    p.add_argument("--clock", choices=sorted(CLOCKS), default="wall", help="wall clock or this process's CPU time")
    args = p.parse_args(argv)
    info = machine()
    r = measure(args.repeat, args.fastsim_runs, technology=args.technology, clock=args.clock)
    print(f"{info}\nUDDS, one core, best of {args.repeat} ({args.clock} clock):\n"
          f"  FASTSim {r['fastsim_version']} 2012 Ford Fusion: {r['fastsim_rate']:,.1f} vehicle-cycles/s\n"
          f"  fleetrun, {r['vehicles']:,} cars in one call (technology: {args.technology or 'none'}): "
          f"{r['fleetrun_rate']:,.0f} vehicle-cycles/s\n"
          f"  ratio fleetrun / FASTSim: {r['ratio']:,.0f}x")


if __name__ == "__main__":
    main()
