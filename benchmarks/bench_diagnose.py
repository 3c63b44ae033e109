"""Benchmark: `fleetrun diagnose` on a 1-hour, 10 Hz recording (issue 11: under 10 s) and
`fleetrun diagnose-fleet` on the whole EPA 2022 Test Car List (issue 11: under 2 min).

    python benchmarks/bench_diagnose.py [--repeat 3] [--fleet]

The recording is generated with fleetrun.testing.recordings (two hidden effects, AR(1) noise,
offsets); the timed path is the whole command: reading and checking the CSV, baseline,
locating, selection with 200 circular shifts, the open-world review, integrals, JSON and HTML.
With ``--fleet`` the EPA list is imported first (``fleetrun import-epa``, not timed) and the
whole ``diagnose-fleet`` is timed (simulation of every vehicle on the UDDS bags, FTP, HWFET and
US06 with a warm map cache after the first run, selection, unexplained, JSON and HTML).
Prints one JSON line per benchmark.
"""
from __future__ import annotations

import argparse
import json
import platform
import tempfile
import time
from pathlib import Path

from fleetrun.diagnose import diagnose
from fleetrun.testing.recordings import random_case


def _machine() -> dict:
    return {"machine": platform.processor() or platform.machine(), "python": platform.python_version()}


def recording(repeat: int, duration_s: float, rate_hz: float) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        rec = random_case(["oil_warmup", "cornering"], 7, duration_s=duration_s, rate_hz=rate_hz)
        path = rec.write(Path(tmp) / "hour.csv")
        times = []
        for i in range(repeat):
            t0 = time.perf_counter()
            res = diagnose(path, out=Path(tmp) / f"out{i}")
            times.append(time.perf_counter() - t0)
        print(json.dumps({
            "benchmark": "diagnose_1h_10Hz", "samples": len(rec.data),
            "seconds": [round(t, 2) for t in times], "best_s": round(min(times), 2),
            "limit_s": 10.0, "findings": [f["effect"] for f in res["findings"]], **_machine()}))


def fleet(repeat: int) -> None:
    from click.testing import CliRunner

    from fleetrun.cli import cli
    from fleetrun.diagnose.fleet import diagnose_fleet
    from fleetrun.resources import inputs_dir

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        res = CliRunner().invoke(cli, ["import-epa", str(inputs_dir() / "epa" / "22-tstcar.csv"), "-o",
                                       str(tmp / "fleet.xlsx"), "--measured-out", str(tmp / "measured.csv")])
        assert res.exit_code == 0, res.output
        times = []
        for i in range(repeat):
            t0 = time.perf_counter()
            doc = diagnose_fleet(tmp / "fleet.xlsx", tmp / "measured.csv", out=tmp / f"out{i}")
            times.append(time.perf_counter() - t0)
        print(json.dumps({
            "benchmark": "diagnose_fleet_epa_2022", "vehicles": doc["vehicles"], "rows": doc["rows"],
            "seconds": [round(t, 2) for t in times], "best_s": round(min(times), 2), "limit_s": 120.0,
            "findings": [f["effect"] for f in doc["findings"]], **_machine()}))


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--duration-s", type=float, default=3600.0)
    ap.add_argument("--rate-hz", type=float, default=10.0)
    ap.add_argument("--fleet", action="store_true", help="also time diagnose-fleet on the EPA list")
    args = ap.parse_args(argv)
    recording(args.repeat, args.duration_s, args.rate_hz)
    if args.fleet:
        fleet(args.repeat)


if __name__ == "__main__":
    main()
