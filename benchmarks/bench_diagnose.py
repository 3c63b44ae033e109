"""Benchmark: diagnose a 1-hour, 10 Hz differential-level recording (issue 5: under 60 s).

    python benchmarks/bench_diagnose.py [--repeat 3]

Generates the recording with fleetrun.testing.recordings (two hidden effects, AR(1) noise,
offsets), then times the whole ``fleetrun diagnose`` path: reading and checking the CSV,
baseline, locating, selection with 200 circular shifts, JSON and HTML. Prints one JSON line.
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


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--duration-s", type=float, default=3600.0)
    ap.add_argument("--rate-hz", type=float, default=10.0)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        rec = random_case(["oil_warmup", "cornering"], 7, duration_s=args.duration_s,
                          rate_hz=args.rate_hz)
        path = rec.write(Path(tmp) / "hour.csv")
        times = []
        for i in range(args.repeat):
            t0 = time.perf_counter()
            res = diagnose(path, out=Path(tmp) / f"out{i}")
            times.append(time.perf_counter() - t0)
        print(json.dumps({
            "benchmark": "diagnose_1h_10Hz", "samples": len(rec.data),
            "seconds": [round(t, 2) for t in times], "best_s": round(min(times), 2),
            "limit_s": 60.0, "findings": [f["effect"] for f in res["findings"]],
            "machine": platform.processor() or platform.machine(), "python": platform.python_version()}))


if __name__ == "__main__":
    main()
