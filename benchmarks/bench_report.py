"""Benchmark writing ``report.xlsx`` alone (``fleetrun.reports.xlsx.write_report_xlsx``).

    python benchmarks/bench_report.py [--rows 100000] [--repeat 3] [--keep DIR]

Builds the fleet of ``bench_run.make_fleet`` (ROWS vehicle rows x the example's 3 scenarios),
runs it once (local engine, map cache in DIR, so a second invocation is warm), then times
``write_report_xlsx`` REPEAT times and, for scale, ``results.csv`` (``outputs.write_csv``).
Prints the best and median wall time of each and the size of the report.
"""
from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_run import workbook_from_args  # noqa: E402

from fleetrun.workbook import read_fleet  # noqa: E402
from fleetrun.run.outputs import write_csv  # noqa: E402
from fleetrun.reports.xlsx import write_report_xlsx  # noqa: E402
from fleetrun.run.runner import run_fleet  # noqa: E402


def _timed(function, repeat: int) -> list[float]:
    times = []
    for _ in range(repeat):
        started = time.perf_counter()
        function()
        times.append(time.perf_counter() - started)
    return times


def main():
    args, folder, path = workbook_from_args("Benchmark writing report.xlsx",
                                            "build (or reuse) the workbook and map cache in this folder",
                                            "fleetrun-bench-report-")
    result = run_fleet(read_fleet(path), cache_dir=str(folder / "cache"))
    report, csv = folder / "report.xlsx", folder / "results.csv"
    print(f"{args.rows} vehicle rows, {len(result.results)} result rows x {len(result.results.columns)} columns")
    for name, function in (("report.xlsx", lambda: write_report_xlsx(result, report)),
                           ("results.csv", lambda: write_csv(result.results, csv))):
        times = _timed(function, args.repeat)
        target = report if name == "report.xlsx" else csv
        print(f"  {name}: best {min(times):.2f} s, median {statistics.median(times):.2f} s "
              f"({target.stat().st_size / 1e6:.1f} MB)", flush=True)


if __name__ == "__main__":
    main()
