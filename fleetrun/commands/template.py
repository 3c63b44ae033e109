"""``fleetrun template -o new.xlsx``: a blank fleet workbook to fill in."""
from __future__ import annotations

from pathlib import Path

import click

from fleetrun.errors import InputError
from fleetrun.workbook.template import write_template


@click.command("template")
@click.option("-o", "--output", "output", type=click.Path(dir_okay=False, path_type=Path),
              default=Path("fleet.xlsx"), show_default=True, help="Workbook to write.")
@click.option("--force", is_flag=True, help="Overwrite an existing file.")
def command(output: Path, force: bool):
    """Write a fleet workbook template: Vehicles and Scenarios sheets with headers,
    drop-down lists, two example rows each, and an Instructions sheet."""
    if output.suffix.lower() != ".xlsx":
        raise InputError(f"'{output}' must end in .xlsx", hint="Give a name like fleet.xlsx.")
    if output.exists() and not force:
        raise InputError(f"'{output}' exists", hint="Choose another name or add --force.")
    write_template(output)
    click.echo(f"Wrote {output}: fill in Registrations (or Vehicles) and Scenarios, then "
               f"`fleetrun validate {output}` (docs/registrations.md: the path from registration counts).")
