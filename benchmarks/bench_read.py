"""Benchmark reading and checking a fleet workbook (``fleetrun.workbook.read_fleet``).

    python benchmarks/bench_read.py [--rows 100000] [--repeat 3] [--keep DIR]

Builds a workbook of ROWS vehicle rows from the example fleet (``bench_run.make_fleet``, the
same fleet the run benchmark uses), then times ``read_fleet`` on it REPEAT times in this
process and prints the best and the median wall time and the peak Python heap (tracemalloc
is off for the timings and on for one extra pass).
"""
from __future__ import annotations

import statistics
import sys
import time
import tracemalloc
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_run import workbook_from_args  # noqa: E402

from fleetrun.workbook import read_fleet  # noqa: E402


def main():
    args, _, path = workbook_from_args("Benchmark reading a fleet workbook",
                                       "build (or reuse) the workbook in this folder", "fleetrun-bench-read-")
    print(f"{path} ({path.stat().st_size / 1e6:.1f} MB, {args.rows} vehicle rows)")
    times = []
    for _ in range(args.repeat):
        started = time.perf_counter()
        fleet = read_fleet(path)
        times.append(time.perf_counter() - started)
        print(f"  read_fleet: {times[-1]:.2f} s ({len(fleet.vehicles)} vehicles)", flush=True)
    tracemalloc.start()
    read_fleet(path)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(f"best {min(times):.2f} s, median {statistics.median(times):.2f} s; "
          f"peak Python heap {peak / 1e6:.0f} MB")


if __name__ == "__main__":
    main()
