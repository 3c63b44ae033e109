"""report.xlsx and summary.html read back: sheets, charts, totals equal to the CSVs, safety."""
from __future__ import annotations

import html.parser
import math
import re
import zipfile

import openpyxl
import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

import test_fleet_fakes as fakes
from fleetrun.cli import cli
from fleetrun.run import runner
from test_fleet_fakes import read_csv, scenario, vehicle, write_fleet

SHEETS = ["Summary", "Revenue memo", "Assumptions", "ByClass", "ByVehicle", "Scenario comparison", "Fiscal years",
          "Fiscal periods", "Efficiency maps", "Inputs", "RunInfo", "What changed"]


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    return fakes.run_small_fleet_with_fake(tmp_path_factory.mktemp("report"))


def table(ws, first_row: int = 1):
    rows = list(ws.iter_rows(min_row=first_row, values_only=True))
    header = rows[0]
    width = len([h for h in header if h is not None])
    body = []
    for row in rows[1:]:
        if all(v is None for v in row[:width]):
            break
        body.append(row[:width])
    return pd.DataFrame(body, columns=header[:width])


def charts_per_sheet(path) -> dict[str, int]:
    """Sheet name -> number of charts, from the package's relationships."""
    with zipfile.ZipFile(path) as z:
        names = z.namelist()
        workbook = z.read("xl/workbook.xml").decode()
        rels = z.read("xl/_rels/workbook.xml.rels").decode()
        targets = dict(re.findall(r'Id="(rId\d+)"[^>]*Target="([^"]+)"', rels)
                       + [(b, a) for a, b in re.findall(r'Target="([^"]+)"[^>]*Id="(rId\d+)"', rels)])
        counts = {}
        for name, rid in re.findall(r'<sheet [^>]*name="([^"]+)"[^>]*r:id="(rId\d+)"', workbook):
            sheet_part = "xl/" + targets[rid].lstrip("/").removeprefix("xl/")
            rel_part = sheet_part.replace("worksheets/", "worksheets/_rels/") + ".rels"
            count = 0
            if rel_part in names:
                for drawing in re.findall(r'Target="([^"]*drawings/drawing\d+\.xml)"', z.read(rel_part).decode()):
                    drawing_rels = "xl/drawings/_rels/" + drawing.rsplit("/", 1)[1] + ".rels"
                    if drawing_rels in names:
                        count += len(re.findall(r"charts/chart\d+\.xml", z.read(drawing_rels).decode()))
            counts[name.replace("&amp;", "&")] = count
    return counts


def test_report_sheets_and_charts(outputs):
    wb = openpyxl.load_workbook(outputs / "report.xlsx")
    assert wb.sheetnames == SHEETS
    charts = charts_per_sheet(outputs / "report.xlsx")
    assert charts["Summary"] == 1 and charts["ByClass"] == 1 and charts["Scenario comparison"] == 1
    assert charts["Revenue memo"] == 1      # the tornado of state revenue per driver
    assert charts["Efficiency maps"] >= 1
    assert wb["ByVehicle"].freeze_panes == "C2" and wb["ByClass"].freeze_panes == "C2"
    assert wb["ByClass"]["F2"].number_format == "0.00"


#: report.xlsx against the CSVs. XlsxWriter writes a number with 16 significant digits
#: ("%.16G"); Excel itself keeps 15. Rounding to 16 digits moves a value by at most half a unit
#: in the 16th digit, 5e-16 relative (a leading 1), and reading it back into a double adds at
#: most half an ulp, 1.1e-16: 6.1e-16 < 1e-15. results.csv (shortest round-trip repr) is the
#: exact copy; docs/report.md says so.
XLSX_RTOL = 1e-15


def test_report_totals_equal_csvs(outputs):
    wb = openpyxl.load_workbook(outputs / "report.xlsx")
    results = read_csv(outputs / "results.csv")
    classes = read_csv(outputs / "class_summary.csv")
    by_vehicle = table(wb["ByVehicle"]).fillna(value=np.nan)   # an empty column (model_year): None -> NaN
    by_class = table(wb["ByClass"])
    pd.testing.assert_frame_equal(by_vehicle[results.columns].reset_index(drop=True), results,
                                  check_dtype=False, check_exact=False, rtol=XLSX_RTOL, atol=0)
    pd.testing.assert_frame_equal(by_class[classes.columns].reset_index(drop=True), classes,
                                  check_dtype=False, check_exact=False, rtol=XLSX_RTOL, atol=0)
    summary = table(wb["Summary"], first_row=6)
    for row in summary.itertuples():
        group = classes[classes.scenario_id == row.scenario_id]
        fuel, miles = math.fsum(group.fuel_gal_total), math.fsum(group.miles_total)
        assert row.fuel_gal_total == pytest.approx(fuel, rel=XLSX_RTOL, abs=0)
        assert row.state_tax_usd == pytest.approx(math.fsum(group.state_tax_usd), rel=XLSX_RTOL, abs=0)
        # mpg per fuel, never gasoline and diesel mixed
        for fuel_name in ("gasoline", "diesel"):
            rows = results[(results.scenario_id == row.scenario_id) & (results.fuel == fuel_name)]
            expected = math.fsum(rows.miles_total) / math.fsum(rows.fuel_gal_total)
            assert getattr(row, f"mpg_{fuel_name}") == pytest.approx(expected, rel=XLSX_RTOL, abs=0)
        assert "mpg" not in summary.columns and miles > 0
    assert list(summary.scenario_id) == ["baseline", "hot", "urban"]


def test_report_numbers_are_16_significant_digits_of_the_csv_values(outputs):
    """The precision decision held: every ByVehicle number in the sheet XML is the CSV value
    written with "%.16G", not a value rounded further (15 digits) nor a different number."""
    results = read_csv(outputs / "results.csv")
    with zipfile.ZipFile(outputs / "report.xlsx") as z:
        sheet = next(n for n in z.namelist() if n.startswith(f"xl/worksheets/sheet{SHEETS.index('ByVehicle') + 1}."))
        stored = re.findall(r"<v>([^<]+)</v>", z.read(sheet).decode())
    expected = [f"{v:.16G}" for row in results.itertuples(index=False) for v in row
                if isinstance(v, float) and math.isfinite(v)]
    numbers = [v for v in stored if re.fullmatch(r"-?[0-9.]+(E[-+][0-9]+)?", v)]
    assert len(numbers) >= len(expected) > 100
    assert set(expected) <= set(numbers)
    assert any(len(v.replace(".", "").replace("-", "").split("E")[0].strip("0")) == 16 for v in numbers)


def test_report_inputs_and_runinfo(outputs):
    wb = openpyxl.load_workbook(outputs / "report.xlsx")
    inputs = [row for row in wb["Inputs"].iter_rows(values_only=True)]
    assert inputs[1][0] == "scenario_id" and [r[0] for r in inputs[2:5]] == ["baseline", "hot", "urban"]
    header = next(i for i, row in enumerate(inputs) if row[0] == "vehicle_id")
    assert [r[0] for r in inputs[header + 1:]] == ["CAR-1", "CAR-2", "PICKUP-1", "TRUCK-1"]
    assert inputs[header + 4][18] == 4.9   # low_gear_ratio of the dual axle, written in bulk
    info = {row[0]: row[1] for row in wb["RunInfo"].iter_rows(values_only=True) if row and row[0]}
    assert info["physics"] == "thesis" and "fleetrun_version" in info


def test_labels_are_text_in_excel_and_escaped_in_html(tmp_path):
    evil_class = '=HYPERLINK("http://evil.example","x")'
    evil_id = "<script>alert(1)</script>"
    # XlsxWriter's constant_memory mode copies a text of this shape into the sheet XML
    # unescaped (its marker for a pre-built rich string): here it would plant a formula in B1
    rich = '<r><t>x</t></r></is></c><c r="B1"><f>1+1</f></c><c r="C1" t="inlineStr"><is><r><t>y</t></r>'
    path = write_fleet(tmp_path / "evil.xlsx",
                       [vehicle(evil_id, vehicle_class=evil_class), vehicle("B", vehicle_class="+1+2"),
                        vehicle("C", vehicle_class=rich)],
                       [scenario("<b>s</b>", description="<img src=x onerror=alert(1)>")])
    out = tmp_path / "out"
    result = fakes.invoke_run(path, "--out", out, "--no-cache", "-q")
    assert result.exit_code == 0, result.stderr
    wb = openpyxl.load_workbook(out / "report.xlsx", rich_text=False)
    seen, quoted, rich_seen = 0, 0, 0
    for ws in wb.worksheets:
        for row in ws.iter_rows():
            for cell in row:
                if cell.value in (evil_class, evil_id, "+1+2", rich):
                    assert cell.data_type == "s", (ws.title, cell.coordinate)
                    seen += 1
                    rich_seen += cell.value == rich
                if isinstance(cell.value, str) and cell.value.startswith(("=", "+")):
                    # the XLSX form of the CSVs' apostrophe: stays text when a user edits it
                    assert cell.quotePrefix, (ws.title, cell.coordinate, cell.value)
                    quoted += 1
                assert cell.data_type != "f", (ws.title, cell.coordinate, cell.value)
    assert seen >= 6 and quoted >= 4 and rich_seen >= 2
    page = (out / "summary.html").read_text()
    assert "<script>" not in page and "<img" not in page and "<b>s</b>" not in page
    assert "&lt;script&gt;" not in page or True  # ids are not shown in the class table
    assert "&lt;b&gt;s&lt;/b&gt;" in page and "&lt;img src=x onerror=alert(1)&gt;" in page
    assert "=HYPERLINK(&#34;http://evil.example&#34;,&#34;x&#34;)" in page


class _Collector(html.parser.HTMLParser):
    def __init__(self):
        super().__init__()
        self.urls, self.rows, self._row, self.svgs, self.tags = [], [], None, 0, set()
        self._in_class_table = False

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        self.tags.add(tag)
        for key in ("src", "href"):
            if key in attrs:
                self.urls.append(attrs[key])
        if tag == "svg":
            self.svgs += 1
        if tag == "table" and attrs.get("id") == "class-table":
            self._in_class_table = True
        if self._in_class_table and tag == "tr":
            self._row = {}
        if self._in_class_table and tag == "td" and self._row is not None:
            self._row[attrs["data-column"]] = attrs["data-value"]

    def handle_endtag(self, tag):
        if tag == "tr" and self._row:
            self.rows.append(self._row)
            self._row = None
        if tag == "table":
            self._in_class_table = False


def test_summary_html_self_contained_with_class_table(outputs):
    page = (outputs / "summary.html").read_text()
    parsed = _Collector()
    parsed.feed(page)
    assert parsed.urls == [] and "script" not in parsed.tags and "http://" not in page.replace(
        "http://www.w3.org/2000/svg", "")
    assert parsed.svgs >= 3   # revenue and fuel charts plus the maps
    classes = read_csv(outputs / "class_summary.csv", dtype=str, keep_default_na=False)
    assert len(parsed.rows) == len(classes)
    for html_row, (_, csv_row) in zip(parsed.rows, classes.iterrows()):
        for column, value in html_row.items():
            assert value == csv_row[column], column
    assert '<meta name="viewport"' in page and "@media print" in page
    assert read_csv(outputs / "results.csv").shape[0] == 12


def test_scenario_without_vehicles_rows_is_fine(tmp_path):
    path = write_fleet(tmp_path / "z.xlsx", [vehicle(count=0)], [scenario()])
    out = tmp_path / "out"
    result = fakes.invoke_run(path, "--out", out, "--no-cache", "-q")
    assert result.exit_code == 0, result.stderr
    row = read_csv(out / "results.csv").iloc[0]
    assert row.miles_total == 0 and row.fuel_gal_total == 0 and row.mpg > 0


def _cell(wb, ref: str):
    """The cell an absolute chart reference such as 'Efficiency maps'!$B$17 names."""
    sheet, _, address = ref.rpartition("!")
    return wb[sheet.strip("'")][address.replace("$", "")]


def _cells(wb, ref: str):
    sheet, _, address = ref.rpartition("!")
    cells = wb[sheet.strip("'")][address.replace("$", "")]
    return [c for row in cells for c in row]


def test_efficiency_map_charts_point_at_the_rows_and_columns_their_legend_names(outputs):
    """Issue 12: the map charts were one row off (legend showing efficiencies, first torque
    row dropped, an empty row included). Read every series back and follow its references."""
    from fleetrun.run.runner import MAP_SPEEDS_RPM, MAP_TORQUE_FRACTIONS

    wb = openpyxl.load_workbook(outputs / "report.xlsx")
    charts = wb["Efficiency maps"]._charts
    assert len(charts) == 4   # LD_4WD, LD_FWD, LD_RWD, HD_TANDEM_DUAL
    for chart in charts:
        assert [s.tx.strRef for s in chart.series].count(None) == 0
        legends = [_cell(wb, s.tx.strRef.f).value for s in chart.series]
        assert legends == [f"{speed:g} rpm" for speed in MAP_SPEEDS_RPM]
        for series, speed in zip(chart.series, MAP_SPEEDS_RPM):
            legend = _cell(wb, series.tx.strRef.f)
            values = _cells(wb, series.val.numRef.f)
            categories = _cells(wb, series.cat.numRef.f)
            # the values sit in the legend's column, directly below it, one per torque fraction
            assert {c.column for c in values} == {legend.column}
            assert [c.row for c in values] == list(range(legend.row + 1, legend.row + 1 + len(MAP_TORQUE_FRACTIONS)))
            assert [c.value for c in categories] == list(MAP_TORQUE_FRACTIONS)
            assert [c.row for c in categories] == [c.row for c in values]
            # they are the losses (1 - efficiency) of the efficiency table above, same column
            table_rows = len(MAP_TORQUE_FRACTIONS) + 1
            efficiency = [wb["Efficiency maps"].cell(row=c.row - table_rows, column=c.column).value for c in values]
            assert wb["Efficiency maps"].cell(row=legend.row - table_rows, column=legend.column).value == f"{speed:g} rpm"
            # both tables hold 16 significant digits of values below 1 (XLSX_RTOL): each is
            # within 6.1e-16 of its exact value, the difference within 2e-15 absolute
            assert [c.value for c in values] == pytest.approx([1.0 - e for e in efficiency], rel=0, abs=2e-15)


def test_every_chart_has_axis_titles_a_zero_based_value_axis_and_human_legends(outputs):
    wb = openpyxl.load_workbook(outputs / "report.xlsx")
    seen = 0
    for ws in wb.worksheets:
        for chart in ws._charts:
            seen += 1
            assert chart.x_axis.title is not None and chart.y_axis.title is not None, ws.title
            if ws.title == "Revenue memo":
                # the tornado: changes from the central value, a value axis centred on zero
                assert "change" in _text(chart.y_axis.title).lower()
            else:
                assert chart.y_axis.scaling.min == 0, ws.title
            for series in chart.series:
                label = (series.tx.v if series.tx.v is not None else _cell(wb, series.tx.strRef.f).value)
                assert "_" not in label, (ws.title, label)   # no field names such as state_tax_usd
    assert seen == 8


def _text(title) -> str:
    return "".join(r.t for p in title.tx.rich.p for r in (p.r or []))


def test_every_sheet_has_a_page_setup(outputs):
    wb = openpyxl.load_workbook(outputs / "report.xlsx")
    for ws in wb.worksheets:
        assert ws.sheet_properties.pageSetUpPr.fitToPage, ws.title
        # fitToWidth absent is 1 (ECMA-376 CT_PageSetup default; XlsxWriter leaves defaults out)
        assert ws.page_setup.fitToWidth in (None, 1), ws.title
        assert ws.page_setup.orientation in ("landscape", "portrait"), ws.title
    assert wb["Summary"].page_setup.fitToHeight in (None, 1)    # the Summary prints on one page
    assert all(wb[name].page_setup.fitToHeight == 0 for name in SHEETS if name != "Summary")
    for name in ("ByClass", "ByVehicle", "Fiscal years"):
        assert wb[name].print_title_rows == "$1:$1"             # the header row on every page
    assert wb["ByClass"]["G2"].number_format == "0.00%"         # diff_efficiency in percent


SOFFICE = next((p for p in map(__import__("shutil").which, ("soffice", "libreoffice")) if p), None)
PDFTOTEXT = __import__("shutil").which("pdftotext")


@pytest.mark.skipif(SOFFICE is None or PDFTOTEXT is None,
                    reason="LibreOffice (libreoffice-calc-nogui) and poppler-utils are not installed")
def test_report_prints_through_libreoffice(outputs, tmp_path):
    """LibreOffice's PDF export: the Summary is one page, each sheet starts a page, and each
    efficiency map (its two tables) stays on one page."""
    import subprocess

    subprocess.run([SOFFICE, "--headless", "--convert-to", "pdf", "--outdir", str(tmp_path),
                    str(outputs / "report.xlsx")], check=True, capture_output=True, timeout=180,
                   env={**__import__("os").environ, "HOME": str(tmp_path)})
    pdf = tmp_path / "report.pdf"
    text = subprocess.run([PDFTOTEXT, "-layout", str(pdf), "-"], check=True, capture_output=True,
                          text=True).stdout
    pages = text.split("\f")
    assert "Fleet fuel and fuel-tax forecast" in pages[0] and "Headline" in pages[0]
    # Sheet order (docs/interface.md): Summary, Revenue memo, Assumptions, then the tables.
    assert "Summary, page 1 of" in pages[0] and "Revenue memo, page 2 of" in pages[1]
    assert "Assumptions, page 3 of" in pages[2]
    maps = [p for p in pages if "gear ratio" in p and "vehicle type(s)" in p]
    assert len(maps) == 4
    for page in maps:
        assert "efficiency \\ torque fraction" in page and "loss \\ torque fraction" in page
        assert page.count("4000 rpm") >= 3   # both tables' headers and the chart legend
    # The monthly Fiscal periods table runs over several pages and repeats its header on each;
    # the rest of the report stays short enough to print (16 pages before that table existed).
    periods = [p for p in pages if re.search(r"Fiscal periods, page \d+ of", p)]
    assert periods and all("scenario_id" in p and "fuel_gal" in p for p in periods)
    assert len(pages) - len(periods) <= 16


def test_chart_labels_and_legend_fit_inside_the_chart():
    """The class chart's labels and legend (the long class names and scenario ids that were
    clipped at 390 and 1366 px) lie inside the SVG's box: a label's right end at the label
    column, its left end (at 6.6 px per character of the 11 px font, a generous width) not
    before 0; legend items wrap before the right edge."""
    from fleetrun.reports import charts

    classes = ["Tractor-trailer (class 8)", "Medium truck (class 6)", "Bus"]
    scenarios = ["baseline", "hot_summer_with_a_long_identifier", "congested_urban", "ev_adoption_2030"]
    chart = charts.grouped_bars(classes, scenarios, {(c, s): 1e9 for c in classes for s in scenarios})
    for group in chart["groups"]:
        assert chart["label_width"] - 6 - 6.6 * len(group["label"]) >= 0
    for item in chart["legend"]:
        assert item["x"] >= 0 and item["x"] + 14 + 6.6 * len(item["name"]) <= chart["width"]
    assert len({item["y"] for item in chart["legend"]}) > 1          # it wrapped
    for group in chart["groups"]:
        for bar in group["bars"]:   # the value text after the longest bar stays inside
            assert chart["label_width"] + bar["length"] + 4 + 6.6 * len(bar["text"]) <= chart["width"]
