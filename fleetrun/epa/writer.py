"""Write an imported EPA list as a fleet workbook (the format `fleetrun run` reads) and the
measured results as the CSV `fleetrun diagnose-fleet` reads (docs/interface.md).

Workbook sheets: ``Vehicles`` and ``Scenarios`` (the fleet), ``Measured`` (one row per
vehicle and test), ``Derived`` (per vehicle, each value not copied from the list and the
rule that made it), ``Excluded`` (the configurations not modelled, with the reason) and
``About`` (source file, counts, rules). Both files are written atomically.
"""
from __future__ import annotations

from collections import Counter
from pathlib import Path

import pandas as pd
import xlsxwriter

from fleetrun.cycles import shipped_cycles
from fleetrun.epa import rules
from fleetrun.epa.derive import ImportResult
from fleetrun.fileio import atomic_file
from fleetrun.workbook.schema import SCENARIO_COLUMNS, SCENARIOS_SHEET, VEHICLE_COLUMNS, VEHICLES_SHEET

MEASURED_COLUMNS = ("vehicle_id", "test", "mpg", "manufacturer", "make", "model", "model_year", "n_tests",
                    "test_numbers", "procedure", "csv_rows")
DERIVED_COLUMNS = ("vehicle_id", "column", "value", "rule")
EXCLUDED_COLUMNS = ("vehicle_id", "manufacturer", "make", "model", "model_year", "rule", "reason", "csv_rows")


def default_scenario() -> dict:
    """The Scenarios row: ``[scenario]`` of models/epa_import.toml, with the first of its city
    cycles that fleetrun ships (FTP when it is there, else UDDS)."""
    s = dict(rules.constants()["scenario"])
    shipped = {name.upper() for name in shipped_cycles()}
    city = next((c for c in s.pop("city_cycles") if c.upper() in shipped), "UDDS")
    share = float(s.pop("city_share"))
    highway = s.pop("highway_cycle")
    s["cycle_mix"] = f"{city}:{share:g},{highway}:{1.0 - share:g}"
    return s


def write_measured_csv(result: ImportResult, path) -> Path:
    """The measured results (MEASURED_COLUMNS) as CSV, atomically."""
    path = Path(path)
    frame = pd.DataFrame(result.measured, columns=list(MEASURED_COLUMNS))
    with atomic_file(path) as tmp:
        frame.to_csv(tmp, index=False)
    return path


def write_fleet_workbook(result: ImportResult, path, source: str = "", sha256: str = "") -> Path:
    """The fleet workbook of ``result`` at ``path`` (.xlsx), atomically."""
    path = Path(path)
    vehicle_columns = [c.name for c in VEHICLE_COLUMNS]
    scenario = default_scenario()
    with atomic_file(path) as tmp:
        book = xlsxwriter.Workbook(str(tmp), {"nan_inf_to_errors": True, "strings_to_formulas": False,
                                              "strings_to_urls": False})
        bold = book.add_format({"bold": True})
        _sheet(book, VEHICLES_SHEET, vehicle_columns, result.vehicles, bold)
        _sheet(book, SCENARIOS_SHEET, [c.name for c in SCENARIO_COLUMNS if c.name in scenario], [scenario], bold)
        _sheet(book, "Measured", MEASURED_COLUMNS, result.measured, bold)
        _sheet(book, "Derived", DERIVED_COLUMNS, result.derived, bold)
        _sheet(book, "Excluded", EXCLUDED_COLUMNS, result.excluded, bold)
        _about(book, result, source, sha256, bold)
        book.close()
    return path


def _sheet(book, name, columns, rows, bold) -> None:
    sheet = book.add_worksheet(name)
    sheet.write_row(0, 0, list(columns), bold)
    for r, row in enumerate(rows, start=1):
        for c, column in enumerate(columns):
            value = row.get(column)
            if value is not None and value != "":
                sheet.write(r, c, value)
    sheet.freeze_panes(1, 1)
    sheet.set_column(0, len(columns) - 1, 14)


def _about(book, result: ImportResult, source: str, sha256: str, bold) -> None:
    sheet = book.add_worksheet("About")
    lines = [
        ("fleetrun import-epa", None),
        ("source", source), ("source sha256", sha256),
        ("test rows read", result.rows_read), ("test rows selected (--model-year/--make)", result.rows_selected),
        ("vehicle configurations modelled (Vehicles)", len(result.vehicles)),
        ("configurations excluded (Excluded, with the reason)", len(result.excluded)),
        ("measured results (Measured)", len(result.measured)),
        ("", None),
        ("excluded, by rule (the first that applies)", None),
        *sorted(Counter(e["rule"] for e in result.excluded).items(), key=lambda kv: (-kv[1], kv[0])),
        ("", None),
        ("rules", "docs/epa-import.md; constants in models/epa_import.toml"),
        ("vehicle_id", "<Test Vehicle ID>_c<Test Veh Configuration #>"),
        ("duplicate tests", "several rows of one test of one configuration: harmonic mean (mean fuel per mile); "
                            "n_tests and test_numbers in Measured"),
        ("Derived", "every value not copied from the list (peak torque, tyre, gear ratios, class, defaults) "
                    "with the rule that made it"),
    ]
    for r, (key, value) in enumerate(lines):
        sheet.write(r, 0, key, bold if value is None or r == 0 else None)
        if value is not None:
            sheet.write(r, 1, value)
    sheet.set_column(0, 0, 48)
    sheet.set_column(1, 1, 90)
