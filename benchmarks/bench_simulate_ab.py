"""A/B benchmark of ``simulate`` between two checkouts, by CPU time (for a shared machine).

    python benchmarks/bench_simulate_ab.py BEFORE_CHECKOUT AFTER_CHECKOUT [MORE ...] [--vehicles 1000]
                                           [--rounds 3] [--fleets cars example]

Each checkout is timed in its own process, the checkouts in turn, ``--rounds`` times; each
process builds its map cache in a fresh folder, then reports the best of five ``simulate``
calls of the fleet (``bench_simulate.make_fleet``, 1,000 vehicles, UDDS, mode auto) in
process CPU time, which a loaded machine disturbs less than wall time.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys

CHILD = r"""
import sys, tempfile, time
sys.path.insert(0, sys.argv[1])
sys.path.insert(0, sys.argv[1] + "/benchmarks")
from bench_simulate import make_fleet
from fleetrun.cycles import load_cycle
from fleetrun.simulation import simulate
fleet, cycle, cache = make_fleet(int(sys.argv[3]), kind=sys.argv[2]), load_cycle("UDDS"), tempfile.mkdtemp()
simulate(fleet, cycle, mode="auto", cache_dir=cache)
best = 1e9
for _ in range(5):
    t = time.process_time()
    simulate(fleet, cycle, mode="auto", cache_dir=cache)
    best = min(best, time.process_time() - t)
print(f"{len(fleet) / best:.0f}")
"""


def rate(checkout: str, kind: str, vehicles: int) -> int:
    env = dict(os.environ, PYTHONPATH=checkout, OMP_NUM_THREADS="1")
    out = subprocess.run([sys.executable, "-c", CHILD, checkout, kind, str(vehicles)], env=env,
                         capture_output=True, text=True, check=True, cwd=checkout)
    return int(out.stdout.strip())


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("checkouts", nargs="+", help="two or more checkouts (BEFORE AFTER ...), timed in turn")
    p.add_argument("--vehicles", type=int, default=1000)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--fleets", nargs="+", choices=("cars", "example"), default=("cars", "example"))
    args = p.parse_args(argv)
    runs = {(checkout, kind): [] for checkout in args.checkouts for kind in args.fleets}
    for _ in range(args.rounds):
        for checkout in args.checkouts:
            for kind in args.fleets:
                runs[(checkout, kind)].append(rate(checkout, kind, args.vehicles))
    print(f"| fleet | {' | '.join(f'{c} (best; all)' for c in args.checkouts)} |\n"
          f"|---|{'---:|' * len(args.checkouts)}")
    for kind in args.fleets:
        cells = [f"{max(r):,} /s; {', '.join(map(str, r))}" for r in (runs[(c, kind)] for c in args.checkouts)]
        print(f"| {kind} | {' | '.join(cells)} |")


if __name__ == "__main__":
    main()
