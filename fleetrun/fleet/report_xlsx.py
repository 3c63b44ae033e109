"""``report.xlsx``: the run as a workbook an analyst can hand on.

Sheets: Summary, ByClass, ByVehicle, Scenario comparison, Efficiency maps, Inputs, RunInfo.
Native Excel charts, number formats, frozen headers. Written with openpyxl's write-only mode
so 100,000 vehicle rows x scenarios stay fast and memory-bounded.

Every text that came from the input workbook is written as a text cell: a label such as
``=HYPERLINK(...)`` or ``+cmd|...`` shows as typed and is never evaluated.
"""
from __future__ import annotations

import contextlib
import math
from pathlib import Path

import pandas as pd
from openpyxl import Workbook
from openpyxl.cell import WriteOnlyCell
from openpyxl.cell.cell import ILLEGAL_CHARACTERS_RE
from openpyxl.chart import BarChart, LineChart, Reference
from openpyxl.formatting.rule import ColorScaleRule
from openpyxl.styles import Alignment, Font, PatternFill
from openpyxl.utils import get_column_letter

from fleetrun.fleet.runner import RunResult
from fleetrun.fleet.totals import scenario_totals, yearly_totals
from fleetrun.fleet.schema import SCENARIO_COLUMNS, VEHICLE_COLUMNS

HEADER_FONT = Font(bold=True, color="FFFFFF")
HEADER_FILL = PatternFill("solid", fgColor="1F4E78")
TITLE_FONT = Font(bold=True, size=14)

FORMATS = {
    "count": "#,##0", "vehicles": "#,##0", "vehicle_types": "#,##0",
    "miles_total": "#,##0", "fuel_gal_total": "#,##0",
    "mpg": "0.00", "diff_efficiency": "0.0000", "drivetrain_efficiency": "0.0000",
    "state_tax_usd": '"$"#,##0', "federal_tax_usd": '"$"#,##0', "total_tax_usd": '"$"#,##0',
    "diff_input_energy_J": "0.000E+00", "diff_output_energy_J": "0.000E+00",
    "drivetrain_input_energy_J": "0.000E+00", "wheel_energy_J": "0.000E+00",
    "change_pct": "+0.00%;-0.00%;0.00%", "efficiency": "0.000",
    "miles": "#,##0", "fuel_gal": "#,##0", "fuel_gal_low": "#,##0", "fuel_gal_high": "#,##0",
    "fuel_gal_low_total": "#,##0", "fuel_gal_high_total": "#,##0", "fuel_gal_cycle_total": "#,##0",
    "fuel_gal_uncalibrated_total": "#,##0", "co2_t": "#,##0", "kwh": "#,##0", "kwh_total": "#,##0", "ev_fee_usd": '"$"#,##0',
    "model_gallons": "#,##0", "observed_gallons": "#,##0", "model_to_observed": "0.000", "scale": "0.0000",
}


def text_cell(ws, value):
    """A cell that shows ``value`` as text, never a formula (and without XML-illegal chars)."""
    cell = WriteOnlyCell(ws, value=ILLEGAL_CHARACTERS_RE.sub("", str(value)))
    cell.data_type = "s"
    return cell


def _value(ws, value, number_format=None):
    if isinstance(value, str):
        return text_cell(ws, value)
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    if number_format:
        cell = WriteOnlyCell(ws, value=value)
        cell.number_format = number_format
        return cell
    return value


def _header(ws, names):
    cells = []
    for name in names:
        cell = text_cell(ws, name)
        cell.font = HEADER_FONT
        cell.fill = HEADER_FILL
        cell.alignment = Alignment(horizontal="center", wrap_text=True)
        cells.append(cell)
    ws.append(cells)


def _widths(ws, names, minimum=10, maximum=40):
    for i, name in enumerate(names, start=1):
        ws.column_dimensions[get_column_letter(i)].width = max(minimum, min(maximum, len(name) + 2))


def _table(ws, frame: pd.DataFrame, styled: bool = True, widths: bool = True):
    names = list(frame.columns)
    if widths:
        _widths(ws, names)      # write-only sheets: layout before the first row
    _header(ws, names)
    formats = [FORMATS.get(n) if styled else None for n in names]
    for row in frame.itertuples(index=False, name=None):
        ws.append([_value(ws, v, f) for v, f in zip(row, formats)])


@contextlib.contextmanager
def _full_precision_numbers():
    """openpyxl writes floats with 16 significant digits ("%.16g"), which changes the last bit
    of some values; Excel reads 17. Write the shortest round-trip repr instead so every number
    in report.xlsx equals the one in the CSVs bit for bit."""
    from openpyxl.cell import _writer

    original = _writer.safe_string

    def safe_string(value):
        if isinstance(value, float) and math.isfinite(value):
            return repr(float(value))
        return original(value)

    _writer.safe_string = safe_string
    try:
        yield
    finally:
        _writer.safe_string = original


def write_report_xlsx(result: RunResult, path: Path) -> None:
    from fleetrun.fleet.xlsx_bulk import append_rows

    bulk: dict = {}   # sheet title -> (template row, columns, remaining rows), see xlsx_bulk
    # Write-only sheets stream their rows as they are appended: the whole build is inside.
    with _full_precision_numbers():
        wb = Workbook(write_only=True)
        totals = scenario_totals(result.classes)
        _summary(wb, result, totals)
        _by_class(wb, result)
        _by_vehicle(wb, result, bulk)
        _comparison(wb, result)
        _fiscal(wb, result)
        _maps(wb, result)
        _inputs(wb, result, bulk)
        _run_info(wb, result)
        wb.save(path)
    if bulk:
        append_rows(path, bulk)


def _summary(wb, result: RunResult, totals: pd.DataFrame):
    ws = wb.create_sheet("Summary")
    header_row = 6
    ws.freeze_panes = f"A{header_row + 1}"   # write-only sheets: layout before the first row
    for letter, width in zip("ABCDEFGHIJK", (22, 36, 12, 12, 16, 16, 10, 16, 16, 16)):
        ws.column_dimensions[letter].width = width
    descriptions = {s.scenario_id: s.description for s in result.scenarios}
    years = {s.scenario_id: s.budget_years for s in result.scenarios}
    title = text_cell(ws, "Fleet fuel and fuel-tax forecast")
    title.font = TITLE_FONT
    ws.append([title])
    ws.append([text_cell(ws, "Fleet workbook"), text_cell(ws, result.fleet.path.name)])
    ws.append([text_cell(ws, "sha256"), text_cell(ws, result.fleet.sha256)])
    ws.append([text_cell(ws, "Warnings"), len(result.warnings)])
    ws.append([])
    frame = totals.copy()
    frame.insert(1, "description", [descriptions.get(s, "") for s in frame["scenario_id"]])
    frame.insert(2, "budget_years", [years.get(s) for s in frame["scenario_id"]])
    _table(ws, frame, widths=False)
    n = len(frame)
    if n:
        chart = BarChart()
        chart.type = "col"
        chart.title = "Fuel-tax revenue over the budget period by scenario"
        chart.y_axis.title = "US$"
        chart.y_axis.numFmt = '"$"#,##0'
        cols = list(frame.columns)
        for name in ("state_tax_usd", "federal_tax_usd"):
            col = cols.index(name) + 1
            chart.add_data(Reference(ws, min_col=col, min_row=header_row, max_row=header_row + n),
                           titles_from_data=True)
        chart.set_categories(Reference(ws, min_col=1, min_row=header_row + 1, max_row=header_row + n))
        chart.height, chart.width = 8, 16
        ws.add_chart(chart, f"A{header_row + n + 3}")


def _by_class(wb, result: RunResult):
    ws = wb.create_sheet("ByClass")
    frame = result.classes
    ws.freeze_panes = "C2"
    _widths(ws, list(frame.columns))
    ws.column_dimensions["B"].width = 28
    _table(ws, frame, widths=False)
    n = len(frame)
    if not n:
        return
    # One chart: gallons by class, one series per scenario (classes x scenarios pivot below).
    pivot = frame.pivot_table(index="vehicle_class", columns="scenario_id", values="fuel_gal_total",
                              aggfunc="sum", sort=False)
    start = n + 4
    for _ in range(n + 1, start - 1):
        ws.append([])
    ws.append([text_cell(ws, "Fuel over the budget period [gal] by class and scenario")])
    ws.append([text_cell(ws, "vehicle_class")] + [text_cell(ws, s) for s in pivot.columns])
    for label, row in pivot.iterrows():
        ws.append([text_cell(ws, label)] + [_value(ws, float(v), "#,##0") for v in row])
    header = start + 1
    chart = BarChart()
    chart.type = "bar"
    chart.title = "Fuel by vehicle class [gal]"
    chart.x_axis.title = None
    chart.y_axis.numFmt = "#,##0"
    chart.add_data(Reference(ws, min_col=2, max_col=1 + len(pivot.columns), min_row=header,
                             max_row=header + len(pivot)), titles_from_data=True)
    chart.set_categories(Reference(ws, min_col=1, min_row=header + 1, max_row=header + len(pivot)))
    chart.height, chart.width = max(8, 0.6 * len(pivot) * len(pivot.columns)), 18
    ws.add_chart(chart, f"{get_column_letter(len(frame.columns) + 2)}2")


def _by_vehicle(wb, result: RunResult, bulk: dict):
    ws = wb.create_sheet("ByVehicle")
    ws.freeze_panes = "C2"
    frame = result.results
    ws.auto_filter.ref = f"A1:{get_column_letter(len(frame.columns))}{len(frame) + 1}"
    # openpyxl writes the header and the first row (and so the styles); the rest in bulk.
    _table(ws, frame.iloc[:1])
    if len(frame) > 1:
        bulk[ws.title] = (2, len(frame.columns), frame.iloc[1:].itertuples(index=False, name=None))


def _comparison(wb, result: RunResult):
    ws = wb.create_sheet("Scenario comparison")
    classes = result.classes
    scenario_ids = [s.scenario_id for s in result.scenarios]
    base = scenario_ids[0] if scenario_ids else None
    names = ["vehicle_class", "scenario_id", "fuel_gal_total", "mpg", "state_tax_usd",
             "federal_tax_usd", "fuel_change_pct", "state_tax_change_pct"]
    _widths(ws, names, minimum=14)
    ws.column_dimensions["A"].width = 28
    ws.freeze_panes = "C3"
    title = text_cell(ws, f"Change against the first scenario ({base})")
    title.font = TITLE_FONT
    ws.append([title])
    _header(ws, names)
    baseline = classes[classes["scenario_id"] == base].set_index("vehicle_class")
    for _, row in classes.iterrows():
        ref = baseline.loc[row["vehicle_class"]] if row["vehicle_class"] in baseline.index else None
        fuel_change = (row["fuel_gal_total"] / ref["fuel_gal_total"] - 1.0
                       if ref is not None and ref["fuel_gal_total"] else None)
        tax_change = (row["state_tax_usd"] / ref["state_tax_usd"] - 1.0
                      if ref is not None and ref["state_tax_usd"] else None)
        ws.append([text_cell(ws, row["vehicle_class"]), text_cell(ws, row["scenario_id"]),
                   _value(ws, row["fuel_gal_total"], FORMATS["fuel_gal_total"]),
                   _value(ws, row["mpg"], FORMATS["mpg"]),
                   _value(ws, row["state_tax_usd"], FORMATS["state_tax_usd"]),
                   _value(ws, row["federal_tax_usd"], FORMATS["federal_tax_usd"]),
                   _value(ws, fuel_change, FORMATS["change_pct"]),
                   _value(ws, tax_change, FORMATS["change_pct"])])
    ws.append([])
    year_title_row = len(classes) + 4
    t = text_cell(ws, "By budget year")
    t.font = Font(bold=True)
    ws.append([t])
    years = yearly_totals(result.fiscal)
    _header(ws, list(years.columns))
    for row in years.itertuples(index=False, name=None):
        ws.append([_value(ws, v, FORMATS.get(c)) for v, c in zip(row, years.columns)])
    if len(years):
        # Revenue per year, one series per scenario.
        pivot = years.pivot_table(index="fiscal_year", columns="scenario_id", values="state_tax_usd",
                                  aggfunc="sum", sort=False)
        ws.append([])
        pivot_row = year_title_row + len(years) + 3
        ws.append([text_cell(ws, "year")] + [text_cell(ws, s) for s in pivot.columns])
        for year, row in pivot.iterrows():
            ws.append([int(year)] + [_value(ws, float(v), FORMATS["state_tax_usd"]) for v in row])
        chart = BarChart()
        chart.type = "col"
        chart.title = "State fuel-tax revenue by budget year"
        chart.y_axis.numFmt = '"$"#,##0'
        chart.add_data(Reference(ws, min_col=2, max_col=1 + len(pivot.columns), min_row=pivot_row,
                                 max_row=pivot_row + len(pivot)), titles_from_data=True)
        chart.set_categories(Reference(ws, min_col=1, min_row=pivot_row + 1, max_row=pivot_row + len(pivot)))
        chart.height, chart.width = 8, 16
        ws.add_chart(chart, "J2")


def _fiscal(wb, result: RunResult):
    """Fiscal year x fuel x class (fiscal_summary.csv) and the calibration to collections."""
    ws = wb.create_sheet("Fiscal years")
    frame = result.fiscal
    _widths(ws, list(frame.columns), minimum=12)
    ws.freeze_panes = "E2"
    _table(ws, frame, widths=False)
    calibration = result.calibration
    if calibration is not None and len(calibration):
        ws.append([])
        t = text_cell(ws, "Calibration to collections: model vs observed taxable gallons, first fiscal year")
        t.font = Font(bold=True)
        ws.append([t])
        _table(ws, calibration, widths=False)


def _maps(wb, result: RunResult):
    ws = wb.create_sheet("Efficiency maps")
    ws.column_dimensions["A"].width = 26
    title = text_cell(ws, "Differential efficiency: torque fraction (rows) x input speed [rpm] (columns)")
    title.font = TITLE_FONT
    ws.append([title])
    if not result.maps:
        ws.append([text_cell(ws, "No efficiency maps (see RunInfo warnings).")])
        return
    row = 2
    for m in result.maps:
        ws.append([])
        row += 1
        label = f"{m['configuration']}: gear ratio {m['gear_ratio']:g}"
        if m["low_gear_ratio"]:
            label += f", low ratio {m['low_gear_ratio']:g} (axle in high gear)"
        label += f"; {m['vehicle_types']} vehicle type(s)"
        head = text_cell(ws, label)
        head.font = Font(bold=True)
        ws.append([head])
        row += 1
        ws.append([text_cell(ws, "torque_fraction \\ rpm")] + [float(s) for s in m["speeds_rpm"]])
        header_row = row + 1
        row += 1
        for tf, etas in zip(m["torque_fractions"], m["efficiency"]):
            ws.append([tf] + [_value(ws, float(e), FORMATS["efficiency"]) for e in etas])
            row += 1
        first, last = header_row + 1, row
        last_col = get_column_letter(1 + len(m["speeds_rpm"]))
        ws.conditional_formatting.add(
            f"B{first}:{last_col}{last}",
            ColorScaleRule(start_type="min", start_color="F8696B", mid_type="percentile", mid_value=50,
                           mid_color="FFEB84", end_type="max", end_color="63BE7B"))
        chart = LineChart()
        chart.title = f"{m['configuration']} efficiency vs torque fraction"
        chart.y_axis.title = "efficiency"
        chart.x_axis.title = "torque fraction"
        chart.y_axis.scaling.min = 0
        chart.y_axis.scaling.max = 1
        chart.add_data(Reference(ws, min_col=2, max_col=1 + len(m["speeds_rpm"]), min_row=header_row,
                                 max_row=last), titles_from_data=True)
        chart.set_categories(Reference(ws, min_col=1, min_row=first, max_row=last))
        chart.height, chart.width = 7, 14
        ws.add_chart(chart, f"{get_column_letter(len(m['speeds_rpm']) + 3)}{header_row - 1}")
        for _ in range(3):
            ws.append([])
            row += 1


def _inputs(wb, result: RunResult, bulk: dict):
    ws = wb.create_sheet("Inputs")
    fleet = result.fleet
    extra_names = list(dict.fromkeys(k for v in fleet.vehicles for k in v.extra))
    vehicle_names = [c.name for c in VEHICLE_COLUMNS] + extra_names
    _widths(ws, vehicle_names)
    # Scenarios first (a few rows), then the Vehicles table, whose rows may be many.
    t = text_cell(ws, "Scenarios (as read)")
    t.font = Font(bold=True)
    ws.append([t])
    _header(ws, [c.name for c in SCENARIO_COLUMNS])
    for s in fleet.scenarios:
        values = []
        for c in SCENARIO_COLUMNS:
            value = getattr(s, c.name)
            if c.kind == "cycle_mix" and value:
                value = ",".join(f"{Path(k).name if k.lower().endswith('.csv') else k}:{w:g}"
                                 for k, w in value.items())
            values.append(_value(ws, value))
        ws.append(values)
    ws.append([])
    t = text_cell(ws, "Vehicles (as read)")
    t.font = Font(bold=True)
    ws.append([t])
    _header(ws, vehicle_names)
    header_row = len(fleet.scenarios) + 5

    def row_of(v):
        values = []
        for c in VEHICLE_COLUMNS:
            value = getattr(v, c.name)
            if c.name == "transmission_gear_ratios":
                value = ",".join(f"{r:g}" for r in value)
            values.append(value)
        return values + [v.extra.get(k) for k in extra_names]

    if fleet.vehicles:
        ws.append([_value(ws, x) for x in row_of(fleet.vehicles[0])])
        if len(fleet.vehicles) > 1:
            bulk[ws.title] = (header_row + 1, len(vehicle_names),
                              (row_of(v) for v in fleet.vehicles[1:]))


def _run_info(wb, result: RunResult):
    from fleetrun.fleet.manifest import manifest_dict, physics_label

    ws = wb.create_sheet("RunInfo")
    ws.column_dimensions["A"].width = 30
    ws.column_dimensions["B"].width = 90
    info = manifest_dict(result)
    for key in ("fleetrun_version", "created_utc", "physics", "mode"):
        ws.append([text_cell(ws, key), text_cell(ws, info[key])])
    ws.append([text_cell(ws, "with (effects)"), text_cell(ws, physics_label(info) if info.get("with") else "none")])
    for key, value in info["engine"].items():
        ws.append([text_cell(ws, key), text_cell(ws, value)])
    ws.append([text_cell(ws, "scenarios"), text_cell(ws, ", ".join(info["scenarios"]))])
    for key, value in info["timings_s"].items():
        ws.append([text_cell(ws, f"time {key} [s]"), round(value, 3)])
    ws.append([])
    ws.append([text_cell(ws, "Inputs"), text_cell(ws, "sha256")])
    for item in info["inputs"]:
        ws.append([text_cell(ws, item["path"]), text_cell(ws, item["sha256"])])
    ws.append([])
    ws.append([text_cell(ws, "Drive cycles"), text_cell(ws, "miles, duration")])
    for name, c in result.cycles.items():
        ws.append([text_cell(ws, c["name"]), text_cell(ws, f"{c['miles']:.3f} mi, {c['duration_s']:.0f} s")])
    ws.append([])
    ws.append([text_cell(ws, f"Warnings ({len(result.warnings)})")])
    for warning in result.warnings:
        ws.append([None, text_cell(ws, warning)])
