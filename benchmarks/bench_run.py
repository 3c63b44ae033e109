"""Benchmark ``fleetrun run``: wall time and peak memory for 1,000 / 10,000 / 100,000 vehicle
rows x 3 scenarios x 4 cycles, on the local and the dask engine.

    python benchmarks/bench_run.py                        # all sizes, both engines
    python benchmarks/bench_run.py --rows 1000 10000 --engines local
    python benchmarks/bench_run.py --markdown docs/benchmarks-run.md

Fleets are the example fleet's 23 vehicle types repeated with varied counts, miles, weights
and road load, and axle ratios drawn from each type's neighbouring standard ratios (real fleets
share a limited set of axle ratios; the simulation builds one map per distinct differential).
Scenarios are the example fleet's three (12 distinct cycle x temperature conditions).

Each run is a separate ``fleetrun run`` process; peak memory is the largest total resident
size of that process and all its children (dask workers included), sampled every 0.1 s.
The map cache is cleared before the first run of each size ("cold") and the run repeated
with it warm when --warm is given.
"""
from __future__ import annotations

import argparse
import os
import platform
import random
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil
from openpyxl import Workbook, load_workbook

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "inputs" / "example_fleet.xlsx"
STANDARD_AXLE_RATIOS = (2.56, 2.64, 2.73, 2.80, 2.85, 3.06, 3.15, 3.21, 3.23, 3.36, 3.42, 3.45, 3.55,
                        3.58, 3.73, 3.91, 4.10, 4.30, 4.41, 4.63, 4.88, 5.29, 5.38, 5.57)


def make_fleet(rows: int, path: Path, variants: int = 10, seed: int = 1) -> tuple[Path, int]:
    """A workbook of ``rows`` vehicle rows derived from the example fleet, and the number of
    physically distinct vehicles in it.

    Each of the example's 23 types gets ``variants`` physical variants (test weight and road
    load within +-5 %, axle ratio one standard step either way), like the model-year and
    option spread of a real fleet; rows (e.g. counties x types) pick a variant and get their
    own count and annual miles. ``variants=0`` makes every row physically distinct (worst case).
    """
    example = load_workbook(EXAMPLE, read_only=True)
    vehicle_rows = list(example["Vehicles"].iter_rows(values_only=True))
    scenario_rows = list(example["Scenarios"].iter_rows(values_only=True))
    header, base = vehicle_rows[0], [r for r in vehicle_rows[1:] if r[0]]
    col = {name: i for i, name in enumerate(header)}
    rng = random.Random(seed)

    def variant(row):
        row = list(row)
        row[col["test_weight_kg"]] = round(row[col["test_weight_kg"]] * rng.uniform(0.95, 1.05), 1)
        for name in ("coastdown_A_lbf", "coastdown_C_lbf_per_mph2"):
            row[col[name]] = round(row[col[name]] * rng.uniform(0.95, 1.05), 5)
        ratio = row[col["final_drive_ratio"]]
        nearest = min(range(len(STANDARD_AXLE_RATIOS)), key=lambda i: abs(STANDARD_AXLE_RATIOS[i] - ratio))
        pick = min(len(STANDARD_AXLE_RATIOS) - 1, max(0, nearest + rng.choice((-1, 0, 0, 1))))
        row[col["final_drive_ratio"]] = STANDARD_AXLE_RATIOS[pick]
        return row

    pool = [[variant(b) for _ in range(variants)] for b in base] if variants else None
    wb = Workbook(write_only=True)
    ws = wb.create_sheet("Vehicles")
    ws.append(header)
    used = set()
    for n in range(rows):
        t = n % len(base)
        if pool:
            k = rng.randrange(variants)
            row = list(pool[t][k])
            used.add((t, k))
        else:
            row = variant(base[t])
            used.add(n)
        row[col["vehicle_id"]] = f"{row[col['vehicle_id']]}-{n:06d}"
        row[col["count"]] = max(1, round(row[col["count"]] / max(1, rows / len(base)) * rng.uniform(0.5, 1.5)))
        row[col["annual_miles"]] = round(row[col["annual_miles"]] * rng.uniform(0.8, 1.2))
        ws.append(row)
    scenarios = wb.create_sheet("Scenarios")
    for row in scenario_rows:
        if any(v is not None for v in row):
            scenarios.append(row)
    wb.save(path)
    return path, len(used)


def workbook_from_args(description: str, keep_help: str, prefix: str) -> tuple[argparse.Namespace, Path, Path]:
    """The ``--rows/--repeat/--keep`` command line of the in-process benchmarks (bench_read,
    bench_report): parsed arguments, the working folder (``--keep`` or a new temporary one) and
    the fleet workbook ``fleet_ROWS.xlsx`` in it, built with :func:`make_fleet` unless it exists."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--rows", type=int, default=100_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--keep", type=Path, help=keep_help)
    args = parser.parse_args()
    folder = args.keep or Path(tempfile.mkdtemp(prefix=prefix))
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"fleet_{args.rows}.xlsx"
    if not path.exists():
        make_fleet(args.rows, path)
    return args, folder, path


def measure(command: list[str], env: dict) -> tuple[float, float, int, str]:
    """(wall seconds, peak tree RSS in MB, exit code, stderr tail) of one command."""
    started = time.perf_counter()
    process = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    parent = psutil.Process(process.pid)
    peak = 0
    while process.poll() is None:
        try:
            procs = [parent] + parent.children(recursive=True)
            total = 0
            for p in procs:
                try:
                    total += p.memory_info().rss
                except psutil.Error:
                    pass
            peak = max(peak, total)
        except psutil.Error:
            pass
        time.sleep(0.1)
    wall = time.perf_counter() - started
    stderr = process.stderr.read()
    return wall, peak / 1e6, process.returncode, stderr.strip().splitlines()[-1] if stderr.strip() else ""


def main():
    parser = argparse.ArgumentParser(description="Benchmark fleetrun run")
    parser.add_argument("--rows", type=int, nargs="+", default=[1000, 10000, 100000])
    parser.add_argument("--engines", nargs="+", default=["local", "dask"])
    parser.add_argument("--mode", default="auto")
    parser.add_argument("--variants", type=int, default=10,
                        help="physical variants per example vehicle type (0: every row distinct)")
    parser.add_argument("--warm", action="store_true", help="also time a second run with the map cache warm")
    parser.add_argument("--markdown", type=Path, help="write the results table to this file")
    args = parser.parse_args()

    work = Path(tempfile.mkdtemp(prefix="fleetrun-bench-"))
    cache = work / "cache"
    env = {**os.environ, "FLEETRUN_CACHE_DIR": str(cache)}
    results = []
    try:
        for rows in args.rows:
            built = time.perf_counter()
            fleet, distinct = make_fleet(rows, work / f"fleet_{rows}.xlsx", args.variants)
            print(f"{rows} rows ({distinct} distinct vehicles): workbook built in "
                  f"{time.perf_counter() - built:.1f} s ({fleet.stat().st_size / 1e6:.1f} MB)", flush=True)
            for engine in args.engines:
                shutil.rmtree(cache, ignore_errors=True)
                passes = ["cold", "warm"] if args.warm else ["cold"]
                for state in passes:
                    out = work / f"out_{rows}_{engine}_{state}"
                    command = [sys.executable, "-m", "fleetrun", "run", str(fleet), "--out", str(out),
                               "--engine", engine, "--mode", args.mode, "-q"]
                    wall, peak, code, tail = measure(command, env)
                    results.append({"rows": rows, "distinct": distinct, "engine": engine, "cache": state, "wall_s": wall,
                                    "peak_mb": peak, "exit": code, "note": tail})
                    print(f"  {engine:5s} {state}: {wall:7.1f} s, peak {peak:7.0f} MB, exit {code} {tail}",
                          flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)

    if args.markdown:
        lines = [
            "| vehicle rows | distinct vehicles | engine | map cache | wall time [s] | peak memory [MB] | exit |",
            "|---:|---:|---|---|---:|---:|---:|",
        ]
        for r in results:
            lines.append(f"| {r['rows']:,} | {r['distinct']:,} | {r['engine']} | {r['cache']} | {r['wall_s']:.1f} | "
                         f"{r['peak_mb']:.0f} | {r['exit']} |")
        machine = (f"{platform.processor() or platform.machine()}, {psutil.cpu_count()} CPUs, "
                   f"{psutil.virtual_memory().total / 1e9:.0f} GB RAM, Python {platform.python_version()}")
        text = "\n".join(lines)
        print(text)
        args.markdown.write_text(args.markdown.read_text().replace("<!-- results -->", f"<!-- results -->\n\nMachine: {machine}; mode `{args.mode}`.\n\n{text}\n")
                                 if args.markdown.exists() and "<!-- results -->" in args.markdown.read_text()
                                 else text + "\n")


if __name__ == "__main__":
    main()
