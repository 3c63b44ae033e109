"""Write a blank fleet workbook: the two sheets with headers, drop-downs and two example rows.

``write_template(path)`` is what ``fleetrun template -o new.xlsx`` runs. The columns, notes
and drop-down choices come from :mod:`fleetrun.workbook.schema`, the same lists the reader checks.
"""
from __future__ import annotations

from pathlib import Path

import xlsxwriter

from fleetrun.fileio import atomic_file
from fleetrun.workbook.schema import (REGISTRATION_COLUMNS, REGISTRATIONS_SHEET, SCENARIO_COLUMNS,
                                   SCENARIOS_SHEET, VEHICLE_COLUMNS, VEHICLES_SHEET, Column)

#: Cell formats (XlsxWriter properties): required headers dark, optional ones lighter.
HEADER = {"bold": True, "font_color": "#FFFFFF", "bg_color": "#1F4E78", "pattern": 1, "align": "center"}
OPTIONAL_HEADER = {**HEADER, "bg_color": "#5B7FA6"}
VALIDATED_ROWS = 5000     # drop-downs cover this many data rows
TITLE_CHARS = 32          # Excel's longest validation error title (XlsxWriter skips a longer rule)

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
    ("   base_year_vmt_share_pct (optional, for diesel): your state's % of those miles by truck class, e.g.", None),
    ("   combination_truck:9.1, single_unit_truck:4.6, bus:0.6 (FHWA VM-4 / HPMS); other classes the rest.", None),
    ("   Empty cycle_mix_MD and cycle_mix_HD too (or write default there): a mix typed there replaces", None),
    ("   the trucks' default mix. Replace the EXAMPLE- scenario ids with your own.", None),
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
    """Write the template workbook to ``path`` (atomically), with XlsxWriter: the one Excel
    writer of fleetrun (report.xlsx and import-epa's workbook too)."""
    with atomic_file(Path(path)) as temporary:
        workbook = xlsxwriter.Workbook(str(temporary), {"strings_to_numbers": False, "strings_to_formulas": False,
                                                        "strings_to_urls": False})
        instructions = workbook.add_worksheet("Instructions")
        formats = {"required": workbook.add_format(HEADER), "optional": workbook.add_format(OPTIONAL_HEADER),
                   "text": workbook.add_format({"num_format": "@"}), "bold": workbook.add_format({"bold": True}),
                   "title": workbook.add_format({"bold": True, "font_size": 14})}
        registrations = workbook.add_worksheet(REGISTRATIONS_SHEET)
        _fill_sheet(registrations, REGISTRATION_COLUMNS, formats, examples=False)
        _fill_sheet(workbook.add_worksheet(VEHICLES_SHEET), VEHICLE_COLUMNS, formats)
        _fill_sheet(workbook.add_worksheet(SCENARIOS_SHEET), SCENARIO_COLUMNS, formats)
        _fill_instructions(instructions, formats)
        registrations.activate()   # the second sheet, after the Instructions
        workbook.close()


def _fill_sheet(ws, columns: tuple[Column, ...], formats: dict, examples: bool = True) -> None:
    """Headers, notes, drop-downs and (``examples``) the two example rows. The Registrations
    sheet has no example rows: a row there has no id a warning could point at, so it would count."""
    for index, column in enumerate(columns):
        ws.write_string(0, index, column.name, formats["required" if column.required else "optional"])
        ws.write_comment(0, index, ("required: " if column.required else "optional: ") + column.note,
                         {"author": "fleetrun"})
        ws.set_column(index, index, max(12, len(column.name) + 2))
        for row, example in enumerate(column.example if examples else (), start=1):
            if column.kind in ("text", "ratios", "cycle_mix", "choice"):
                ws.write_string(row, index, str(example), formats["text"])  # keep "3.5,2.1" and ids as text
            else:
                ws.write(row, index, example)
        if column.kind in ("number", "integer"):
            _number_rule(ws, column, index)
        if column.choices:
            ws.data_validation(1, index, VALIDATED_ROWS, index, {
                "validate": "list", "source": list(column.choices), "ignore_blank": not column.required,
                "error_title": column.name[:TITLE_CHARS], "error_message": f"Choose one of: {', '.join(column.choices)}"})
    ws.freeze_panes(1, 1)


def _number_rule(ws, column: Column, index: int) -> None:
    """Excel refuses what is not a number (a whole number for integer columns) in range."""
    kind = "integer" if column.kind == "integer" else "decimal"
    if column.maximum is not None:
        low = column.minimum if column.minimum is not None else 0.0
        rule, words = {"criteria": "between", "minimum": low, "maximum": column.maximum}, \
            f"from {low:g} to {column.maximum:g}"
    elif column.strictly_positive:
        rule, words = {"criteria": ">", "value": 0}, "greater than 0"
    elif column.minimum is not None:
        rule, words = {"criteria": ">=", "value": column.minimum}, f"at least {column.minimum:g}"
    else:
        rule, words = {"criteria": "between", "minimum": -1e300, "maximum": 1e300}, ""
    noun = "a whole number" if kind == "integer" else "a number"
    ws.data_validation(1, index, VALIDATED_ROWS, index, {
        "validate": kind, **rule, "ignore_blank": not column.required, "error_title": column.name[:TITLE_CHARS],
        "error_message": f"{column.name}: {noun} {words}".strip()})


def _fill_instructions(ws, formats: dict) -> None:
    for index, width in enumerate((34, 12, 70, 22, 22)):
        ws.set_column(index, index, width)
    for row, (text, _) in enumerate(INSTRUCTIONS):
        ws.write_string(row, 0, text, formats["title"] if row == 0 else None)
    row = len(INSTRUCTIONS) - 1      # the "Columns" line: the table's header row
    ws.write_string(row, 0, INSTRUCTIONS[-1][0], formats["bold"])
    ws.write_string(row, 3, "range (outside: refused)", formats["bold"])
    ws.write_string(row, 4, "usual (outside: warning)", formats["bold"])
    for sheet, columns in ((REGISTRATIONS_SHEET, REGISTRATION_COLUMNS), (VEHICLES_SHEET, VEHICLE_COLUMNS),
                           (SCENARIOS_SHEET, SCENARIO_COLUMNS)):
        for column in columns:
            row += 1
            choices = f" ({', '.join(column.choices)})" if column.choices else ""
            values = (f"{sheet}.{column.name}", "required" if column.required else "optional",
                      column.note + choices, column.range_text(), usual_text(column))
            for index, value in enumerate(values):
                if value:
                    ws.write_string(row, index, value)


def usual_text(column) -> str:
    """The plausible range of a column as the Instructions sheet and docs show it."""
    usual = column.plausible
    if not usual:
        return ""
    if isinstance(usual, dict):
        return "; ".join(f"{duty} {low:g} to {high:g}" for duty, (low, high) in usual.items())
    return f"{usual[0]:g} to {usual[1]:g}"
