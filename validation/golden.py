"""Golden outputs: prove that a restructuring changes no number, bit for bit.

    python validation/golden.py write DIR     # produce the golden outputs of today's code
    python validation/golden.py check DIR     # produce them again and compare byte for byte

Run from the checkout root (``PYTHONPATH=$PWD``). The outputs are kept OUTSIDE the checkout
(e.g. ``/tmp/golden``): they are the code's own output, not a reference value, and only serve
to show that a change meant to be pure restructuring is one. After a deliberate physics change,
``write`` them again.

What is produced (every file compared by its sha256):
- ``fleetrun run inputs/example_fleet.xlsx --no-cache`` (and once more ``--with
  bearing_preload:drag_torque_Nm=3,warmup``): results.csv, class_summary.csv;
- ``fleetrun diagnose``: the Argonne Camry cold UDDS calibrated on the hot UDDS, one generated
  differential recording (cornering + oil warm-up, seed 3) and one generated vehicle recording
  (warm-up, seed 5): diagnosis.json (and the generated recordings' CSV themselves);
- ``fleetrun map``: six configurations, thesis and vecto-generic, one with ``--with``;
- ``fleetrun simulate``: trace CSV and the JSON line for four vehicles x three modes;
- library level: ``simulate`` on the whole example fleet over five cycles x three modes at two
  ambient temperatures, with and without effects, every per-vehicle sum and every trace array
  saved at full precision (``.npy`` bytes), so a change in the last bit shows.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
FLEET = ROOT / "inputs" / "example_fleet.xlsx"
DYNO = ROOT / "inputs" / "dyno"
CYCLES = ("UDDS", "HWFET", "US06", "NYCC", "HD-UDDS")
MODES = ("direct", "map2d", "map3d")
MAPS = [
    ["LD_RWD", "--gear-ratio", "3.55"],
    ["LD_FWD", "--gear-ratio", "2.8", "--format", "json"],
    ["LD_AWD", "--gear-ratio", "3.6"],
    ["HD_DUAL", "--gear-ratio", "5.29", "--low-gear-ratio", "1.36", "--axle-gear", "low"],
    ["HD_TANDEM_DUAL", "--gear-ratio", "4.1", "--low-gear-ratio", "1.3", "--speeds-rpm", "0,500,1500,2500"],
    ["HD_TAG", "--gear-ratio", "4.3", "--physics", "vecto-generic"],
    ["LD_RWD", "--gear-ratio", "3.73", "--with", "bearing_preload:drag_torque_Nm=3,cornering"],
]


def fleetrun(*args, cwd=None):
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1")
    proc = subprocess.run([sys.executable, "-m", "fleetrun", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"fleetrun {' '.join(map(str, args))} failed ({proc.returncode}):\n{proc.stderr}")
    return proc.stdout


def produce(out: Path, quick: bool = False) -> None:
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        # fleet runs
        for tag, extra in (("run", []), ("run_with", ["--with", "bearing_preload:drag_torque_Nm=3,warmup"])):
            fleetrun("run", FLEET, "--out", tmp / tag, "--no-cache", "-q", *extra)
            for name in ("results.csv", "class_summary.csv"):
                (out / f"{tag}_{name}").write_bytes((tmp / tag / name).read_bytes())
        # maps
        for i, args in enumerate(MAPS):
            (out / f"map_{i}.txt").write_text(fleetrun("map", *args))
        # simulate CLI
        for vid in ("LD-CAMRY-25", "LD-COROLLA-20-MT", "LD-ESCAPE-AWD", "HD-DUMP-CLASS7-2SPD"):
            for mode in MODES:
                trace = tmp / f"trace_{vid}_{mode}.csv"
                line = fleetrun("simulate", FLEET, "--vehicle", vid, "--cycle", "UDDS", "--mode", mode,
                                "-o", trace)
                (out / f"simulate_{vid}_{mode}.json").write_text(line)
                (out / trace.name).write_bytes(trace.read_bytes())
        library_simulations(out, tmp)
        if not quick:
            diagnoses(out, tmp)


def diagnoses(out: Path, tmp: Path) -> None:
    fleetrun("diagnose", DYNO / "camry2018_udds_cold.csv", "--calibrate-on", DYNO / "camry2018_udds_hot.csv",
             "--out", tmp / "camry")
    (out / "diagnose_camry.json").write_text(_canonical_json((tmp / "camry" / "diagnosis.json").read_bytes(), tmp))
    code = ("import sys\n"
            "try:\n"  # the generator moved to fleetrun.testing (issue 8); golden outputs predate it
            "    from fleetrun.testing.recordings import random_case, generate_vehicle_recording\n"
            "except ModuleNotFoundError:\n"
            "    from fleetrun.diagnose.generator import random_case, generate_vehicle_recording\n"
            "random_case(['cornering', 'oil_warmup'], seed=3).write(sys.argv[1] + '/rig.csv')\n"
            "generate_vehicle_recording([('warmup', {})], seed=5).write(sys.argv[1] + '/veh.csv')\n"
            "generate_vehicle_recording([], seed=99, name='hot').write(sys.argv[1] + '/hot.csv')\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1")
    subprocess.run([sys.executable, "-c", code, str(tmp)], check=True, env=env)
    for name in ("rig.csv", "rig.toml", "veh.csv", "hot.csv"):
        (out / f"recording_{name}").write_bytes((tmp / name).read_bytes())
    fleetrun("diagnose", tmp / "rig.csv", "--out", tmp / "rig", "--shifts", "50")
    (out / "diagnose_rig.json").write_text(_canonical_json((tmp / "rig" / "diagnosis.json").read_bytes(), tmp))
    fleetrun("diagnose", tmp / "veh.csv", "--calibrate-on", tmp / "hot.csv", "--out", tmp / "veh",
             "--shifts", "50")
    (out / "diagnose_vehicle.json").write_text(_canonical_json((tmp / "veh" / "diagnosis.json").read_bytes(), tmp))


def _canonical_json(raw: bytes, tmp: Path) -> str:
    """diagnosis.json without what changes from run to run (timings, the temporary and checkout folders)."""
    def clean(obj):
        if isinstance(obj, dict):
            return {k: clean(v) for k, v in obj.items() if k != "timing_s"}
        if isinstance(obj, list):
            return [clean(v) for v in obj]
        if isinstance(obj, str):
            return obj.replace(str(tmp), "<tmp>").replace(str(ROOT), "<root>")
        return obj
    return json.dumps(clean(json.loads(raw)), indent=1, sort_keys=True)


def library_simulations(out: Path, tmp: Path) -> None:
    """Every sum and trace array of ``simulate`` at full precision, in a child process."""
    code = r"""
import sys
from pathlib import Path
import numpy as np
from fleetrun.workbook.reader import read_fleet
from fleetrun.simulation import simulate, SUM_FIELDS
from fleetrun.simulation.core import trace_kinematics
out, fleet, cache = Path(sys.argv[1]), sys.argv[2], sys.argv[3]
vehicles = read_fleet(fleet).vehicles
for cycle in sys.argv[4].split(","):
    for mode in sys.argv[5].split(","):
        for ambient, effects in ((20.0, ()), (-5.0, "bearing_preload:drag_torque_Nm=3,oil_warmup,warmup")):
            tag = f"{cycle}_{mode}_{ambient:g}"
            r = simulate(vehicles, cycle, mode=mode, ambient_temp_C=ambient, effects=effects, trace=True,
                         cache_dir=cache)
            arrays = {k: np.asarray(getattr(r, k)) for k in SUM_FIELDS}
            arrays.update({k: np.asarray(v) for k, v in r.trace.columns().items()})
            # the step motion (kept in the golden set since the trace carried it as internals)
            k = trace_kinematics(r.trace)
            shape = r.trace.time_s.shape
            arrays.update({"_v_avg": k.v_avg, "_accel": k.accel, "_dt": np.broadcast_to(k.dt, shape),
                           "_driving": k.moving & (r.trace.wheel_torque_Nm > 0)})
            for k, a in sorted(arrays.items()):
                np.save(out / f"sim_{tag}_{k}.npy", np.ascontiguousarray(a))
"""
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1")
    (tmp / "cache").mkdir(exist_ok=True)
    subprocess.run([sys.executable, "-c", code, str(out), str(FLEET), str(tmp / "cache"), ",".join(CYCLES),
                    ",".join(MODES)], check=True, env=env)


def digests(folder: Path) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("action", choices=("write", "check"))
    ap.add_argument("folder", type=Path)
    ap.add_argument("--quick", action="store_true", help="skip the diagnoses (the slow part)")
    args = ap.parse_args(argv)
    if args.action == "write":
        produce(args.folder, args.quick)
        (args.folder / "SHA256SUMS.json").write_text(json.dumps(digests(args.folder), indent=1))
        print(f"wrote {len(digests(args.folder))} golden files to {args.folder}")
        return 0
    golden = json.loads((args.folder / "SHA256SUMS.json").read_text())
    with tempfile.TemporaryDirectory() as tmp:
        produce(Path(tmp), args.quick)
        now = digests(Path(tmp))
        compared = [k for k in golden if k != "SHA256SUMS.json" and k in now]
        missing = [k for k in golden if k != "SHA256SUMS.json" and k not in now
                   and not (args.quick and (k.startswith("diagnose_") or k.startswith("recording_")))]
        differ = [k for k in compared if golden[k] != now[k]]
        for k in differ[:40]:
            print(f"DIFFERS {k}")
            if k.endswith(".npy"):
                a, b = np.load(args.folder / k, allow_pickle=False), np.load(Path(tmp) / k, allow_pickle=False)
                if a.shape == b.shape and a.dtype.kind == "f":
                    print(f"   max abs diff {np.nanmax(np.abs(a - b)):.3g}")
        for k in missing:
            print(f"MISSING {k}")
    print(f"{len(compared)} files compared: {len(differ)} differ, {len(missing)} missing")
    return 1 if differ or missing else 0


if __name__ == "__main__":
    sys.exit(main())
