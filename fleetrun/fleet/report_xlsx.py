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
from openpyxl.chart import BarChart, LineChart, Reference, Series
from openpyxl.formatting.rule import ColorScaleRule
from openpyxl.styles import Alignment, Font, PatternFill
from openpyxl.utils import get_column_letter
from openpyxl.worksheet.page import PageMargins
from openpyxl.worksheet.properties import PageSetupProperties

from fleetrun.fleet.charts import efficiency_scale
from fleetrun.fleet.runner import RunResult
from fleetrun.fleet.totals import scenario_totals, yearly_totals
from fleetrun.fleet.schema import SCENARIO_COLUMNS, VEHICLE_COLUMNS

HEADER_FONT = Font(bold=True, color="FFFFFF")
HEADER_FILL = PatternFill("solid", fgColor="1F4E78")
TITLE_FONT = Font(bold=True, size=14)

FORMATS = {
    "count": "#,##0", "vehicles": "#,##0", "vehicle_types": "#,##0",
    "miles_total": "#,##0", "fuel_gal_total": "#,##0",
    "mpg": "0.00", "diff_efficiency": "0.00%", "drivetrain_efficiency": "0.00%",
    "state_tax_usd": '"$"#,##0', "federal_tax_usd": '"$"#,##0', "total_tax_usd": '"$"#,##0',
    "diff_input_energy_J": "0.000E+00", "diff_output_energy_J": "0.000E+00",
    "drivetrain_input_energy_J": "0.000E+00", "wheel_energy_J": "0.000E+00",
    "change_pct": "+0.00%;-0.00%;0.00%", "efficiency": "0.0%",
    "miles": "#,##0", "fuel_gal": "#,##0", "fuel_gal_low": "#,##0", "fuel_gal_high": "#,##0",
    "fuel_gal_low_total": "#,##0", "fuel_gal_high_total": "#,##0", "fuel_gal_cycle_total": "#,##0",
    "fuel_gal_uncalibrated_total": "#,##0", "co2_t": "#,##0", "kwh": "#,##0", "kwh_total": "#,##0", "ev_fee_usd": '"$"#,##0',
    "model_gallons": "#,##0", "observed_gallons": "#,##0", "model_to_observed": "0.0%", "scale": "0.0000",
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
        _assumptions(wb, result)
        _by_class(wb, result)
        _by_vehicle(wb, result, bulk)
        _comparison(wb, result)
        _fiscal(wb, result)
        _maps(wb, result)
        _inputs(wb, result, bulk)
        _run_info(wb, result)
        _what_changed(wb, result)
        wb.save(path)
    if bulk:
        append_rows(path, bulk)


# --- printing and charts ------------------------------------------------------------------

def page_setup(ws, *, landscape: bool = True, title_rows: str | None = "1:1", one_page: bool = False) -> None:
    """Print layout of a sheet: US letter, fit to the page width (and height for one page),
    the header row repeated on every page, the sheet name and page number in the footer."""
    ws.page_setup.orientation = "landscape" if landscape else "portrait"
    ws.page_setup.paperSize = "1"   # US letter (ECMA-376 paper size 1)
    ws.page_setup.fitToWidth = 1
    ws.page_setup.fitToHeight = 1 if one_page else 0
    ws.sheet_properties.pageSetUpPr = PageSetupProperties(fitToPage=True)
    ws.page_margins = PageMargins(left=0.4, right=0.4, top=0.5, bottom=0.6)
    ws.oddFooter.center.text = "&A, page &P of &N"
    if title_rows:
        ws.print_title_rows = title_rows


def _axes(chart, x_title: str, y_title: str, y_format: str) -> None:
    """Axis titles with units, a value axis from zero, the legend below the plot."""
    chart.x_axis.title = x_title
    chart.y_axis.title = y_title
    chart.y_axis.numFmt = y_format
    chart.y_axis.scaling.min = 0
    chart.x_axis.delete = False
    chart.y_axis.delete = False
    chart.legend.position = "b"


def _series(ws, column: int, first_row: int, last_row: int, title: str) -> Series:
    """One chart series over ``column``'s rows with a human legend text."""
    return Series(Reference(ws, min_col=column, min_row=first_row, max_row=last_row), title=title)


def _scenario_bars(ws, pivot: pd.DataFrame, header_row: int, bar_type: str, title: str,
                   axes: tuple[str, str, str], size: tuple[float, float]) -> None:
    """A bar chart of ``pivot`` as written below ``header_row`` (labels in column A, one
    column and one series per scenario), placed two rows under the table."""
    first, last = header_row + 1, header_row + len(pivot)
    chart = BarChart()
    chart.type = bar_type
    chart.title = title
    _axes(chart, *axes)
    for k, scenario_id in enumerate(pivot.columns):
        chart.series.append(_series(ws, 2 + k, first, last, f"Scenario {scenario_id}"))
    chart.set_categories(Reference(ws, min_col=1, min_row=first, max_row=last))
    chart.height, chart.width = size
    ws.add_chart(chart, f"A{last + 2}")


def _summary(wb, result: RunResult, totals: pd.DataFrame):
    ws = wb.create_sheet("Summary")
    header_row = 6
    ws.freeze_panes = f"A{header_row + 1}"   # write-only sheets: layout before the first row
    page_setup(ws, title_rows=None, one_page=True)
    names = ["scenario_id", "description", "budget_years"] + list(totals.columns[1:])
    _widths(ws, names, minimum=12)
    ws.column_dimensions["B"].width = 30
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
    row = header_row + n
    row = _summary_words(ws, result, row)
    if n:
        chart = BarChart()
        chart.type = "col"
        chart.title = "Fuel-tax revenue over the budget period"
        _axes(chart, "Scenario", "US$ over the budget period", '"$"#,##0')
        cols = list(frame.columns)
        for name, label in (("state_tax_usd", "State fuel tax"), ("federal_tax_usd", "Federal fuel tax")):
            chart.series.append(_series(ws, cols.index(name) + 1, header_row + 1, header_row + n, label))
        chart.set_categories(Reference(ws, min_col=1, min_row=header_row + 1, max_row=header_row + n))
        chart.height, chart.width = 7.5, 16
        ws.add_chart(chart, f"A{row + 2}")


def _summary_words(ws, result: RunResult, row: int) -> int:
    """The headline of each scenario (rounded to its range; state and federal apart) and
    where the ranges come from; the last row written."""
    from fleetrun.fleet import report_text

    ranges = report_text.scenario_ranges(result.fiscal, result.scenarios)
    bold = Font(bold=True)
    heads = [text_cell(ws, "Headline (rounded to its range)")] + [None] * 12
    for column, label in ((1, "Fuel"), (5, "State fuel tax"), (9, "Federal fuel tax")):
        heads[column] = text_cell(ws, label)
    for cell in heads:
        if cell is not None:
            cell.font = bold
    lines: list[list] = [[], heads]
    for s in result.scenarios:
        texts = dict(report_text.headline(s, ranges[s.scenario_id]))
        line = [text_cell(ws, s.scenario_id)] + [None] * 12
        for column, label in ((1, "Fuel"), (5, "State fuel tax"), (9, "Federal fuel tax")):
            line[column] = text_cell(ws, texts[label])
        lines.append(line)
    for sentence in report_text.range_source_lines(result.error_model):
        lines.append([None, text_cell(ws, sentence)])
    lines.append([None, text_cell(ws, "Rates, mixes, growth, temperature and on-road fuel of each scenario: "
                                      "see the Assumptions sheet.")])
    for line in lines:
        ws.append(line)
    return row + len(lines)


ASSUMPTION_WIDTH = 48   # characters per scenario column of the Assumptions sheet


def _assumptions(wb, result: RunResult):
    """One column per scenario, one row per assumption (report_text.assumptions)."""
    from fleetrun.fleet import report_text

    ws = wb.create_sheet("Assumptions")
    page_setup(ws)
    ws.column_dimensions["A"].width = 30
    for k in range(len(result.scenarios)):
        ws.column_dimensions[get_column_letter(2 + k)].width = ASSUMPTION_WIDTH
    ws.freeze_panes = "B2"
    _header(ws, ["assumption"] + [s.scenario_id for s in result.scenarios])
    table = [dict(report_text.assumptions(s)) for s in result.scenarios]
    labels = list(dict.fromkeys(label for t in table for label in t))
    wrap = Alignment(wrap_text=True, vertical="top")
    for row, label in enumerate(labels, start=2):
        texts = [label] + [t.get(label, "") for t in table]
        # write-only sheets cannot grow a row to its wrapped text: give it the lines it needs
        lines = max(math.ceil(len(text) / (ASSUMPTION_WIDTH * 1.05)) for text in texts)
        ws.row_dimensions[row].height = 15 * max(1, lines)
        cells = [text_cell(ws, text) for text in texts]
        for cell in cells:
            cell.alignment = wrap
        ws.append(cells)


def _by_class(wb, result: RunResult):
    ws = wb.create_sheet("ByClass")
    frame = result.classes
    ws.freeze_panes = "C2"
    page_setup(ws)
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
    _scenario_bars(ws, pivot, start + 1, "bar", "Fuel by vehicle class over the budget period",
                   ("Vehicle class", "US gallons", "#,##0"),
                   (max(7.5, 0.5 * len(pivot) * len(pivot.columns)), 18))


def _by_vehicle(wb, result: RunResult, bulk: dict):
    ws = wb.create_sheet("ByVehicle")
    ws.freeze_panes = "C2"
    page_setup(ws)
    frame = result.results
    ws.auto_filter.ref = f"A1:{get_column_letter(len(frame.columns))}{len(frame) + 1}"
    # openpyxl writes the header and the first row (and so the styles); the rest in bulk.
    _table(ws, frame.iloc[:1])
    if len(frame) > 1:
        bulk[ws.title] = (2, len(frame.columns), frame.iloc[1:].itertuples(index=False, name=None))


def _comparison(wb, result: RunResult):
    ws = wb.create_sheet("Scenario comparison")
    page_setup(ws, title_rows="2:2")
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
    _by_fiscal_year(ws, result, len(classes) + 4)


def _by_fiscal_year(ws, result: RunResult, title_row: int) -> None:
    """Fleet totals per scenario and fiscal year, and a chart of state revenue per year."""
    t = text_cell(ws, "By fiscal year (fleet totals)")
    t.font = Font(bold=True)
    ws.append([t])
    years = yearly_totals(result.fiscal)
    _header(ws, list(years.columns))
    for row in years.itertuples(index=False, name=None):
        ws.append([_value(ws, v, FORMATS.get(c)) for v, c in zip(row, years.columns)])
    if not len(years):
        return
    # State revenue per fiscal year, one series per scenario.
    pivot = years.pivot_table(index="fiscal_year", columns="scenario_id", values="state_tax_usd",
                              aggfunc="sum", sort=False)
    ws.append([])
    pivot_row = title_row + len(years) + 3
    ws.append([text_cell(ws, "fiscal_year")] + [text_cell(ws, s) for s in pivot.columns])
    for year, row in pivot.iterrows():
        ws.append([text_cell(ws, str(int(year)))] + [_value(ws, float(v), FORMATS["state_tax_usd"]) for v in row])
    _scenario_bars(ws, pivot, pivot_row, "col", "State fuel-tax revenue by fiscal year",
                   ("Fiscal year", "US$ (state fuel tax)", '"$"#,##0'), (7.5, 16))


def _fiscal(wb, result: RunResult):
    """Fiscal year x fuel x class (fiscal_summary.csv) and the calibration to collections."""
    ws = wb.create_sheet("Fiscal years")
    page_setup(ws)
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


MAP_BLOCK_ROWS = 2   # blank + title rows before each map's table


def _maps(wb, result: RunResult):
    ws = wb.create_sheet("Efficiency maps")
    page_setup(ws, title_rows=None)
    ws.column_dimensions["A"].width = 24
    title = text_cell(ws, "Differential efficiency: torque fraction (rows) x input speed (columns); "
                          "one colour scale for all maps")
    title.font = TITLE_FONT
    ws.append([title])
    if not result.maps:
        ws.append([text_cell(ws, "No efficiency maps (see RunInfo warnings).")])
        return
    low, high = efficiency_scale(result.maps)
    row = 1   # the last row written
    for m in result.maps:
        row = _map_block(ws, m, row, low, high)


def _map_block(ws, m: dict, row: int, low: float, high: float) -> int:
    """One map: its efficiency table, its loss table (what the chart draws, from zero) and
    the chart beside them; the last row written. Rows are counted as they are written."""
    from openpyxl.worksheet.pagebreak import Break

    if row > 1:
        ws.row_breaks.append(Break(id=row))   # each map starts a printed page
    label = f"{m['configuration']}: gear ratio {m['gear_ratio']:g}"
    if m["low_gear_ratio"]:
        label += f", low ratio {m['low_gear_ratio']:g} (axle in high gear)"
    head = text_cell(ws, label + f"; {m['vehicle_types']} vehicle type(s)")
    head.font = Font(bold=True)
    ws.append([])
    ws.append([head])
    row += MAP_BLOCK_ROWS
    speeds = [f"{s:g} rpm" for s in m["speeds_rpm"]]
    n_rows, last_col = len(m["torque_fractions"]), get_column_letter(1 + len(speeds))
    for kind in ("efficiency", "loss"):
        ws.append([text_cell(ws, f"{kind} \\ torque fraction")] + [text_cell(ws, s) for s in speeds])
        header_row = row = row + 1
        for tf, etas in zip(m["torque_fractions"], m["efficiency"]):
            values = etas if kind == "efficiency" else [1.0 - e for e in etas]
            ws.append([tf] + [_value(ws, float(e), FORMATS["efficiency"]) for e in values])
            row += 1
        if kind == "efficiency":
            efficiency_header = header_row
            ws.conditional_formatting.add(
                f"B{header_row + 1}:{last_col}{row}",
                ColorScaleRule(start_type="num", start_value=low, start_color="F8696B", mid_type="num",
                               mid_value=(low + high) / 2, mid_color="FFEB84", end_type="num", end_value=high,
                               end_color="63BE7B"))
    chart = _map_chart(ws, m, header_row, n_rows, len(speeds))
    ws.add_chart(chart, f"{get_column_letter(len(speeds) + 3)}{efficiency_header}")
    return row


def _map_chart(ws, m: dict, header_row: int, n_rows: int, n_speeds: int) -> LineChart:
    """Loss (1 - efficiency) against torque fraction, one line per input speed, from zero."""
    chart = LineChart()
    chart.title = f"{m['configuration']} differential loss"
    _axes(chart, "Torque fraction (input torque / Kim torque scale)", "Loss, share of input power", "0%")
    chart.add_data(Reference(ws, min_col=2, max_col=1 + n_speeds, min_row=header_row,
                             max_row=header_row + n_rows), titles_from_data=True)
    chart.set_categories(Reference(ws, min_col=1, min_row=header_row + 1, max_row=header_row + n_rows))
    chart.height, chart.width = 11, 16
    return chart


def _inputs(wb, result: RunResult, bulk: dict):
    ws = wb.create_sheet("Inputs")
    page_setup(ws, title_rows=None)
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
    page_setup(ws, landscape=False, title_rows=None)
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


def _what_changed(wb, result: RunResult):
    """The comparison with the run that was in the output folder (fleetrun.fleet.changes)."""
    ws = wb.create_sheet("What changed")
    page_setup(ws, title_rows=None)
    for letter, width in zip("ABCDE", (40, 18, 20, 20, 14)):
        ws.column_dimensions[letter].width = width
    changes = result.changes
    title = text_cell(ws, "What changed since the earlier run in this output folder")
    title.font = TITLE_FONT
    ws.append([title])
    if not changes:
        ws.append([text_cell(ws, "No earlier run in this folder: nothing to compare.")])
        return
    ws.append([text_cell(ws, "Earlier run"), text_cell(ws, f"{changes['earlier_created_utc']} "
                                                           f"(fleetrun {changes['earlier_version']})")])
    ws.append([])
    _header(ws, ["input", "status", "earlier sha256", "sha256"])
    for item in changes["inputs"]:
        ws.append([text_cell(ws, item["path"]), text_cell(ws, item["status"]),
                   text_cell(ws, item["earlier_sha256"] or ""), text_cell(ws, item["sha256"] or "")])
    ws.append([])
    _header(ws, ["scenario_id", "total", "earlier", "now", "change"])
    for row in changes["totals"]:
        ws.append([text_cell(ws, row["scenario_id"]), text_cell(ws, row["total"]),
                   _value(ws, row["earlier"], "#,##0"), _value(ws, row["now"], "#,##0"),
                   _value(ws, row["change_pct"], FORMATS["change_pct"])])
