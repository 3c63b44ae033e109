"""The cold-start model against the EPA Test Car List: bag 1 / bag 3 fuel, vehicle by vehicle.

    python validation/ftp_coldstart.py [--tstcar inputs/epa/22-tstcar.csv] [--markdown FILE]

Imports the list with ``fleetrun import-epa`` (the workbook and the measured-results CSV),
drives every modelled vehicle over the ``FTP`` with the cold-start constants of
``models/thermal.toml`` (or, with ``--literature-defaults``, their literature values before
the fleet fit; nothing is fitted here) and compares the model's bag 1 / bag 3 fuel
with EPA's (= FE bag 3 / FE bag 1: the two bags drive the same 505 s):

- at the FTP's nominal 25 C (40 CFR 86.130: 20-30 C) against the FTP rows' bags;
- at -6.7 C against the list's 20 F "Cold CO" FTP rows of the same vehicles (read from the
  CSV: the measured-results CSV has the 75 F tests only).

Printed (and with --markdown written): the measured and modelled distributions (median,
quartiles, 5-95 %), the per-vehicle difference (model - measured) and their correlation.
Fitting the constants to these data is the fleet calibration's job (issue 10 item 4), with
manufacturers held out; this script only measures. docs/simulation.md quotes its output.
"""
from __future__ import annotations

import argparse
import dataclasses
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fleetrun.workbook.reader import read_fleet  # noqa: E402
from fleetrun.simulation import simulate  # noqa: E402
from fleetrun.simulation.thermal import thermal_constants  # noqa: E402

NOMINAL_FTP_C = 25.0
# the literature values of the constants the fleet fit replaced (models/thermal.toml's comments)
LITERATURE_ENRICHMENT = 0.10
LITERATURE_HEAT_CAPACITY_KJ_PER_K_PER_L = 22.0
COLD_CO_C = (20.0 - 32.0) * 5.0 / 9.0      # 20 F
CHUNK = 128


def import_list(tstcar: Path, folder: Path):
    """The list as a fleet workbook and measured CSV (``fleetrun import-epa``)."""
    fleet, measured = folder / "fleet.xlsx", folder / "measured.csv"
    subprocess.run([sys.executable, "-m", "fleetrun", "import-epa", str(tstcar), "-o", str(fleet),
                    "--measured-out", str(measured), "--force"], check=True, cwd=ROOT, capture_output=True)
    return read_fleet(fleet).vehicles, pd.read_csv(measured)


def model_bag_ratio(vehicles, ambient_C: float, thermal=None) -> pd.Series:
    """Bag 1 / bag 3 fuel of the model per vehicle id, at ``ambient_C`` (``thermal``: the
    cold-start constants; None = models/thermal.toml)."""
    out = {}
    for first in range(0, len(vehicles), CHUNK):
        part = vehicles[first:first + CHUNK]
        bags = simulate(part, "FTP", ambient_temp_C=ambient_C, thermal=thermal).phases
        ratio = bags["bag1"].fuel_g / bags["bag3"].fuel_g
        out.update({v.vehicle_id: float(r) for v, r in zip(part, ratio)})
    return pd.Series(out, name="model")


def measured_bag_ratio(measured: pd.DataFrame) -> pd.Series:
    """EPA's FE bag 3 / FE bag 1 per vehicle id (the FTP rows)."""
    m = measured.pivot_table(index="vehicle_id", columns="test", values="mpg")
    return (m["FTP:bag3"] / m["FTP:bag1"]).dropna().rename("measured")


def cold_co_ratio(tstcar: Path) -> pd.Series:
    """FE bag 3 / FE bag 1 of the 20 F "Cold CO" FTP rows per vehicle id (mean of repeats)."""
    d = pd.read_csv(tstcar, low_memory=False)
    d = d[(d["Test Procedure Description"] == "Cold CO") & (d["FE Bag 1"] > 0) & (d["FE Bag 3"] > 0)]
    ids = d["Test Vehicle ID"].astype(str) + "_c" + d["Test Veh Configuration #"].astype(str)
    return (d["FE Bag 3"] / d["FE Bag 1"]).groupby(ids).mean().rename("measured")


def describe(x: pd.Series) -> str:
    q = x.quantile([0.05, 0.25, 0.5, 0.75, 0.95]).to_numpy()
    return f"median {q[2]:.3f}, quartiles {q[1]:.3f}-{q[3]:.3f}, 5-95 % {q[0]:.3f}-{q[4]:.3f} (n = {x.size})"


def compare(title: str, model: pd.Series, measured: pd.Series) -> list[str]:
    both = pd.concat([model, measured], axis=1, join="inner").dropna()
    diff = both["model"] - both["measured"]
    r = np.corrcoef(both["model"], both["measured"])[0, 1] if len(both) > 2 else float("nan")
    return [f"### {title}", "",
            f"- measured: {describe(both['measured'])}",
            f"- model:    {describe(both['model'])}",
            f"- model - measured per vehicle: {describe(diff)}; correlation {r:.2f}", ""]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tstcar", type=Path, default=ROOT / "inputs" / "epa" / "22-tstcar.csv")
    ap.add_argument("--markdown", type=Path, help="also write the lines here")
    ap.add_argument("--literature-defaults", action="store_true",
                    help="use the literature value of every fitted constant (gasoline enrichment "
                         f"{LITERATURE_ENRICHMENT:g}; the toml's comments) instead of the fit")
    args = ap.parse_args(argv)
    thermal = None
    if args.literature_defaults:
        k = thermal_constants()
        thermal = dataclasses.replace(k, enrichment_at_25C={**k.enrichment_at_25C, "gasoline": LITERATURE_ENRICHMENT},
                                      heat_capacity_J_per_K_per_L=1e3 * LITERATURE_HEAT_CAPACITY_KJ_PER_K_PER_L)
    with tempfile.TemporaryDirectory() as tmp:
        vehicles, measured = import_list(args.tstcar, Path(tmp))
    warm = measured_bag_ratio(measured)
    cold = cold_co_ratio(args.tstcar)
    with_bags = [v for v in vehicles if v.vehicle_id in warm.index]
    lines = compare(f"FTP at {NOMINAL_FTP_C:g} C: bag 1 / bag 3 fuel",
                    model_bag_ratio(with_bags, NOMINAL_FTP_C, thermal), warm)
    cold_vehicles = [v for v in vehicles if v.vehicle_id in cold.index]
    lines += compare(f"20 F FTP (Cold CO) at {COLD_CO_C:.1f} C: bag 1 / bag 3 fuel",
                     model_bag_ratio(cold_vehicles, COLD_CO_C, thermal), cold)
    text = "\n".join(lines)
    print(text)
    if args.markdown:
        args.markdown.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
