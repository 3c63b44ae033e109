"""``fleetrun import-epa TSTCAR.csv -o FLEET.xlsx``: a fleet workbook from an EPA Test Car List."""
from __future__ import annotations

from pathlib import Path

import click

from fleetrun.epa import import_test_car_list
from fleetrun.epa.writer import write_fleet_workbook, write_measured_csv
from fleetrun.errors import InputError
from fleetrun.fileio import FORCE_IMPORT_HELP, kept_note, refuse_replacing_inputs, replacing_import
from fleetrun.workbook.reader import file_sha256


@click.command("import-epa")
@click.argument("tstcar", type=click.Path(path_type=Path, dir_okay=False))
@click.option("-o", "--output", "output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Fleet workbook to write (.xlsx).")
@click.option("--measured-out", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Also write the measured results (vehicle_id, test, mpg, ...) as CSV.")
@click.option("--model-year", "model_years", multiple=True, type=int,
              help="Only this model year (repeatable).")
@click.option("--make", "makes", multiple=True,
              help="Only this make or manufacturer, case-insensitive (repeatable).")
@click.option("--force", is_flag=True, help=FORCE_IMPORT_HELP)
def command(tstcar: Path, output: Path, measured_out: Path | None, model_years, makes, force):
    """Write a fleet workbook from an EPA Test Car List CSV: one Vehicles row per test vehicle
    and configuration, with Measured, Derived and Excluded sheets (docs/epa-import.md)."""

    if output.suffix.lower() != ".xlsx":
        raise InputError(f"'{output}' must end in .xlsx", hint="Give a name like fleet.xlsx")
    if not tstcar.is_file():
        raise InputError("does not exist", file=tstcar, hint="Check the path of the EPA Test Car List CSV")
    refuse_replacing_inputs(output, [tstcar], "-o")
    if measured_out is not None:
        refuse_replacing_inputs(measured_out, [tstcar, output], "--measured-out")
        if measured_out.resolve() == output.resolve():
            raise InputError(f"--measured-out {measured_out} is the workbook -o writes",
                             hint="Give the measured results another name, e.g. measured.csv")
    result = import_test_car_list(tstcar, model_years, makes)
    if not result.vehicles:
        picked = f" of the {result.rows_selected} selected rows" if (model_years or makes) else ""
        raise InputError(f"no vehicle{picked} can be modelled ({len(result.excluded)} excluded; "
                         f"{result.rows_read} test rows read)", file=tstcar,
                         hint="Check --model-year / --make, or the Excluded reasons with fewer filters")
    with replacing_import(output, force) as kept:   # the analyst's edits of an earlier import stay
        write_fleet_workbook(result, output, source=str(tstcar), sha256=file_sha256(tstcar))
    if measured_out is not None:
        write_measured_csv(result, measured_out)
    click.echo(f"Wrote {output}: {len(result.vehicles)} vehicles modelled, {len(result.excluded)} excluded "
               f"(sheet Excluded), {len(result.measured)} measured results"
               + (f" (also {measured_out})" if measured_out else "") + f". Next: `fleetrun run {output}`."
               + kept_note(kept))
