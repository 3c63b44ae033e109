"""report.xlsx prints without ``###``: every number fits its column (a state-sized fleet, so
revenue runs into billions of dollars), and the Summary's texts are not cut.

A number wider than its column prints as ``###`` in Excel and LibreOffice. The printed text
of each number is rebuilt here from its cell's number format (Excel's rules for the formats
the report uses), independently of the report code, and compared with the column's width in
characters (openpyxl reads the width XlsxWriter stored; a digit of the default font is one
character wide).
"""
from __future__ import annotations

import math

import openpyxl
import pytest

import test_fleet_fakes as fakes
from test_fleet_fakes import scenario, vehicle, write_fleet

PRINTED_SHEETS = ("Summary", "Revenue memo", "ByClass", "Scenario comparison", "Fiscal years", "Fiscal periods")


def printed(value: float, number_format: str) -> str | None:
    """The text Excel shows for ``value`` in ``number_format`` (None: a format this test
    does not know, e.g. General, which shrinks instead of printing ###)."""
    fmt = number_format.split(";")[0]
    dollars = '"$"' in fmt
    fmt = fmt.replace('"$"', "")
    if fmt.endswith("%"):
        decimals = len(fmt.split(".")[1]) - 1 if "." in fmt else 0
        return f"{value * 100:+.{decimals}f}%" if fmt.startswith("+") else f"{value * 100:.{decimals}f}%"
    if fmt.startswith("#,##0"):
        decimals = len(fmt.split(".")[1]) if "." in fmt else 0
        return ("$" if dollars else "") + f"{value:,.{decimals}f}"
    if fmt.startswith("0.") and set(fmt[2:]) == {"0"}:
        return f"{value:.{len(fmt) - 2}f}"
    return None


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("layout")
    fleet = [vehicle("CARS", count=2_000_000, annual_miles=11_000),
             vehicle("A-VERY-LONG-VEHICLE-ID-OF-A-HEAVY-TRACTOR", vehicle_class="Tractor-trailer (class 8)",
                     fuel="diesel", count=150_000, annual_miles=60_000)]
    scenarios = [scenario("baseline_long_scenario_identifier", description="Average year " * 8,
                          first_fiscal_year=2027, observed_base_gallons_gasoline=1.0e9, calibrate_to_observed="no"),
                 scenario("hot", ambient_temp_C=38, first_fiscal_year=2027)]
    path = write_fleet(tmp / "state.xlsx", fleet, scenarios)
    out = tmp / "out"
    result = fakes.invoke_run(path, "--out", out, "--no-cache", "-q")
    assert result.exit_code == 0, result.stderr
    return openpyxl.load_workbook(out / "report.xlsx")


def _width(ws, letter: str) -> float:
    """The column's width; openpyxl files a run of equal columns under the first one's letter."""
    from openpyxl.utils import column_index_from_string

    index = column_index_from_string(letter)
    for dim in ws.column_dimensions.values():
        if dim.min and dim.max and dim.min <= index <= dim.max and dim.width:
            return dim.width
    return 8.43


def test_no_number_prints_as_hashes(report):
    checked = 0
    for name in PRINTED_SHEETS:
        ws = report[name]
        for row in ws.iter_rows():
            for cell in row:
                if isinstance(cell.value, (int, float)) and not isinstance(cell.value, bool) and math.isfinite(cell.value):
                    text = printed(cell.value, cell.number_format)
                    if text is None:
                        continue
                    checked += 1
                    assert len(text) < _width(ws, cell.column_letter), (name, cell.coordinate, text)
    assert checked > 100


def test_summary_heading_and_ids_are_not_cut(report):
    ws = report["Summary"]
    for row in ws.iter_rows():
        texts = [(c, c.value) for c in row if isinstance(c.value, str)]
        for cell, text in texts:
            if text.startswith("Headline"):
                # the heading has its row to itself: nothing to its right cuts it
                assert [c for c, _ in texts] == [cell]
    ids = [c.value for c in ws["A"] if isinstance(c.value, str) and c.value.startswith("baseline_long")]
    assert ids and all(len(i) < _width(ws, "A") for i in ids)


def test_summary_sentences_wrap_within_the_table(report):
    # a sentence in one cell runs past the table and a fit-to-page print shrinks the whole
    # sheet to fit it: each sentence under the headline is merged across the table's columns,
    # wrapped, in a row tall enough for its lines at the columns' total width
    ws = report["Summary"]
    header = next(r for r in ws.iter_rows() if r[0].value == "scenario_id")
    last_column = max(c.column for c in header if c.value is not None)
    table_width = sum(_width(ws, c.column_letter) for c in header if c.value is not None)
    merged = {m.min_row: m for m in ws.merged_cells.ranges}
    sentences = [c for c in ws["A"] if isinstance(c.value, str) and c.value.startswith(("Ranges:", "Drivers:", "Rates,"))]
    assert len(sentences) == 3
    for cell in sentences:
        span = merged[cell.row]
        assert (span.min_col, span.max_col, span.max_row) == (1, last_column, cell.row)
        assert cell.alignment.wrap_text
        lines = math.ceil(len(cell.value) / table_width)
        height = ws.row_dimensions[cell.row].height or 15.0   # no height stored: the default 15 pt
        assert height >= 15 * lines
