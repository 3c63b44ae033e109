"""``fleetrun diagnose``: find the physics a recording shows and the model leaves out (CONTRACT.md).

    fleetrun diagnose RECORDING [--meta FILE] [--calibrate-on REFERENCE] [--out DIR]
                      [--residual auto|simulation|same-trace]

Writes DIR/diagnosis.json and DIR/diagnosis.html (DIR defaults to ./diagnosis-<stem>) and
prints the findings, one line each.
"""
from __future__ import annotations

from pathlib import Path

import click


@click.command("diagnose")
@click.argument("recording", type=click.Path(dir_okay=False))
@click.option("--meta", type=click.Path(dir_okay=False),
              help="Sidecar TOML (default: the recording's stem with .toml).")
@click.option("--calibrate-on", "calibrate_on", type=click.Path(dir_okay=False),
              help="Reference recording of the same vehicle or rig without the effect "
                   "(e.g. a hot start); the baseline's free constants are fitted on it first.")
@click.option("--out", "out", type=click.Path(file_okay=False),
              help="Output folder (default ./diagnosis-<stem>).")
@click.option("--physics", default="thesis", show_default=True, help="Differential physics baseline.")
@click.option("--shifts", "n_shifts", type=click.IntRange(20, 5000), default=200, show_default=True,
              help="Circular shifts in the noise null distribution.")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed of the shifts.")
@click.option("--residual", type=click.Choice(["auto", "simulation", "same-trace"]), default="auto",
              show_default=True,
              help="With --calibrate-on at vehicle level: the residual is measured minus the "
                   "calibrated simulation, or minus the reference recording where both drive "
                   "the same trace (auto: same-trace when the reference covers half the "
                   "recording).")
def command(recording, meta, calibrate_on, out, physics, n_shifts, seed, residual):
    """Compare a recording with the model; name, fit and test the physics it leaves out."""
    from fleetrun.diagnose import diagnose
    from fleetrun.diagnose.engine import Settings

    out = out or f"diagnosis-{Path(recording).stem}"
    result = diagnose(recording, meta=meta, calibrate_on=calibrate_on, out=out, physics=physics,
                      settings=Settings(n_shifts=n_shifts, seed=seed), residual=residual)
    b = result["baseline"]
    click.echo(f"baseline: held-out RMSE {b['heldout_rmse']:.4g} {result['units']}, "
               f"mismatch {'significant' if result['mismatch']['significant'] else 'not significant'}"
               + (f", residual: {b['residual']}" if "residual" in b else ""))
    u = result["unexplained"]
    if u["significant"]:
        click.echo(f"unexplained: RMSE {u['rmse']:.4g} left against {u['noise_rmse']:.4g} that no "
                   f"function of the channels explains ({100 * u['energy_share']:.0f} % of the "
                   "mismatch's structured energy); the cause is not in the catalogue"
                   + ("; the sensor_drift check fires" if u.get("drift", {}).get("significant") else ""))
    for f in result["findings"]:
        ps = ", ".join(f"{k}={v:.4g}" for k, v in f["parameters"].items())
        click.echo(f"finding: {f['effect']} ({ps}): held-out RMSE "
                   f"{f['heldout_rmse_before']:.4g} -> {f['heldout_rmse_after']:.4g}")
    for d in result.get("descriptions", []):
        click.echo(f"weak description (not a finding): {d['effect']}: {d['reason']}")
    for a in result.get("ambiguities", []):
        click.echo(f"ambiguous: {' / '.join(a['effects'])}; separate them: {a['separating_test']}")
    if not result["findings"] and not result.get("ambiguities"):
        click.echo("findings: none")
    click.echo(f"wrote {Path(out) / 'diagnosis.json'} and {Path(out) / 'diagnosis.html'}")
