"""Scale checks (slow): a 10,000-row fleet runs to completion from a warm cache, local and dask,
every row written, and 100,000 rows stay memory-bounded. How long they take is measured by
benchmarks/bench_run.py and reported in docs/benchmarks-run.md, not asserted here (a wall-clock
bound fails on a loaded machine without saying anything about the code)."""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
pytestmark = pytest.mark.slow


def run_cli(*args) -> tuple[float, subprocess.CompletedProcess]:
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "fleetrun", "run", *map(str, args), "-q"],
                          capture_output=True, text=True, cwd=ROOT)
    return time.perf_counter() - started, done


@pytest.fixture(scope="module")
def fleets(tmp_path_factory):
    import bench_run

    folder = tmp_path_factory.mktemp("scale")
    return {rows: bench_run.make_fleet(rows, folder / f"fleet_{rows}.xlsx")[0] for rows in (10_000, 100_000)}


@pytest.mark.parametrize("engine", ["local", "dask"])
def test_ten_thousand_rows(fleets, tmp_path, engine):
    if engine == "dask":
        pytest.importorskip("distributed")
    cache = tmp_path / "cache"
    run_cli(fleets[10_000], "--out", tmp_path / "warmup", "--cache-dir", cache, "--engine", engine)
    _, done = run_cli(fleets[10_000], "--out", tmp_path / "out", "--cache-dir", cache, "--engine", engine)
    assert done.returncode == 0, done.stderr
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert manifest["vehicle_types"] == 10_000
    rows = sum(1 for _ in open(tmp_path / "out" / "results.csv")) - 1
    assert rows == 10_000 * len(manifest["scenarios"])


def test_hundred_thousand_rows_local(fleets, tmp_path):
    psutil = pytest.importorskip("psutil")

    process = subprocess.Popen([sys.executable, "-m", "fleetrun", "run", str(fleets[100_000]), "--out",
                                str(tmp_path / "out"), "-q"], cwd=ROOT, stderr=subprocess.PIPE, text=True)
    peak = 0
    handle = psutil.Process(process.pid)
    while process.poll() is None:
        try:
            peak = max(peak, handle.memory_info().rss)
        except psutil.Error:
            pass
        time.sleep(0.1)
    assert process.returncode == 0, process.stderr.read()
    assert peak < 2e9
    assert sum(1 for _ in open(tmp_path / "out" / "results.csv")) == 3 * 100_000 + 1
