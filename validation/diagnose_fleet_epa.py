"""The fleet-level diagnosis of docs/diagnose-fleet.md, reproducible.

    python validation/diagnose_fleet_epa.py [--out DIR] [--img docs/img]

Imports the EPA 2022 Test Car List (inputs/epa/22-tstcar.csv) with ``fleetrun import-epa``,
runs ``fleetrun diagnose-fleet`` on it (JSON and HTML in DIR) and writes the report's figures
to ``--img``. Prints the per-test errors, the findings and what stays unexplained.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path


def run(out_dir: Path, img_dir: Path | None = None) -> dict:
    from click.testing import CliRunner

    from fleetrun.cli import cli
    from fleetrun.diagnose.fleet import diagnose_fleet
    from fleetrun.diagnose.fleet_report import fleet_figures
    from fleetrun.resources import inputs_dir

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    res = CliRunner().invoke(cli, ["import-epa", str(inputs_dir() / "epa" / "22-tstcar.csv"), "-o",
                                   str(out_dir / "epa_fleet.xlsx"), "--measured-out", str(out_dir / "epa_measured.csv"), "--force"])
    if res.exit_code != 0:
        raise SystemExit(res.output)
    result = diagnose_fleet(out_dir / "epa_fleet.xlsx", out_dir / "epa_measured.csv", out=out_dir / "diagnosis")
    if img_dir is not None:
        img_dir = Path(img_dir)
        img_dir.mkdir(parents=True, exist_ok=True)
        for name, png in fleet_figures(result).items():
            (img_dir / f"diagnose_fleet_epa_{name}.png").write_bytes(png)
    return result


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="diagnose-fleet-epa")
    ap.add_argument("--img", default=None, help="write the figures here (docs/img)")
    args = ap.parse_args(argv)
    r = run(Path(args.out), Path(args.img) if args.img else None)
    print(f"{r['vehicles']} vehicles, {r['manufacturers']} manufacturers, {r['rows']} results, {r['timing_s']} s")
    for block in ("baseline", "after", "full_model"):
        print(block, json.dumps({t: [v["mean_error"], v["heldout_mae"]] for t, v in r[block]["tests"].items()}))
    for f in r["findings"]:
        print("finding", f["effect"], f["parameters"], f["tests"], f["explanation"])
    for c in r["candidates"]:
        print("candidate", c)
    for key in ("unexplained",):
        u = r[key]
        print(key, u["tests"], [(d["property"], d["strength"], d["significant"], d["profile"]) for d in u["drivers"]])
    u = r["full_model"]["unexplained"]
    print("full model unexplained", u["tests"], [(d["property"], d["strength"], d["significant"]) for d in u["drivers"]])


if __name__ == "__main__":
    main()
