"""End to end beside FASTSim 3.1: ``fleetrun run`` of a 7,600-row EPA fleet as a user runs it
(process start, imports, reading, simulating, aggregating, all seven outputs), one core.

    pip install fastsim==3.1.0
    python benchmarks/bench_end_to_end.py [--rows 7600] [--repeat 3] [--fastsim-runs 30] [--trees DIR...] [--split]

``--trees`` times the fleetrun of other source trees too (e.g. an older commit exported with
``git archive``), round by round beside this one. ``--split`` prints instead where the command's
CPU goes (interpreter start, imports, reading, simulating, aggregating, writing), per tree.

- The fleet: ``fleetrun import-epa inputs/epa/22-tstcar.csv`` (1,103 vehicle configurations of the
  EPA 2022 Test Car List), its rows repeated to ``--rows`` rows, each with its own test weight
  (x 0.95-1.05), so every row is a different vehicle and is simulated (none is deduplicated);
  one scenario driving UDDS only (FASTSim's benchmark cycle).
- fleetrun: wall time of ``python -m fleetrun run FLEET --out DIR -q`` (a new process each time,
  warm map cache, its modules' bytecode compiled in the warm-up run as an installed package's is, pinned to one CPU with ``taskset`` where there is one, OMP_NUM_THREADS=1);
  rate = rows / wall time (vehicle-UDDS runs per second, everything included).
- FASTSim 3.1: its own 2012 Ford Fusion over its own UDDS in a loop (bench_fastsim.py), pinned
  alike; runs per second. The two alternate, so a load change hits both.

The ratio fleetrun / FASTSim is the figure (README, docs/benchmarks-run.md). Each round also gives
the ratio by CPU time (user + system of the fleetrun process; FASTSim's process time per run),
which a machine shared with other work slows less than the wall time.
"""
from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from openpyxl import load_workbook

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

LIST = ROOT / "inputs" / "epa" / "22-tstcar.csv"
SCENARIO = {"scenario_id": "udds", "description": "UDDS only (FASTSim's benchmark cycle)", "ambient_temp_C": 20,
            "cycle_mix": "UDDS:1", "budget_years": 2, "vmt_growth_pct_per_year": 1.0,
            "state_tax_gasoline_usd_per_gal": 0.2, "state_tax_diesel_usd_per_gal": 0.2,
            "federal_tax_gasoline_usd_per_gal": 0.184, "federal_tax_diesel_usd_per_gal": 0.244}


def pinned(command: list[str]) -> list[str]:
    """``command`` on one CPU (taskset), where the system has taskset."""
    return ["taskset", "-c", "0", *command] if shutil.which("taskset") else command


def make_fleet(rows: int, folder: Path, env: dict, seed: int = 1) -> Path:
    """The EPA list imported, its rows repeated to ``rows`` distinct vehicles, one UDDS scenario."""
    imported = folder / "epa.xlsx"
    subprocess.run([sys.executable, "-m", "fleetrun", "import-epa", str(LIST), "-o", str(imported), "--force"], check=True,
                   cwd=ROOT, env=env, capture_output=True)
    wb = load_workbook(imported)
    ws = wb["Vehicles"]
    header = [c.value for c in ws[1]]
    base = [list(r) for r in ws.iter_rows(min_row=2, values_only=True) if r[0]]
    ident, weight = header.index("vehicle_id"), header.index("test_weight_kg")
    rng = random.Random(seed)
    ws.delete_rows(2, ws.max_row)
    for n in range(rows):
        row = list(base[n % len(base)])
        row[ident] = f"{row[ident]}-{n:05d}"
        row[weight] = round(row[weight] * rng.uniform(0.95, 1.05), 2)
        ws.append(row)
    scenarios = wb["Scenarios"]
    names = [c.value for c in scenarios[1]]
    scenarios.delete_rows(2, scenarios.max_row)
    scenarios.append([SCENARIO.get(name) for name in names])
    path = folder / f"epa_{rows}.xlsx"
    wb.save(path)
    return path


def fleetrun_seconds(fleet: Path, out: Path, env: dict, tree: Path = ROOT) -> tuple[float, float]:
    """(wall, CPU user + system) seconds of one ``fleetrun run`` process."""
    shutil.rmtree(out, ignore_errors=True)
    env = {**env, "PYTHONPATH": str(tree)}
    started, children = time.perf_counter(), os.times()
    done = subprocess.run(pinned([sys.executable, "-m", "fleetrun", "run", str(fleet), "--out", str(out), "-q"]),
                          cwd=tree, env=env, capture_output=True, text=True)
    elapsed, after = time.perf_counter() - started, os.times()
    if done.returncode != 0:
        raise SystemExit(f"fleetrun run failed ({done.returncode}):\n{done.stderr}")
    return elapsed, (after.children_user - children.children_user) + (after.children_system - children.children_system)


FASTSIM = """
import sys, time
sys.path.insert(0, {bench!r})
from bench_fastsim import fastsim_runner
once, version = fastsim_runner()
once()
best = best_cpu = float("inf")
for _ in range({repeat}):
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range({runs}):
        once()
    best = min(best, (time.perf_counter() - t0) / {runs})
    best_cpu = min(best_cpu, (time.process_time() - c0) / {runs})
print(version, 1.0 / best, 1.0 / best_cpu)
"""


def fastsim_rate(runs: int, env: dict) -> tuple[str, float, float]:
    """FASTSim's UDDS runs per second of wall time and per second of CPU time (best batch), in
    its own pinned process."""
    code = FASTSIM.format(bench=str(ROOT / "benchmarks"), repeat=2, runs=runs)
    done = subprocess.run(pinned([sys.executable, "-c", code]), cwd=ROOT, env=env, capture_output=True, text=True,
                          check=True)
    version, rate, cpu_rate = done.stdout.split()
    return version, float(rate), float(cpu_rate)


SPLIT = """
import json, resource, sys, time
def cpu():
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime
marks = {{"start": cpu()}}
argv = ["run", {fleet!r}, "--out", {out!r}, "-q"]
from fleetrun import cli
if hasattr(cli, "_collect_less"):
    cli._collect_less(argv)        # what the console entry point does first (GC settings, the command's modules)
else:
    import fleetrun.commands.run
from fleetrun.run import batch, runner
marks["imports"] = cpu()
read, run, write = batch.read_fleet, batch.run_fleet, batch.write_run_outputs
def timed_read(*args, **kwargs):
    try:
        return read(*args, **kwargs)
    finally:
        marks["read"] = cpu()
def timed_run(*args, **kwargs):
    result = run(*args, **kwargs)
    marks.update(result.timings_s)  # CPU seconds: run_fleet's clock is the process clock here
    return result
def timed_write(*args, **kwargs):
    started = cpu()
    try:
        return write(*args, **kwargs)
    finally:
        marks["write"] = cpu() - started
batch.read_fleet, batch.run_fleet, batch.write_run_outputs = timed_read, timed_run, timed_write
runner.time = type("ProcessClock", (), {{"perf_counter": staticmethod(time.process_time)}})
try:
    cli.main(argv)
except SystemExit as exc:
    if exc.code:
        raise
marks["total"] = cpu()
print(json.dumps(marks))
"""
SPLIT_STAGES = ("start", "imports", "read", "simulate", "aggregate", "write", "other", "total")


def cpu_split(fleet: Path, out: Path, env: dict, tree: Path) -> dict[str, float]:
    """CPU seconds of one ``fleetrun run`` process by stage (a new pinned process, the command's
    own path through ``fleetrun.cli.main``): interpreter start, imports, reading, simulating,
    aggregating, writing the outputs, the rest, and the total."""
    shutil.rmtree(out, ignore_errors=True)
    done = subprocess.run(pinned([sys.executable, "-c", SPLIT.format(fleet=str(fleet), out=str(out))]), cwd=tree,
                          env={**env, "PYTHONPATH": str(tree)}, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"fleetrun run (split) failed ({done.returncode}):\n{done.stderr}")
    marks = json.loads(done.stdout.strip().splitlines()[-1])
    split = {"start": marks["start"], "imports": marks["imports"] - marks["start"],
             "read": marks["read"] - marks["imports"], "simulate": marks["simulate"],
             "aggregate": marks["aggregate"], "write": marks["write"], "total": marks["total"]}
    split["other"] = split["total"] - sum(v for k, v in split.items() if k != "total")
    return split


def print_splits(fleet: Path, folder: Path, env: dict, trees: list[Path], repeat: int) -> None:
    """Per tree the CPU split of its fastest of ``repeat`` runs (trees alternating)."""
    best: dict[Path, dict] = {}
    for _ in range(repeat):
        for tree in trees:
            split = cpu_split(fleet, folder / "out", env, tree)
            if tree not in best or split["total"] < best[tree]["total"]:
                best[tree] = split
    print("CPU seconds by stage (fastest of %d runs each): " % repeat + " / ".join(SPLIT_STAGES), flush=True)
    for tree, split in best.items():
        print(f"  {tree}: " + " / ".join(f"{split[k]:.2f}" for k in SPLIT_STAGES), flush=True)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rows", type=int, default=7600)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--fastsim-runs", type=int, default=30)
    p.add_argument("--trees", type=Path, nargs="*", default=[], help="other fleetrun source trees to time alike")
    p.add_argument("--split", action="store_true",
                   help="only the command's CPU by stage (start, imports, read, simulate, aggregate, write), no FASTSim")
    args = p.parse_args(argv)
    folder = Path(tempfile.mkdtemp(prefix="fleetrun-e2e-"))
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
           "FLEETRUN_CACHE_DIR": str(folder / "cache"), "PYTHONPATH": str(ROOT),
           # compiled once in the warm-up run, as an installed package is (pip compiles it)
           "PYTHONPYCACHEPREFIX": str(folder / "pycache")}
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    try:
        fleet = make_fleet(args.rows, folder, env)
        trees = [ROOT, *args.trees]
        for tree in trees:
            fleetrun_seconds(fleet, folder / "out", env, tree)    # builds the maps (cold cache)
        print(f"load average at start {os.getloadavg()[0]:.2f}; {args.rows} rows, UDDS, one CPU", flush=True)
        if args.split:
            print_splits(fleet, folder, env, trees, args.repeat)
            return
        for k in range(args.repeat):
            version, fs_rate, fs_cpu_rate = fastsim_rate(args.fastsim_runs, env)
            for tree in trees:
                seconds, cpu = fleetrun_seconds(fleet, folder / "out", env, tree)
                rate, cpu_rate = args.rows / seconds, args.rows / cpu
                print(f"  round {k + 1}, {tree}: fleetrun run {seconds:.2f} s = {rate:,.0f} vehicle-UDDS/s; FASTSim "
                      f"{version} {fs_rate:,.1f} /s; ratio {rate / fs_rate:.1f}x; by CPU time: fleetrun {cpu:.2f} s = "
                      f"{cpu_rate:,.0f} /s, FASTSim {fs_cpu_rate:,.1f} /s, ratio {cpu_rate / fs_cpu_rate:.1f}x; "
                      f"load {os.getloadavg()[0]:.2f}", flush=True)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
