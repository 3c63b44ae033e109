"""``fleetrun import-registrations EXTRACT.csv -o FLEET.xlsx``: a fleet workbook from a DMV-style
registration extract (docs/registrations.md)."""
from __future__ import annotations

from pathlib import Path

import click

from fleetrun.errors import InputError
from fleetrun.fileio import FORCE_IMPORT_HELP, kept_note, refuse_replacing_inputs, replacing_import


@click.command("import-registrations")
@click.argument("extract", type=click.Path(path_type=Path, dir_okay=False))
@click.option("-o", "--output", "output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Fleet workbook to write (.xlsx): a Registrations sheet and a default scenario.")
@click.option("--first-fiscal-year", type=int, default=None, help="Fiscal year of budget year 1 (e.g. 2027).")
@click.option("--base-year-vmt-million", type=float, default=None,
              help="The base fiscal year's vehicle-miles in millions (e.g. from FHWA VM-2).")
@click.option("--base-year-vmt-share-pct", default=None,
              help="Percent of those miles by FHWA class, e.g. 'combination_truck:9.1,single_unit_truck:4.6' "
                   "(your VM-4 / HPMS; docs/registrations.md, \"Miles by class\").")
@click.option("--force", is_flag=True, help=FORCE_IMPORT_HELP)
def command(extract: Path, output: Path, first_fiscal_year, base_year_vmt_million, base_year_vmt_share_pct, force):
    """Aggregate a registration extract (one line per vehicle, or counts per make, model and
    model year; read in chunks) into the Registrations sheet of a new fleet workbook."""
    from fleetrun.registrations.extract import read_extract
    from fleetrun.registrations.workbook import write_registrations_workbook

    if base_year_vmt_share_pct is not None:
        _check_shares(base_year_vmt_share_pct)
    if output.suffix.lower() != ".xlsx":
        raise InputError(f"'{output}' must end in .xlsx", hint="Give a name like fleet.xlsx")
    refuse_replacing_inputs(output, [extract], "-o")
    frame = read_extract(extract)
    with replacing_import(output, force) as kept:   # the analyst's Scenarios of an earlier import stay
        write_registrations_workbook(frame, output, first_fiscal_year, base_year_vmt_million, base_year_vmt_share_pct)
    click.echo(f"Wrote {output}: {len(frame):,} registration rows ({frame['count'].sum():,.0f} vehicles). "
               f"Next: check the Scenarios sheet (tax rates, VMT), then `fleetrun run {output}`." + kept_note(kept))


def _check_shares(text: str) -> None:
    """A usage error (exit 2) for a share list the workbook would refuse."""
    from fleetrun.workbook.cells import CellProblem, parse_class_shares
    from fleetrun.workbook.schema import FHWA_CLASSES

    try:
        parse_class_shares(text, FHWA_CLASSES)
    except CellProblem as exc:
        raise click.BadParameter(str(exc), param_hint="--base-year-vmt-share-pct") from None
