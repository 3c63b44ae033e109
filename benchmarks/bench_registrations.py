"""Registration extracts at scale (docs/registrations.md, "Scale").

    python benchmarks/bench_registrations.py [--rows 50000] [--vehicles 5000000] [--lines 1000000] [--keep DIR]

1. A make/model/model-year extract of ``--rows`` lines holding ``--vehicles`` vehicles (makes
   and models of the EPA 2022 Test Car List and some the list does not have; model years
   1985-2024; seeded), end to end: ``fleetrun import-registrations`` then ``fleetrun run``,
   each timed as a separate process (wall clock, as an analyst would see it).
2. A per-vehicle extract of ``--lines`` lines read by ``fleetrun.registrations.extract`` in a
   fresh process: time and peak resident memory (ru_maxrss), beside the file's size.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def make_models() -> pd.DataFrame:
    from fleetrun.epa.reader import read_test_car_list

    table = read_test_car_list(ROOT / "inputs" / "epa" / "22-tstcar.csv")
    pairs = table[["make", "model", "vehicle_type"]].dropna().drop_duplicates(["make", "model"])
    pairs["vehicle_class"] = np.where(pairs["vehicle_type"].astype(str).str.lower().str.contains("car"),
                                      "automobile", "light_truck")
    unknown = pd.DataFrame({"make": [f"Make{i}" for i in range(500)], "model": [f"Model{i}" for i in range(500)],
                            "vehicle_class": ["automobile", "light_truck"] * 250})
    return pd.concat([pairs[["make", "model", "vehicle_class"]], unknown], ignore_index=True)


def make_extract(path: Path, rows: int, vehicles: int, seed: int = 19) -> None:
    rng = np.random.default_rng(seed)
    models = make_models()
    years = np.arange(1985, 2025)
    grid = pd.DataFrame({"m": np.repeat(np.arange(len(models)), len(years)), "model_year": np.tile(years, len(models))})
    pick = grid.sample(n=min(rows, len(grid)), random_state=seed, replace=rows > len(grid)).reset_index(drop=True)
    out = models.iloc[pick["m"]].reset_index(drop=True)
    out["model_year"] = pick["model_year"]
    out["fuel"] = np.where(rng.random(len(out)) < 0.02, "diesel", "gasoline")
    weights = rng.gamma(1.0, 1.0, len(out)) * np.exp(-(2024 - out["model_year"].to_numpy()) / 12.0)
    out["count"] = np.maximum(1, np.round(weights / weights.sum() * vehicles)).astype(int)
    out[["vehicle_class", "make", "model", "model_year", "fuel", "count"]].to_csv(path, index=False)


def make_per_vehicle(path: Path, lines: int, seed: int = 20) -> None:
    rng = np.random.default_rng(seed)
    models = make_models()
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("vin,vehicle_class,make,model,model_year,fuel,county\n")
        for start in range(0, lines, 200_000):
            n = min(200_000, lines - start)
            m = models.iloc[rng.integers(0, len(models), n)]
            chunk = pd.DataFrame({"vin": [f"V{start + i:09d}" for i in range(n)], "vehicle_class": m["vehicle_class"].to_numpy(),
                                  "make": m["make"].to_numpy(), "model": m["model"].to_numpy(),
                                  "model_year": rng.integers(1985, 2025, n), "fuel": "gasoline",
                                  "county": rng.integers(1, 255, n)})
            chunk.to_csv(fh, index=False, header=False)


def timed(cmd: list[str]) -> float:
    started = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    return time.perf_counter() - started


BASELINE = """
import resource, sys
sys.path.insert(0, {root!r})
import fleetrun.registrations.extract
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""
READ_ONLY = """
import resource, sys, time
sys.path.insert(0, {root!r})
from fleetrun.registrations.extract import read_extract
t = time.perf_counter()
frame = read_extract({path!r})
print(time.perf_counter() - t, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, len(frame), frame['count'].sum())
"""


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=50_000)
    parser.add_argument("--vehicles", type=int, default=5_000_000)
    parser.add_argument("--lines", type=int, default=1_000_000)
    parser.add_argument("--keep", type=Path, default=None)
    args = parser.parse_args(argv)
    folder = args.keep or Path(tempfile.mkdtemp(prefix="bench-registrations-"))
    folder.mkdir(parents=True, exist_ok=True)
    extract, workbook = folder / "extract.csv", folder / "fleet.xlsx"
    make_extract(extract, args.rows, args.vehicles)
    counts = pd.read_csv(extract)["count"]
    print(f"extract: {len(counts):,} make/model/year rows, {counts.sum():,} vehicles")
    py = [sys.executable, "-m", "fleetrun"]
    t_import = timed(py + ["import-registrations", str(extract), "-o", str(workbook), "--first-fiscal-year", "2027",
                           "--base-year-vmt-million", "60000"])
    t_run = timed(py + ["run", str(workbook), "--out", str(folder / "out"), "--replace"])
    print(f"import-registrations {t_import:.1f} s, run {t_run:.1f} s, end to end {t_import + t_run:.1f} s")
    per_vehicle = folder / "per_vehicle.csv"
    make_per_vehicle(per_vehicle, args.lines)
    out = subprocess.run([sys.executable, "-c", READ_ONLY.format(root=str(ROOT), path=str(per_vehicle))],
                         check=True, capture_output=True, text=True).stdout.split()
    size_mb = per_vehicle.stat().st_size / 1e6
    baseline = subprocess.run([sys.executable, "-c", BASELINE.format(root=str(ROOT))], check=True,
                              capture_output=True, text=True).stdout.split()
    print(f"a fresh process with pandas and the reader imported: {int(baseline[0]) / 1024:.0f} MB resident")
    print(f"per-vehicle extract: {args.lines:,} lines ({size_mb:.0f} MB) read in {float(out[0]):.1f} s, "
          f"peak resident memory {int(out[1]) / 1024:.0f} MB, {int(out[2]):,} distinct rows, {float(out[3]):,.0f} vehicles")


if __name__ == "__main__":
    main()
