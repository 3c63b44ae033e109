"""``report.xlsx``: the run as a workbook an analyst can hand on.

Sheets: Summary, Revenue memo, Assumptions, ByClass, ByVehicle, Scenario comparison, Fiscal
years, Fiscal periods, Efficiency maps, Inputs, RunInfo, What changed. Native Excel charts, number formats, frozen
headers, a page setup on every sheet. Written with XlsxWriter in its ``constant_memory``
mode: each sheet is streamed row by row to a temporary file. The workbook stays a document a
person opens: per-vehicle tables beyond :data:`DETAIL_ROWS` rows (the Vehicles echoed in Inputs:
:data:`INPUT_ROWS`) are not copied in (the sheet
says so and where they are: results.csv, results.parquet), and no sheet is ever cut at Excel's
row limit without an error.

Numbers: XlsxWriter writes 16 significant digits (``%.16G``), Excel keeps 15; results.csv
is the exact copy (shortest round-trip repr). Non-finite numbers are never written (the
cell stays empty). Every text is written as a text cell, never a formula or a link
(``strings_to_formulas``, ``strings_to_urls``, ``strings_to_numbers`` all off); a text that a
spreadsheet would take for a formula (``=HYPERLINK(...)``, ``+cmd|...``,
:mod:`fleetrun.workbook.text_cells`) also gets Excel's quote prefix, so it stays text when a
user edits the cell.
"""
from __future__ import annotations

import math
import threading
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import xlsxwriter
import xlsxwriter.workbook
from xlsxwriter.utility import xl_col_to_name

from fleetrun.budget.result import EfficiencyMap, RunResult
from fleetrun.budget.totals import scenario_totals, yearly_totals
from fleetrun.reports import text as report_text
from fleetrun.reports.charts import efficiency_scale
from fleetrun.reports.manifest import physics_label, run_header
from fleetrun.reports.sheet_rows import write_rows
from fleetrun.workbook.schema import SCENARIO_COLUMNS, VEHICLE_COLUMNS
from fleetrun.workbook.text_cells import looks_like_formula

#: Cell styles by name (XlsxWriter format properties); any other style name is a number format.
STYLES = {
    "header": {"bold": True, "font_color": "#FFFFFF", "bg_color": "#1F4E78", "pattern": 1,
               "align": "center", "text_wrap": True},
    "title": {"bold": True, "font_size": 14},
    "bold": {"bold": True},
    "wrap": {"text_wrap": True, "valign": "top"},
}

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
    "mpg_gasoline": "0.00", "mpg_diesel": "0.00", "state_tax_low_usd": '"$"#,##0', "state_tax_high_usd": '"$"#,##0',
    "federal_tax_low_usd": '"$"#,##0', "federal_tax_high_usd": '"$"#,##0', "low_usd": '"$"#,##0',
    "high_usd": '"$"#,##0', "central_usd": '"$"#,##0', "share": "0.0%", "low_change_usd": '"$"#,##0',
    "high_change_usd": '"$"#,##0',
    "gal_per_mile": "0.00000", "change_gal": "+#,##0;-#,##0;0", "change_from_vmt_gal": "+#,##0;-#,##0;0",
    "change_from_gal_per_mile_gal": "+#,##0;-#,##0;0",
}

WORKBOOK_OPTIONS = {"constant_memory": True, "strings_to_formulas": False, "strings_to_urls": False,
                    "strings_to_numbers": False, "nan_inf_to_errors": False}
#: zlib level of report.xlsx's zip package: the sheets' XML (9 MB for the 7,600-row fleet of
#: benchmarks/bench_end_to_end.py) deflates 3x faster at 1 than at zlib's default 6, into a file
#: ~18 % larger (2.1 MB instead of 1.8 MB there); the XML in it is the same (docs/benchmarks-run.md).
PACKAGE_COMPRESSLEVEL = 1
#: Per-vehicle rows a report.xlsx copies (ByVehicle; the Vehicles in Inputs): ~20 columns x
#: 20,000 rows is a ~5 MB workbook that opens in seconds. Beyond it the sheet says where the
#: rows are: results.csv and results.parquet hold every row at any size (docs/report.md).
DETAIL_ROWS = 20_000
#: Vehicles rows the Inputs sheet echoes as read: a copy of the fleet workbook (whose sha256 the
#: workbook records), so a smaller bound; beyond it the sheet names the file instead.
INPUT_ROWS = 2_000
#: Excel's rows per sheet; a sheet that would pass it is an error, never a silent cut.
EXCEL_MAX_ROWS = 1_048_576
ZIP64_CELLS = 20_000_000   # above this many cells a sheet's XML may pass 4 GB: zip64 archive
CM_TO_PIXELS = 96 / 2.54   # chart sizes are given in cm, XlsxWriter takes pixels at 96 dpi


class Sheet:
    """One worksheet written top to bottom (constant_memory needs the rows in order).
    ``row`` is the 1-based number of the last row written, as Excel counts."""

    def __init__(self, book: "Book", name: str):
        self.book, self.name, self.ws, self.row = book, name, book.workbook.add_worksheet(name), 0
        self.row_breaks: list[int] = []

    def _room(self, rows: int) -> None:
        """RuntimeError if ``rows`` more rows would pass Excel's last row: XlsxWriter would
        drop them without a word, and no sheet of the report may be cut silently."""
        if self.row + rows > EXCEL_MAX_ROWS:
            raise RuntimeError(f"report.xlsx sheet {self.name!r}: {self.row + rows:,} rows would pass "
                               f"Excel's {EXCEL_MAX_ROWS:,}; nothing is cut silently")

    def append(self, values=(), styles=None, height: float | None = None) -> int:
        """Write ``values`` into the next row (None: empty cell); ``styles``: one style name
        for every cell or one per cell. Returns the row's 1-based number."""
        self._room(1)
        index, self.row = self.row, self.row + 1
        if height is not None:
            self.ws.set_row(index, height)
        for column, value in enumerate(values):
            style = styles if styles is None or isinstance(styles, str) else styles[column]
            self.book.write(self.ws, index, column, value, style)
        return self.row

    def note(self, text: str, columns: int, chars_per_line: int) -> int:
        """A sentence in the next row, merged across the first ``columns`` columns and wrapped,
        the row as tall as its lines at ``chars_per_line`` characters need: printed within the
        table's width instead of running past it (which shrinks a fit-to-page print). Returns
        the row's 1-based number."""
        self._room(1)
        index, self.row = self.row, self.row + 1
        self.ws.set_row(index, 15 * max(1, math.ceil(len(text) / chars_per_line)))
        if columns > 1:
            self.ws.merge_range(index, 0, index, columns - 1, "", self.book.style("wrap"))
        self.book.write(self.ws, index, 0, text, "wrap")
        return self.row

    def rows(self, columns: list[list], styles: list) -> None:
        """Many rows at once: ``columns`` are the table's columns as lists (a DataFrame's
        ``tolist()``), ``styles`` one style name (or None) per column; each cell as
        :meth:`Book.write` writes it."""
        self._room(len(columns[0]) if columns else 0)
        cell, ws, index = self.book.cell, self.ws, self.row
        formats = [self.book.style(s) for s in styles]
        texts = [lambda value, style=s, plain=f: (self.book.style(style, quoted=True) if looks_like_formula(value)
                                                  else plain)
                 for s, f in zip(styles, formats)]   # the Format Book.text gives the text
        if write_rows(ws, index, columns, [t if _texts(c) else f for c, f, t in zip(columns, formats, texts)]):
            columns, index = [c[-1:] for c in columns], index + len(columns[0]) - 1   # the last row: below
        for values in zip(*columns):
            for column, value in enumerate(values):
                if value is not None:
                    cell(ws, index, column, value, styles[column], formats[column])
            index += 1
        self.row = index


def _texts(values: list) -> bool:
    """Whether a column holds texts (each written by :meth:`Book.text`, with its own Format)."""
    return str in set(map(type, values))


class Book:
    """The XlsxWriter workbook and its formats (made once per style, as XlsxWriter wants)."""

    def __init__(self, path: Path, cells: int):
        options = {**WORKBOOK_OPTIONS, "tmpdir": str(Path(path).parent), "use_zip64": cells > ZIP64_CELLS}
        self.workbook = xlsxwriter.Workbook(str(path), options)
        self._formats: dict = {}

    def style(self, name: str | None, quoted: bool = False):
        """The Format of style ``name`` (STYLES or a number format), with the quote prefix."""
        key = (name, quoted)
        if key not in self._formats:
            properties = dict(STYLES.get(name, {"num_format": name} if name else {}))
            if quoted:
                properties["quote_prefix"] = True
            self._formats[key] = self.workbook.add_format(properties) if properties else None
        return self._formats[key]

    def write(self, ws, row: int, column: int, value, style: str | None = None) -> None:
        """One cell: text as text, finite numbers as numbers, booleans, nothing for None/NaN."""
        self.cell(ws, row, column, value, style, self.style(style))

    def cell(self, ws, row: int, column: int, value, style: str | None, cell_format) -> None:
        """:meth:`write` with the style's Format already looked up (``cell_format``)."""
        if type(value) is float:   # the common case first
            if math.isfinite(value):
                ws.write_number(row, column, value, cell_format)
        elif isinstance(value, str):
            self.text(ws, row, column, value, style)
        elif isinstance(value, (bool, np.bool_)):
            ws.write_boolean(row, column, bool(value), cell_format)
        elif isinstance(value, (int, float)) or hasattr(value, "__float__") and not pd.isna(value):
            number = float(value)
            if math.isfinite(number):
                ws.write_number(row, column, value if isinstance(value, int) else number, cell_format)
        elif value is not None and not pd.isna(value):
            self.text(ws, row, column, str(value), style)

    def text(self, ws, row: int, column: int, value: str, style: str | None = None) -> None:
        """A text cell that shows ``value`` as typed. In constant_memory mode XlsxWriter passes
        a string that starts with ``<r>`` and ends with ``</r>`` into the sheet XML unescaped
        (its marker for a pre-built rich string): such text is written as a rich string of
        three plain runs, which XlsxWriter escapes; it shows the same text."""
        cell_format = self.style(style, quoted=looks_like_formula(value))
        if value.startswith("<r>") and value.endswith("</r>"):
            runs = [value[:1], value[1:2], value[2:]]
            ws.write_rich_string(row, column, *runs, *([cell_format] if cell_format else []))
        else:
            ws.write_string(row, column, value, cell_format)

    def close(self) -> None:
        """Package the workbook, deflated at :data:`PACKAGE_COMPRESSLEVEL` (XlsxWriter has no
        option for it: its ZipFile is swapped for the one call, under a lock so that reports
        closed in threads at once never leave XlsxWriter with the swapped class)."""
        with _PACKAGING_LOCK:
            packaging = xlsxwriter.workbook.ZipFile
            xlsxwriter.workbook.ZipFile = _PackageZipFile
            try:
                self.workbook.close()
            finally:
                xlsxwriter.workbook.ZipFile = packaging


_PACKAGING_LOCK = threading.Lock()


class _PackageZipFile(zipfile.ZipFile):
    """The report's zip package at :data:`PACKAGE_COMPRESSLEVEL`."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("compresslevel", PACKAGE_COMPRESSLEVEL)
        super().__init__(*args, **kwargs)


def _widths(sheet: Sheet, names, minimum=10, maximum=40):
    for i, name in enumerate(names):
        sheet.ws.set_column(i, i, max(minimum, min(maximum, len(name) + 2)))


def printed_width(values, number_format: str | None) -> int:
    """Characters the widest of ``values`` takes in ``number_format`` (so that no column prints
    ``###``: a number wider than its column shows as hashes in Excel and LibreOffice)."""
    numbers = [float(v) for v in values if isinstance(v, (int, float, np.integer, np.floating))
               and not isinstance(v, bool) and math.isfinite(float(v))]
    texts = [str(v) for v in values if isinstance(v, str)]
    widest = max((len(t) for t in texts), default=0)
    if not numbers:
        return widest
    big = max(numbers, key=abs)
    fmt = number_format or ""
    if "E+" in fmt:
        shown = f"{big:.3E}"
    elif fmt.endswith("%"):
        decimals = len(fmt.split(".")[1].rstrip("%")) if "." in fmt else 0
        shown = f"{big * 100:,.{decimals}f}%" if "," in fmt else f"{big * 100:.{decimals}f}%"
    elif "#,##0" in fmt:
        decimals = len(fmt.split(".")[1]) if "." in fmt.split(";")[0] else 0
        shown = ('$' if '"$"' in fmt else '') + f"{big:,.{decimals}f}"
    elif fmt.startswith("0."):
        shown = f"{big:.{len(fmt) - 2}f}"
    else:
        shown = repr(big) if not float(big).is_integer() else f"{big:.0f}"
    return max(widest, len(shown) + (1 if big < 0 else 0))


def fit_frame(sheet: Sheet, frames, minimum: int = 10, maximum: int = 60, formats: dict | None = None) -> dict[int, int]:
    """Column widths for one or more tables written in the same columns (the k-th column of
    each frame lands in sheet column k): the widest header or printed value + 3 characters of
    margin (proportional fonts, the filter button). ``formats``: number format per column
    index where a column's name is not a FORMATS key (a pivot's scenario columns). Returns the
    widths set, by column index."""
    widths: dict[int, int] = {}
    for frame in frames:
        for k, name in enumerate(frame.columns):
            fmt = FORMATS.get(str(name)) or (formats or {}).get(k)
            width = max(len(str(name)), printed_width(frame[name].tolist(), fmt)) + 3
            widths[k] = max(widths.get(k, 0), width)
    for k, width in widths.items():
        widths[k] = max(minimum, min(maximum, width))
        sheet.ws.set_column(k, k, widths[k])
    return widths


def _table(sheet: Sheet, frame: pd.DataFrame, styled: bool = True, widths: bool = True) -> None:
    names = [str(n) for n in frame.columns]
    if widths:
        _widths(sheet, names)
    sheet.append(names, "header")
    sheet.rows([frame[n].tolist() for n in frame.columns], [FORMATS.get(n) if styled else None for n in names])


def write_report_xlsx(result: RunResult, path: Path, detail_rows: int | None = None,
                      input_rows: int | None = None) -> None:
    """The workbook of ``result``. ByVehicle copies results.csv up to ``detail_rows`` rows
    (default :data:`DETAIL_ROWS`), Inputs the Vehicles rows as read up to ``input_rows``
    (:data:`INPUT_ROWS`); beyond that the sheet says where the rows are instead
    (results.csv / results.parquet, the fleet workbook)."""
    detail_rows = DETAIL_ROWS if detail_rows is None else detail_rows
    input_rows = INPUT_ROWS if input_rows is None else input_rows
    cells = (min(len(result.results), detail_rows) * len(result.results.columns)
             + min(len(result.fleet.vehicles), input_rows) * (len(VEHICLE_COLUMNS) + 5))
    book = Book(path, cells)
    totals = scenario_totals(result.classes)
    _summary(book, result, totals)
    _memo(book, result)
    _assumptions(book, result)
    _by_class(book, result)
    _by_vehicle(book, result, detail_rows)
    _comparison(book, result)
    _fiscal(book, result)
    _periods(book, result)
    _registrations(book, result)
    _maps(book, result)
    _inputs(book, result, input_rows)
    _run_info(book, result)
    _what_changed(book, result)
    book.close()


# --- printing and charts ------------------------------------------------------------------

def page_setup(sheet: Sheet, *, landscape: bool = True, title_row: int | None = 1, one_page: bool = False) -> None:
    """Print layout of a sheet: US letter, fit to the page width (and height for one page),
    the header row ``title_row`` (1-based) repeated on every page, the sheet name and page
    number in the footer."""
    ws = sheet.ws
    if landscape:
        ws.set_landscape()
    else:
        ws.set_portrait()
    ws.set_paper(1)   # US letter (ECMA-376 paper size 1)
    ws.fit_to_pages(1, 1 if one_page else 0)
    ws.set_margins(left=0.4, right=0.4, top=0.5, bottom=0.6)
    ws.set_footer("&C&A, page &P of &N")
    if title_row:
        ws.repeat_rows(title_row - 1)


def _chart(book: Book, kind: str, title: str, axes: tuple[str, str, str], size: tuple[float, float]):
    """A chart with axis titles with units, a value axis from zero, the legend below the plot;
    ``kind``: XlsxWriter's chart type (bar: horizontal, column, line); size (height, width) in cm."""
    x_title, y_title, y_format = axes
    chart = book.workbook.add_chart({"type": kind})
    chart.set_title({"name": title})
    category_axis, value_axis = (chart.set_y_axis, chart.set_x_axis) if kind == "bar" else (chart.set_x_axis, chart.set_y_axis)
    category_axis({"name": x_title})
    value_axis({"name": y_title, "num_format": y_format, "min": 0})
    chart.set_legend({"position": "bottom"})
    chart.set_size({"height": round(size[0] * CM_TO_PIXELS), "width": round(size[1] * CM_TO_PIXELS)})
    return chart


def _series(sheet: Sheet, column: int, first_row: int, last_row: int, name, categories_column: int = 1) -> dict:
    """One chart series over 1-based ``column``'s rows ``first_row``..``last_row``, with the
    categories in ``categories_column``; ``name``: a legend text or a (row, column) cell."""
    name = [sheet.name, name[0] - 1, name[1] - 1] if isinstance(name, tuple) else name
    return {"name": name, "values": [sheet.name, first_row - 1, column - 1, last_row - 1, column - 1],
            "categories": [sheet.name, first_row - 1, categories_column - 1, last_row - 1, categories_column - 1]}


def _scenario_bars(sheet: Sheet, pivot: pd.DataFrame, header_row: int, kind: str, title: str,
                   axes: tuple[str, str, str], size: tuple[float, float]) -> None:
    """A bar chart of ``pivot`` as written below ``header_row`` (labels in column A, one
    column and one series per scenario), placed two rows under the table."""
    first, last = header_row + 1, header_row + len(pivot)
    chart = _chart(sheet.book, kind, title, axes, size)
    for k, scenario_id in enumerate(pivot.columns):
        chart.add_series(_series(sheet, 2 + k, first, last, f"Scenario {scenario_id}"))
    sheet.ws.insert_chart(f"A{last + 2}", chart)


def _summary(book: Book, result: RunResult, totals: pd.DataFrame):
    from fleetrun.reports import text as report_text

    sheet = Sheet(book, "Summary")
    header_row = 6
    sheet.ws.freeze_panes(f"A{header_row + 1}")
    page_setup(sheet, title_row=None, one_page=True)
    descriptions = {s.scenario_id: s.description for s in result.scenarios}
    years = {s.scenario_id: s.budget_years for s in result.scenarios}
    # one range per total on this sheet, the headline's (the rows' summed ends: ByClass, CSVs)
    frame = report_text.totals_with_fuel_mpg(totals, result.results).drop(
        columns=["fuel_gal_low_total", "fuel_gal_high_total"])
    frame.insert(1, "description", [descriptions.get(s, "") for s in frame["scenario_id"]])
    frame.insert(2, "budget_years", [years.get(s) for s in frame["scenario_id"]])
    widths = fit_frame(sheet, [frame], minimum=12)
    widths[1] = 34
    sheet.ws.set_column("B:B", widths[1], book.style("wrap"))
    sheet.append(["Fleet fuel and fuel-tax forecast"], "title")
    sheet.append(["Fleet workbook", result.fleet.path.name])
    sheet.append(["sha256", result.fleet.sha256])
    sheet.append(["Warnings", len(result.warnings)])
    sheet.append([])
    sheet.append([str(n) for n in frame.columns], "header")
    for values in frame.itertuples(index=False):
        lines = max(1, math.ceil(len(str(values[1])) / 32))
        sheet.append(list(values), [None, "wrap"] + [FORMATS.get(str(n)) for n in frame.columns[2:]],
                     height=15 * lines if lines > 1 else None)
    n = len(frame)
    row = _summary_words(sheet, result, len(frame.columns), sum(widths.values()))
    if n:
        chart = _chart(book, "column", "Fuel-tax revenue over the budget period",
                       ("Scenario", "US$ over the budget period", '"$"#,##0'), (7.5, 16))
        cols = list(frame.columns)
        for name, label in (("state_tax_usd", "State fuel tax"), ("federal_tax_usd", "Federal fuel tax")):
            chart.add_series(_series(sheet, cols.index(name) + 1, header_row + 1, header_row + n, label))
        sheet.ws.insert_chart(f"A{row + 2}", chart)


def _summary_words(sheet: Sheet, result: RunResult, columns: int, chars_per_line: int) -> int:
    """The headline of each scenario (rounded to its range; state and federal apart) and
    where the ranges come from, each sentence wrapped across the table's ``columns`` columns
    (``chars_per_line`` their width); the last row written. The heading has a row of its own,
    so no label is cut by the next cell."""
    ranges = report_text.scenario_ranges(result.fiscal, result.scenarios, result.period_ranges)
    labels = ((1, "Fuel"), (5, "State fuel tax"), (9, "Federal fuel tax"))
    sheet.append([])
    sheet.append([report_text.HEADLINE_HEADING], "bold")
    heads = ["scenario_id"] + [None] * 12
    for column, label in labels:
        heads[column] = label
    sheet.append(heads, "bold")
    for s in result.scenarios:
        texts = dict(report_text.headline(s, ranges[s.scenario_id]))
        line = [s.scenario_id] + [None] * 12
        for column, label in labels:
            line[column] = texts[label]
        sheet.append(line)
    sources = report_text.range_source_lines(result.error_model)
    sentences = sources[:1] + [report_text.TOTAL_RANGE, report_text.ROW_RANGES] + sources[1:] + [
        "Rates, mixes, growth, temperature and on-road fuel of each scenario: see the Assumptions sheet; "
        "fiscal year x fuel with ranges: the Revenue memo sheet."]
    for sentence in sentences:
        sheet.note(sentence, columns, chars_per_line)
    return sheet.row


def _memo(book: Book, result: RunResult):
    """Revenue memo: fiscal year x fuel (and all fuels) with gallons, state and federal revenue
    and their 90 % ranges (revenue_memo.csv), and the tornado of state revenue per driver."""
    from fleetrun.reports import text as report_text

    sheet = Sheet(book, "Revenue memo")
    page_setup(sheet, title_row=3)
    memo = result.memo if result.memo is not None else pd.DataFrame()
    tornado = result.tornado if result.tornado is not None else pd.DataFrame()
    if len(tornado):
        tornado = tornado.assign(low_change_usd=tornado.low_usd - tornado.central_usd,
                                 high_change_usd=tornado.high_usd - tornado.central_usd)
    fit_frame(sheet, [memo, tornado], minimum=12)
    sheet.ws.freeze_panes("D4")
    sheet.append(["Revenue by fiscal year and fuel, with 90 % ranges"], "title")
    sheet.append([report_text.range_source_lines(result.error_model)[0]])
    _table(sheet, memo, widths=False)
    if not len(tornado):
        return
    sheet.append([])
    sheet.append(["Sensitivity: state revenue over the budget period with one driver at its 5th or 95th "
                  "percentile, the others central"], "bold")
    header = sheet.append(list(tornado.columns), "header")
    sheet.rows([tornado[c].tolist() for c in tornado.columns], [FORMATS.get(c) for c in tornado.columns])
    first = result.scenarios[0].scenario_id
    rows = [header + 1 + k for k, sid in enumerate(tornado["scenario_id"]) if sid == first]
    if not rows:
        return
    chart = book.workbook.add_chart({"type": "bar", "subtype": "stacked"})
    chart.set_title({"name": f"State revenue by driver, scenario {first}: change from the central value"})
    for column, name in ((6, "Driver at its low end"), (7, "Driver at its high end")):
        chart.add_series({"name": name, "categories": [sheet.name, rows[0] - 1, 1, rows[-1] - 1, 1],
                          "values": [sheet.name, rows[0] - 1, column - 1, rows[-1] - 1, column - 1]})
    chart.set_x_axis({"name": "Change of state revenue over the budget period (US$)", "num_format": '"$"#,##0'})
    chart.set_y_axis({"name": "Driver", "reverse": True, "label_position": "low"})
    chart.set_legend({"position": "bottom"})
    chart.set_size({"width": round(18 * CM_TO_PIXELS), "height": round(max(7.5, 1.2 * len(rows)) * CM_TO_PIXELS)})
    sheet.ws.insert_chart(f"A{sheet.row + 2}", chart)


def _periods(book: Book, result: RunResult):
    """Quarters and months of each fiscal year (fiscal_periods.csv)."""
    sheet = Sheet(book, "Fiscal periods")
    page_setup(sheet)
    frame = result.periods if result.periods is not None else pd.DataFrame()
    fit_frame(sheet, [frame], minimum=10)
    sheet.ws.freeze_panes("E2")
    _table(sheet, frame, widths=False)


ASSUMPTION_WIDTH = 48   # characters per scenario column of the Assumptions sheet


def _assumptions(book: Book, result: RunResult):
    """One column per scenario, one row per assumption (report_text.assumptions)."""
    sheet = Sheet(book, "Assumptions")
    page_setup(sheet)
    sheet.ws.set_column(0, 0, 30)
    if result.scenarios:
        sheet.ws.set_column(1, len(result.scenarios), ASSUMPTION_WIDTH)
    sheet.ws.freeze_panes("B2")
    sheet.append(["assumption"] + [s.scenario_id for s in result.scenarios], "header")
    table = [dict(report_text.assumptions(s)) for s in result.scenarios]
    labels = list(dict.fromkeys(label for t in table for label in t))
    for label in labels:
        texts = [label] + [t.get(label, "") for t in table]
        # rows are streamed: give each the lines its wrapped text needs
        lines = max(math.ceil(len(text) / (ASSUMPTION_WIDTH * 1.05)) for text in texts)
        sheet.append(texts, "wrap", height=15 * max(1, lines))


def _by_class(book: Book, result: RunResult):
    sheet = Sheet(book, "ByClass")
    frame = result.classes
    sheet.ws.freeze_panes("C2")
    page_setup(sheet)
    # One chart: gallons by class, one series per scenario (classes x scenarios pivot below).
    pivot = frame.pivot_table(index="vehicle_class", columns="scenario_id", values="fuel_gal_total",
                              aggfunc="sum", sort=False) if len(frame) else pd.DataFrame()
    chart_data = pivot.reset_index()
    fit_frame(sheet, [frame, chart_data], formats={k: "#,##0" for k in range(1, len(chart_data.columns))})
    _table(sheet, frame, widths=False)
    n = len(frame)
    if not n:
        return
    start = n + 4
    sheet.row = start - 1   # two empty rows under the table
    sheet.append(["Fuel over the budget period [gal] by class and scenario"])
    sheet.append(["vehicle_class"] + list(pivot.columns))
    for label, row in pivot.iterrows():
        sheet.append([label] + [float(v) for v in row], [None] + ["#,##0"] * len(row))
    _scenario_bars(sheet, pivot, start + 1, "bar", "Fuel by vehicle class over the budget period",
                   ("Vehicle class", "US gallons", "#,##0"),
                   (max(7.5, 0.5 * len(pivot) * len(pivot.columns)), 18))


def _by_vehicle(book: Book, result: RunResult, detail_rows: int):
    """results.csv as a filterable table, or, beyond ``detail_rows`` rows, a note saying how many
    rows there are and where they are (results.csv and results.parquet hold every one)."""
    sheet = Sheet(book, "ByVehicle")
    sheet.ws.freeze_panes("C2")
    page_setup(sheet)
    frame = result.results
    if len(frame) > detail_rows:
        _widths(sheet, [str(n) for n in frame.columns])
        sheet.append(list(frame.columns), "header")
        sheet.append([f"{len(frame):,} per-vehicle rows (scenario x vehicle type): more than the "
                      f"{detail_rows:,} this workbook holds, so none are copied here."], "bold")
        sheet.append(["Every row, with these columns, is in results.csv and results.parquet next to this "
                      "workbook; totals by class are in ByClass, by scenario in Summary (docs/report.md)."])
        return
    sheet.ws.autofilter(0, 0, len(frame), len(frame.columns) - 1)
    _table(sheet, frame)


def _comparison_frame(result: RunResult) -> pd.DataFrame:
    """Per class and scenario: fuel, mpg, taxes and the change against the first scenario."""
    classes = result.classes
    base = result.scenarios[0].scenario_id if result.scenarios else None
    baseline = classes[classes["scenario_id"] == base].set_index("vehicle_class")
    rows = []
    for _, row in classes.iterrows():
        ref = baseline.loc[row["vehicle_class"]] if row["vehicle_class"] in baseline.index else None
        fuel_change = (row["fuel_gal_total"] / ref["fuel_gal_total"] - 1.0
                       if ref is not None and ref["fuel_gal_total"] else None)
        tax_change = (row["state_tax_usd"] / ref["state_tax_usd"] - 1.0
                      if ref is not None and ref["state_tax_usd"] else None)
        rows.append([row["vehicle_class"], row["scenario_id"], row["fuel_gal_total"], row["mpg"],
                     row["state_tax_usd"], row["federal_tax_usd"], fuel_change, tax_change])
    return pd.DataFrame(rows, columns=["vehicle_class", "scenario_id", "fuel_gal_total", "mpg", "state_tax_usd",
                                       "federal_tax_usd", "fuel_change_pct", "state_tax_change_pct"])


def _comparison(book: Book, result: RunResult):
    sheet = Sheet(book, "Scenario comparison")
    page_setup(sheet, title_row=2)
    base = result.scenarios[0].scenario_id if result.scenarios else None
    frame = _comparison_frame(result)
    years = yearly_totals(result.fiscal)
    pivot = years.pivot_table(index="fiscal_year", columns="scenario_id", values="state_tax_usd",
                              aggfunc="sum", sort=False).reset_index() if len(years) else pd.DataFrame()
    fit_frame(sheet, [frame, years, pivot], minimum=12,
              formats={6: FORMATS["change_pct"], 7: FORMATS["change_pct"]}
              | {k: FORMATS["state_tax_usd"] for k in range(1, len(pivot.columns))})
    sheet.ws.freeze_panes("C3")
    sheet.append([f"Change against the first scenario ({base})"], "title")
    sheet.append(list(frame.columns), "header")
    styles = [None, None] + [FORMATS[n] for n in ("fuel_gal_total", "mpg", "state_tax_usd", "federal_tax_usd")] \
        + [FORMATS["change_pct"]] * 2
    sheet.rows([frame[c].tolist() for c in frame.columns], styles)
    sheet.append([])
    _by_fiscal_year(sheet, result)


def _by_fiscal_year(sheet: Sheet, result: RunResult) -> None:
    """Fleet totals per scenario and fiscal year, and a chart of state revenue per year."""
    sheet.append(["By fiscal year (fleet totals)"], "bold")
    years = yearly_totals(result.fiscal)
    sheet.append(list(years.columns), "header")
    sheet.rows([years[c].tolist() for c in years.columns], [FORMATS.get(c) for c in years.columns])
    if not len(years):
        return
    # State revenue per fiscal year, one series per scenario.
    pivot = years.pivot_table(index="fiscal_year", columns="scenario_id", values="state_tax_usd",
                              aggfunc="sum", sort=False)
    sheet.append([])
    pivot_row = sheet.append(["fiscal_year"] + list(pivot.columns))
    for year, row in pivot.iterrows():
        sheet.append([str(int(year))] + [float(v) for v in row], [None] + [FORMATS["state_tax_usd"]] * len(row))
    _scenario_bars(sheet, pivot, pivot_row, "column", "State fuel-tax revenue by fiscal year",
                   ("Fiscal year", "US$ (state fuel tax)", '"$"#,##0'), (7.5, 16))


def _fiscal(book: Book, result: RunResult):
    """Fiscal year x fuel x class (fiscal_summary.csv) and the calibration to collections."""
    sheet = Sheet(book, "Fiscal years")
    page_setup(sheet)
    frame = result.fiscal
    calibration = result.calibration
    fit_frame(sheet, [frame] + ([calibration] if calibration is not None and len(calibration) else []), minimum=12)
    sheet.ws.freeze_panes("E2")
    _table(sheet, frame, widths=False)
    if calibration is not None and len(calibration):
        sheet.append([])
        sheet.append(["Calibration to collections: model vs observed taxable gallons, first fiscal year"], "bold")
        _table(sheet, calibration, widths=False)


REGISTRATION_ROWS_SHOWN = 5_000   # more rows: registrations.csv has them all


def _registrations(book: Book, result: RunResult):
    """Registrations (docs/registrations.md): the year-on-year change in gallons split into VMT
    and gallons per mile (turnover), then every registration row's choice of vehicle."""
    if result.registrations is None:
        return
    sheet = Sheet(book, "Registrations")
    page_setup(sheet)
    frame = result.registrations
    shown = frame.head(REGISTRATION_ROWS_SHOWN)
    _shared_widths(sheet, [result.turnover, shown])
    sheet.append(["Change in gallons from the year before: from VMT (change in miles x last year's gallons "
                  "per mile) and from gallons per mile (turnover: newer model years replace older ones)"], "bold")
    _table(sheet, result.turnover, widths=False)
    sheet.append([])
    more = f" (first {len(shown):,} of {len(frame):,}; all in registrations.csv)" if len(shown) < len(frame) else ""
    sheet.append([f"Each registration row: the vehicle that represents it, matched on what, assumed what{more}"],
                 "bold")
    _table(sheet, shown, widths=False)


def _shared_widths(sheet: Sheet, frames, minimum: int = 10, maximum: int = 60) -> None:
    """Column widths for tables stacked in one sheet: each column as wide as its widest header
    or value in its number format over all the tables (no ``###``, no cut-off class names),
    at most ``maximum`` characters (longer text runs on into the empty cells to its right)."""
    for i in range(max(len(f.columns) for f in frames)):
        need = max(max(len(str(f.columns[i])), printed_width(f.iloc[:, i].tolist(), FORMATS.get(str(f.columns[i]))))
                   for f in frames if i < len(f.columns))
        sheet.ws.set_column(i, i, max(minimum, min(maximum, need + 2)))


MAP_BLOCK_ROWS = 2   # blank + title rows before each map's table


def _maps(book: Book, result: RunResult):
    sheet = Sheet(book, "Efficiency maps")
    page_setup(sheet, title_row=None)
    sheet.ws.set_column("A:A", 24)
    sheet.append(["Differential efficiency: torque fraction (rows) x input speed (columns); "
                  "one colour scale for all maps"], "title")
    if not result.maps:
        sheet.append(["No efficiency maps (see RunInfo warnings)."])
        return
    low, high = efficiency_scale(result.maps)
    for m in result.maps:
        _map_block(sheet, m, low, high)
    sheet.ws.set_h_pagebreaks(sheet.row_breaks)


def _map_block(sheet: Sheet, m: EfficiencyMap, low: float, high: float) -> None:
    """One map: its efficiency table, its loss table (what the chart draws, from zero) and
    the chart beside them."""
    if sheet.row > 1:
        sheet.row_breaks.append(sheet.row)   # each map starts a printed page
    label = f"{m.configuration}: gear ratio {m.gear_ratio:g}"
    if m.low_gear_ratio:
        label += f", low ratio {m.low_gear_ratio:g} (axle in high gear)"
    sheet.append([])
    sheet.append([label + f"; {m.vehicle_types} vehicle type(s)"], "bold")
    speeds = [f"{s:g} rpm" for s in m.speeds_rpm]
    n_rows, last_col = len(m.torque_fractions), xl_col_to_name(len(speeds))
    styles = [None] + [FORMATS["efficiency"]] * len(speeds)
    header_rows = {}
    for kind in ("efficiency", "loss"):
        header_rows[kind] = sheet.append([f"{kind} \\ torque fraction"] + speeds)
        for tf, etas in zip(m.torque_fractions, m.efficiency):
            values = etas if kind == "efficiency" else [1.0 - e for e in etas]
            sheet.append([tf] + [float(e) for e in values], styles)
    first = header_rows["efficiency"] + 1
    sheet.ws.conditional_format(f"B{first}:{last_col}{first + n_rows - 1}", {
        "type": "3_color_scale", "min_type": "num", "min_value": low, "min_color": "#F8696B",
        "mid_type": "num", "mid_value": (low + high) / 2, "mid_color": "#FFEB84",
        "max_type": "num", "max_value": high, "max_color": "#63BE7B"})
    chart = _map_chart(sheet, m, header_rows["loss"], n_rows, len(speeds))
    sheet.ws.insert_chart(f"{xl_col_to_name(len(speeds) + 2)}{header_rows['efficiency']}", chart)


def _map_chart(sheet: Sheet, m: EfficiencyMap, header_row: int, n_rows: int, n_speeds: int):
    """Loss (1 - efficiency) against torque fraction, one line per input speed, from zero."""
    chart = _chart(sheet.book, "line", f"{m.configuration} differential loss",
                   ("Torque fraction (input torque / Kim torque scale)", "Loss, share of input power", "0%"),
                   (11, 16))
    for column in range(2, 2 + n_speeds):
        chart.add_series(_series(sheet, column, header_row + 1, header_row + n_rows, (header_row, column)))
    return chart


def _inputs(book: Book, result: RunResult, input_rows: int):
    sheet = Sheet(book, "Inputs")
    page_setup(sheet, title_row=None)
    fleet = result.fleet
    extra_names = list(dict.fromkeys(k for v in fleet.vehicles for k in v.extra))
    vehicle_names = [c.name for c in VEHICLE_COLUMNS] + extra_names
    _widths(sheet, vehicle_names)
    # Scenarios first (a few rows), then the Vehicles table, whose rows may be many.
    sheet.append(["Scenarios (as read)"], "bold")
    sheet.append([c.name for c in SCENARIO_COLUMNS], "header")
    for s in fleet.scenarios:
        values = []
        for c in SCENARIO_COLUMNS:
            value = getattr(s, c.name)
            if c.kind == "cycle_mix" and value:
                value = ",".join(f"{Path(k).name if k.lower().endswith('.csv') else k}:{w:g}"
                                 for k, w in value.items())
            values.append(value)
        sheet.append(values)
    sheet.append([])
    sheet.append(["Vehicles (as read)"], "bold")
    sheet.append(vehicle_names, "header")
    if len(fleet.vehicles) > input_rows:
        sheet.append([f"{len(fleet.vehicles):,} Vehicles rows: more than the {input_rows:,} this workbook "
                      f"copies; they are in the fleet workbook {fleet.path.name} (sha256 {fleet.sha256})."], "bold")
        return
    columns = [[getattr(v, c.name) for v in fleet.vehicles] for c in VEHICLE_COLUMNS]
    ratios = [c.name for c in VEHICLE_COLUMNS].index("transmission_gear_ratios")
    columns[ratios] = [",".join(f"{r:g}" for r in value) for value in columns[ratios]]
    columns += [[v.extra.get(k) for v in fleet.vehicles] for k in extra_names]
    sheet.rows(columns, [None] * len(columns))


def _run_info(book: Book, result: RunResult):
    sheet = Sheet(book, "RunInfo")
    page_setup(sheet, landscape=False, title_row=None)
    sheet.ws.set_column("A:A", 30)
    sheet.ws.set_column("B:B", 90)
    info = run_header(result)
    for key in ("fleetrun_version", "created_utc", "physics", "mode"):
        sheet.append([key, str(info[key])])
    sheet.append(["with (effects)", physics_label(info) if info.get("with") else "none"])
    for key, value in info["engine"].items():
        sheet.append([key, str(value)])
    sheet.append(["scenarios", ", ".join(info["scenarios"])])
    for key, value in info["timings_s"].items():
        sheet.append([f"time {key} [s]", round(value, 3)])
    sheet.append([])
    sheet.append(["Inputs", "sha256"])
    for item in info["inputs"]:
        sheet.append([item["path"], item["sha256"]])
    sheet.append([])
    sheet.append(["Drive cycles", "miles, duration"])
    for c in result.cycles.values():
        sheet.append([c.name, f"{c.miles:.3f} mi, {c.duration_s:.0f} s"])
    sheet.append([])
    sheet.append([f"Warnings ({len(result.warnings)})"])
    for warning in result.warnings:
        sheet.append([None, warning])


def _what_changed(book: Book, result: RunResult):
    """The comparison with the run that was in the output folder (fleetrun.reports.changes)."""
    sheet = Sheet(book, "What changed")
    page_setup(sheet, title_row=None)
    for column, width in enumerate((40, 18, 30, 20, 14)):
        sheet.ws.set_column(column, column, width)
    changes = result.changes
    sheet.append(["What changed since the earlier run in this output folder"], "title")
    if not changes:
        sheet.append(["No earlier run in this folder: nothing to compare."])
        return
    sheet.append(["Earlier run", f"{changes.earlier_created_utc} (fleetrun {changes.earlier_version})"])
    sheet.append([])
    sheet.append(["input", "status", "earlier sha256", "sha256"], "header")
    for item in changes.inputs:
        sheet.append([item.path, item.status, item.earlier_sha256 or "", item.sha256 or ""])
    sheet.append([])
    sheet.append(["scenario_id", "total", "earlier", "now", "change"], "header")
    for row in changes.totals:
        sheet.append([row.scenario_id, row.total, row.earlier, row.now, row.change_pct],
                     [None, None, "#,##0", "#,##0", FORMATS["change_pct"]])
    if changes.causes:
        sheet.append([])
        sheet.append(["scenario_id", "total", "cause", "change"], "header")
        for c in changes.causes:
            sheet.append([c.scenario_id, c.total, c.cause, c.amount], [None, None, None, "#,##0"])
