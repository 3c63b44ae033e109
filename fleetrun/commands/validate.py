"""``fleetrun validate FLEET.xlsx``: check a fleet workbook without simulating."""
from __future__ import annotations

from pathlib import Path

import click


@click.command("validate")
@click.argument("workbook", type=click.Path(path_type=Path))
@click.option("--strict", is_flag=True, help="Treat warnings as errors (exit 1).")
def command(workbook: Path, strict: bool):
    """Check FLEET.xlsx: every problem at once (exit 1), warnings for implausible values."""
    from fleetrun.errors import InputError
    from fleetrun.workbook import read_fleet

    fleet = read_fleet(workbook)   # on errors, stderr holds just the one Error: message
    for warning in fleet.warnings:
        click.echo(f"Warning: {warning}", err=True)
    if strict and fleet.warnings:
        raise InputError(f"{workbook}: {len(fleet.warnings)} warning(s) and --strict",
                         hint="Fix the values or drop --strict.")
    click.echo(f"{workbook}: OK: {len(fleet.vehicles)} vehicle types, "
               f"{sum(v.count for v in fleet.vehicles):,.0f} vehicles, "
               + (f"{len(fleet.registrations):,} registration rows ({sum(r['count'] for r in fleet.registrations):,.0f} "
                  "vehicles), " if fleet.registrations else "")
               + f"{len(fleet.scenarios)} scenarios ({', '.join(s.scenario_id for s in fleet.scenarios)}); "
               f"{len(fleet.warnings)} warning(s)")
