"""Benchmark the issue-10 done-when: ``fleetrun import-epa inputs/epa/22-tstcar.csv -o fleet.xlsx
&& fleetrun run fleet.xlsx`` on the whole 2022 list, and the same run over three cycles.

    python benchmarks/bench_epa_import.py                 # prints a Markdown table
    python benchmarks/bench_epa_import.py --repeat 3

Each step is a separate ``fleetrun`` process (what a user runs), timed by wall clock, one
thread (OMP_NUM_THREADS=1). The map cache is a fresh temporary folder: the first run builds
the maps ("cold", what a clean clone does), the second finds them ("warm"). The three-cycle
run replaces the workbook's scenario mix by FTP, HWFET and US06 (the three tests of the list).
"""
from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from openpyxl import load_workbook

ROOT = Path(__file__).resolve().parents[1]
LIST = ROOT / "inputs" / "epa" / "22-tstcar.csv"
THREE_CYCLES = "FTP:0.43,HWFET:0.4,US06:0.17"


def fleetrun(*args, env) -> float:
    """Wall time [s] of one ``python -m fleetrun ...`` process (fails loudly on a non-zero exit)."""
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "fleetrun", *map(str, args)], env=env, cwd=ROOT,
                          capture_output=True, text=True)
    elapsed = time.perf_counter() - started
    if done.returncode != 0:
        raise SystemExit(f"fleetrun {' '.join(map(str, args))} failed ({done.returncode}):\n{done.stderr}")
    return elapsed


def three_cycle_copy(fleet: Path, path: Path) -> Path:
    book = load_workbook(fleet)
    sheet = book["Scenarios"]
    column = [c.value for c in sheet[1]].index("cycle_mix") + 1
    sheet.cell(row=2, column=column, value=THREE_CYCLES)
    book.save(path)
    return path


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=1, help="repeat the whole sequence (min is reported)")
    args = parser.parse_args(argv)
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(ROOT))
    env.pop("FLEETRUN_CACHE_DIR", None)
    rows: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory(prefix="bench-epa-") as tmp:
        tmp = Path(tmp)
        for k in range(args.repeat):
            cache = tempfile.mkdtemp(dir=tmp, prefix="maps-")   # empty: the first run builds the maps
            fleet, three = tmp / "fleet.xlsx", tmp / "fleet3.xlsx"
            steps = [
                ("import-epa (whole 2022 list)", ("import-epa", LIST, "-o", fleet, "--measured-out", tmp / "m.csv", "--force")),
                ("run, default scenario (FTP + HWFET), cold map cache", ("run", fleet, "--out", tmp / f"o1-{k}")),
                ("run, default scenario, warm map cache", ("run", fleet, "--out", tmp / f"o2-{k}")),
                ("run, FTP + HWFET + US06, warm map cache", ("run", three, "--out", tmp / f"o3-{k}")),
            ]
            for label, step in steps:
                if step[1] == three and not three.exists():
                    three_cycle_copy(fleet, three)
                extra = ("--cache-dir", cache, "-q") if step[0] == "run" else ()
                rows.setdefault(label, []).append(fleetrun(*step, *extra, env=env))
        vehicles = sum(1 for r in load_workbook(fleet, read_only=True)["Vehicles"].iter_rows(min_row=2) if r[0].value)
    print(f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}; "
          f"{vehicles} vehicles modelled; best of {args.repeat}\n")
    print("| step | wall time [s] |\n|---|---|")
    for label, times in rows.items():
        print(f"| {label} | {min(times):.1f} |")


if __name__ == "__main__":
    main()
