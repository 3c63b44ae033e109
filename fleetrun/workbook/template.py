"""Write a blank fleet workbook: the two sheets with headers, drop-downs and two example rows.

``write_template(path)`` is what ``fleetrun template -o new.xlsx`` runs. The columns, notes
and drop-down choices come from :mod:`fleetrun.workbook.schema`, the same lists the reader checks.
"""
from __future__ import annotations

from pathlib import Path

from openpyxl import Workbook
from openpyxl.comments import Comment
from openpyxl.styles import Alignment, Font, PatternFill
from openpyxl.utils import get_column_letter
from openpyxl.worksheet.datavalidation import DataValidation

from fleetrun.workbook.schema import (REGISTRATION_COLUMNS, REGISTRATIONS_SHEET, SCENARIO_COLUMNS,
                                   SCENARIOS_SHEET, VEHICLE_COLUMNS, VEHICLES_SHEET, Column)

HEADER_FILL = PatternFill("solid", fgColor="1F4E78")
OPTIONAL_FILL = PatternFill("solid", fgColor="5B7FA6")
HEADER_FONT = Font(bold=True, color="FFFFFF")
VALIDATED_ROWS = 5000     # drop-downs cover this many data rows

INSTRUCTIONS = [
    ("fleetrun fleet workbook", None),
    ("", None),
    ("START HERE (a revenue office): the Registrations sheet, then Scenarios; docs/registrations.md.", None),
    ("Registrations: one row per count you have: vehicle_class (automobile, light_truck, single_unit_truck,", None),
    ("   combination_truck, bus, motorcycle, or truck = FHWA MV-1's all trucks) and count are enough.", None),
    ("   Optional: model_year, fuel, make and model (a DMV extract), vehicle_id (a Vehicles row).", None),
    ("   A DMV extract as CSV:  fleetrun import-registrations EXTRACT.csv -o fleet.xlsx", None),
    ("   fleetrun picks a vehicle for every row (listed in registrations.csv and the report's", None),
    ("   Registrations sheet) and ages the fleet over the budget years (scrappage, new model years).", None),
    ("Scenarios for registrations: cycle_mix = default; base_year_vmt_million = the state's VMT", None),
    ("   of the first fiscal year in millions (FHWA VM-2); first_fiscal_year = the year the counts describe.", None),
    ("   Delete the Vehicles sheet's example rows (or the sheet) when you have no engineering data.", None),
    ("", None),
    ("Vehicles (engineering data, optional beside Registrations): one row per vehicle type;", None),
    ("   header in row 1 (do not rename the headers).", None),
    ("Dark headers are required; lighter headers are optional (leave the cell empty).", None),
    ("configuration, duty_class, fuel and transmission have drop-down lists.", None),
    ("transmission_gear_ratios: comma list, first gear first, e.g. 4.62,3.04,2.06,1.66,1.26,1.00", None),
    ("coastdown_A/B/C: the EPA Test Car List target coefficients (lbf, lbf/mph, lbf/mph^2).", None),
    ("low_gear_ratio: only for HD_DUAL, HD_TANDEM_DUAL and HD_TAG_DUAL (two-speed axles).", None),
    ("", None),
    ("Scenarios: one row per scenario.", None),
    ("cycle_mix: CYCLE:share list, shares of each vehicle's annual miles adding up to 1,", None),
    ("   e.g. UDDS:0.55,HWFET:0.45. `fleetrun cycles` lists the drive cycles; a CSV path works too.", None),
    ("cycle_mix_MD / cycle_mix_HD (optional): the mix medium / heavy trucks drive instead,", None),
    ("   e.g. HD-UDDS:0.6,HWFET:0.4 (a loaded truck cannot follow US06). Empty: cycle_mix.", None),
    ("budget_years: 2 = a biennium. Year y uses annual_miles x (1 + growth/100)^(y - 1).", None),
    ("Tax rates in US dollars per gallon.", None),
    ("Every number has a physical range (below): outside it `validate` and `run` refuse the cell;", None),
    ("   outside the usual range they warn (check the units). Sheets up to 12,000,000 cells.", None),
    ("", None),
    ("The example rows (ids starting EXAMPLE-) show the format: replace or delete them;", None),
    ("   `fleetrun validate` warns while one is left in.", None),
    ("Check the workbook with:  fleetrun validate FLEET.xlsx", None),
    ("Run it with:              fleetrun run FLEET.xlsx --out results/", None),
    ("", None),
    ("Columns", None),
]


def write_template(path: Path) -> None:
    """Write the template workbook to ``path`` (atomically)."""
    from fleetrun.fileio import atomic_file

    workbook = build_template()
    with atomic_file(Path(path)) as temporary:
        workbook.save(temporary)


def build_template() -> Workbook:
    workbook = Workbook()
    instructions = workbook.active
    instructions.title = "Instructions"
    _fill_sheet(workbook.create_sheet(REGISTRATIONS_SHEET), REGISTRATION_COLUMNS, examples=False)
    _fill_sheet(workbook.create_sheet(VEHICLES_SHEET), VEHICLE_COLUMNS)
    _fill_sheet(workbook.create_sheet(SCENARIOS_SHEET), SCENARIO_COLUMNS)
    _fill_instructions(instructions)
    workbook.active = 1
    return workbook


def _fill_sheet(ws, columns: tuple[Column, ...], examples: bool = True) -> None:
    """Headers, notes, drop-downs and (``examples``) the two example rows. The Registrations
    sheet has no example rows: a row there has no id a warning could point at, so it would count."""
    for index, column in enumerate(columns, start=1):
        cell = ws.cell(row=1, column=index, value=column.name)
        cell.font = HEADER_FONT
        cell.fill = HEADER_FILL if column.required else OPTIONAL_FILL
        cell.alignment = Alignment(horizontal="center")
        cell.comment = Comment(("required: " if column.required else "optional: ") + column.note,
                               "fleetrun")
        ws.column_dimensions[get_column_letter(index)].width = max(12, len(column.name) + 2)
        for row, example in enumerate(column.example if examples else (), start=2):
            target = ws.cell(row=row, column=index, value=example)
            if column.kind in ("text", "ratios", "cycle_mix", "choice"):
                target.number_format = "@"  # keep "3.5,2.1" and ids as text
        if column.kind in ("number", "integer"):
            _number_rule(ws, column, get_column_letter(index))
        if column.choices:
            letter = get_column_letter(index)
            rule = DataValidation(type="list", formula1='"' + ",".join(column.choices) + '"',
                                  allow_blank=not column.required, showErrorMessage=True,
                                  errorTitle=column.name,
                                  error=f"Choose one of: {', '.join(column.choices)}")
            rule.add(f"{letter}2:{letter}{VALIDATED_ROWS + 1}")
            ws.add_data_validation(rule)
    ws.freeze_panes = "B2"


def _number_rule(ws, column: Column, letter: str) -> None:
    """Excel refuses what is not a number (a whole number for integer columns) in range."""
    kind = "whole" if column.kind == "integer" else "decimal"
    if column.maximum is not None:
        low = column.minimum if column.minimum is not None else 0.0
        operator, first, second, words = ("between", f"{low:g}", f"{column.maximum:g}",
                                          f"from {low:g} to {column.maximum:g}")
    elif column.strictly_positive:
        operator, first, second, words = "greaterThan", "0", None, "greater than 0"
    elif column.minimum is not None:
        operator, first, second, words = ("greaterThanOrEqual", f"{column.minimum:g}", None,
                                          f"at least {column.minimum:g}")
    else:
        operator, first, second, words = "between", "-1E+300", "1E+300", "a number"
    rule = DataValidation(type=kind, operator=operator, formula1=first, formula2=second,
                          allow_blank=not column.required, showErrorMessage=True, errorTitle=column.name,
                          error=f"{column.name}: {'a whole number' if kind == 'whole' else 'a number'} "
                                f"{words if words != 'a number' else ''}".strip())
    rule.add(f"{letter}2:{letter}{VALIDATED_ROWS + 1}")
    ws.add_data_validation(rule)


def _fill_instructions(ws) -> None:
    for letter, width in zip("ABCDE", (34, 12, 70, 22, 22)):
        ws.column_dimensions[letter].width = width
    row = 1
    for text, _ in INSTRUCTIONS:
        ws.cell(row=row, column=1, value=text)
        row += 1
    ws["A1"].font = Font(bold=True, size=14)
    for index, text in enumerate(("", "", "", "range (outside: refused)", "usual (outside: warning)"), start=1):
        if text:
            ws.cell(row=row - 1, column=index, value=text)
        ws.cell(row=row - 1, column=index).font = Font(bold=True)
    for sheet, columns in ((REGISTRATIONS_SHEET, REGISTRATION_COLUMNS), (VEHICLES_SHEET, VEHICLE_COLUMNS),
                           (SCENARIOS_SHEET, SCENARIO_COLUMNS)):
        for column in columns:
            ws.cell(row=row, column=1, value=f"{sheet}.{column.name}")
            ws.cell(row=row, column=2, value="required" if column.required else "optional")
            choices = f" ({', '.join(column.choices)})" if column.choices else ""
            ws.cell(row=row, column=3, value=column.note + choices)
            ws.cell(row=row, column=4, value=column.range_text() or None)
            ws.cell(row=row, column=5, value=usual_text(column) or None)
            row += 1


def usual_text(column) -> str:
    """The plausible range of a column as the Instructions sheet and docs show it."""
    usual = column.plausible
    if not usual:
        return ""
    if isinstance(usual, dict):
        return "; ".join(f"{duty} {low:g} to {high:g}" for duty, (low, high) in usual.items())
    return f"{usual[0]:g} to {usual[1]:g}"
