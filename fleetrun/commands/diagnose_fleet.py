"""``fleetrun diagnose-fleet``: find physics hidden in a whole fleet's test results (docs/interface.md).

    fleetrun diagnose-fleet FLEET.xlsx --measured MEASURED.csv [--out DIR]

Writes DIR/diagnosis.json (schema fleetrun.fleet-diagnosis/1) and DIR/diagnosis.html (DIR
defaults to ./diagnosis-<workbook stem>) and prints the findings, one line each.
"""
from __future__ import annotations

from pathlib import Path

import click

from fleetrun.diagnose.fleet import FleetSettings, diagnose_fleet


@click.command("diagnose-fleet")
@click.argument("fleet", type=click.Path(dir_okay=False))
@click.option("--measured", required=True, type=click.Path(dir_okay=False),
              help="Measured results: vehicle_id, test, mpg, manufacturer (fleetrun import-epa --measured-out).")
@click.option("--out", "out", type=click.Path(file_okay=False),
              help="Output folder (default ./diagnosis-<workbook stem>).")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed of the shuffled nulls.")
def command(fleet, measured, out, seed):
    """Simulate every vehicle, locate the mismatch across tests and vehicle properties, and fit
    candidate effects with one set of global parameters, judged on held-out manufacturers."""
    out = out or f"diagnosis-{Path(fleet).stem}"
    result = diagnose_fleet(fleet, measured, out=out, settings=FleetSettings(seed=seed))
    click.echo(f"{result['vehicles']} vehicles, {result['manufacturers']} manufacturers, "
               f"{result['rows']} measured results")
    for f in result["findings"]:
        ps = ", ".join(f"{k}={v:.4g}" for k, v in f["parameters"].items())
        click.echo(f"finding: {f['effect']} ({ps}) in {', '.join(f['tests'])}: held-out MAE "
                   f"{100 * f['heldout_mae_before']:.2f} % -> {100 * f['heldout_mae_after']:.2f} %")
    if not result["findings"]:
        click.echo("findings: none")
    u = result["unexplained"]
    if u["significant"]:
        drv = [d["property"] for d in u["drivers"] if d["significant"]]
        click.echo("unexplained: " + "; ".join(x for x in (", ".join(u["tests"]), ", ".join(drv)) if x))
    click.echo(f"wrote {Path(out) / 'diagnosis.json'} and {Path(out) / 'diagnosis.html'}")
