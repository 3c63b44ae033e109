"""reports/sheet_rows.py writes a table's rows as one piece of worksheet XML: the workbook must be
the same bytes as XlsxWriter's own cell-by-cell writing (the reference: XlsxWriter is the one
Excel writer, and its output is what Excel and LibreOffice were checked against), for hostile
values too, and fall back to that path where it cannot be exact."""
from __future__ import annotations

import zipfile

import pytest

import test_fleet_fakes as fakes
from fleetrun.reports import sheet_rows, xlsx
from fleetrun.run.runner import run_fleet
from fleetrun.workbook.reader import read_fleet

NUMBERS = [1.5, float("nan"), -0.0, 1e16, 5e-324, float("inf"), None, 3, 2 ** 60, 0.1 + 0.2, -1e-300, 123456789.0]
TEXTS = ["x", "=HYPERLINK(1)", " lead", "trail ", 'a<b&c>"d\'', "_x0041_", "\x01ctl", None, float("nan"), "+cmd",
         "é€😀", "", "-1", "line\nbreak", "\ufffe", "@SUM(A1)"]


def _parts(path) -> dict[str, bytes]:
    """The package's parts but its timestamps (docProps)."""
    with zipfile.ZipFile(path) as z:
        return {n: z.read(n) for n in z.namelist() if not n.startswith("docProps/")}


def _tables(path, monkeypatch, fast: bool) -> dict[str, bytes]:
    if not fast:
        monkeypatch.setattr(xlsx, "write_rows", lambda *args: False)
    book = xlsx.Book(path, cells=0)
    sheet = xlsx.Sheet(book, "T")
    sheet.ws.set_column(3, 3, 12, book.style("bold"))      # a column format: cells without a style take it
    sheet.append(["a", "b", "c", "d", "e", "f", "g"], "header")
    n = 3 * len(TEXTS)
    numbers, texts = (NUMBERS * n)[:n], (TEXTS * n)[:n]
    sheet.rows([numbers, texts, [f"id-{i}" for i in range(n)], numbers[::-1], [None] * n, texts[::-1],
                [i for i in range(n)]], ["#,##0", None, "0.00%", None, None, "wrap", "count"])
    sheet.append(["after", 1.0])
    sheet.rows([[1.0] * 9, ["=x"] * 9], [None, None])
    sheet.rows([[True] * 9, [1.0] * 9], [None, None])        # booleans: cell by cell
    sheet.rows([[None] * 9, [None] * 9], [None, None])       # nothing to write
    book.close()
    monkeypatch.undo()
    return _parts(path)


def test_block_rows_same_xml_as_cell_by_cell(tmp_path, monkeypatch):
    calls = []
    real = sheet_rows.write_rows
    monkeypatch.setattr(xlsx, "write_rows", lambda *args: calls.append(real(*args)) or calls[-1])
    fast = _tables(tmp_path / "fast.xlsx", monkeypatch, True)
    slow = _tables(tmp_path / "slow.xlsx", monkeypatch, False)
    assert calls[:3] == [True, True, False]       # the booleans went cell by cell
    assert fast.keys() == slow.keys()
    assert [name for name in fast if fast[name] != slow[name]] == []


def test_block_rows_refused_where_not_exact(tmp_path):
    book = xlsx.Book(tmp_path / "r.xlsx", cells=0)
    sheet = xlsx.Sheet(book, "T")
    sheet.append(["a"])
    sheet.ws.set_row(5, 30)                                   # a row with its own height
    assert not sheet_rows.write_rows(sheet.ws, 1, [[1.0] * 10], [None])
    assert not sheet_rows.write_rows(sheet.ws, 1, [["<r>rich</r>"] * 10], [lambda v: None])
    assert not sheet_rows.write_rows(sheet.ws, 1, [[1.0, "x"] * 5], [None])
    # a text longer than half XlsxWriter's cell limit (its own path checks and truncates it),
    # in a text column beside a number column: cell by cell
    long = "y" * (sheet.ws.xls_strmax // 2 + 1)
    assert not sheet_rows.write_rows(sheet.ws, 10, [[1.0] * 10, ["x"] * 9 + [long]], [None, lambda v: None])
    assert sheet_rows.write_rows(sheet.ws, 10, [[1.0] * 10, ["x"] * 10], [None, lambda v: None])   # the same, short: in one piece
    book.close()


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    base = tmp_path_factory.mktemp("rows")
    many = [fakes.vehicle(f"CAR-{i}", test_weight_kg=1500 + i, vehicle_class=["Car", "=Van", " SUV"][i % 3])
            for i in range(12)]
    fleet = read_fleet(fakes.write_fleet(base / "fleet.xlsx", many, [fakes.scenario("baseline"),
                                                                     fakes.scenario("hot", ambient_temp_C=38)]))
    return run_fleet(fleet, simulate=fakes.fake_simulate, error_model=None)


def test_report_xlsx_same_bytes_either_way(small_run, tmp_path, monkeypatch):
    xlsx.write_report_xlsx(small_run, tmp_path / "fast.xlsx")
    monkeypatch.setattr(xlsx, "write_rows", lambda *args: False)
    xlsx.write_report_xlsx(small_run, tmp_path / "slow.xlsx")
    fast, slow = _parts(tmp_path / "fast.xlsx"), _parts(tmp_path / "slow.xlsx")
    assert fast.keys() == slow.keys()
    assert [name for name in fast if fast[name] != slow[name]] == []
