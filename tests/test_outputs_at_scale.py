"""Outputs at any size (docs/report.md, "Outputs at any size"): report.xlsx copies per-vehicle
rows only up to ``DETAIL_ROWS`` and says where the rest are; results.csv and results.parquet
hold every row; no sheet is ever cut at Excel's row limit without an error.

The limit is lowered for these tests (a fleet of 4 vehicle types x 3 scenarios = 12 result
rows) so the path a 360,000-row fleet takes runs in a second; the rule is the same code."""
from __future__ import annotations

import openpyxl
import pandas as pd
import pytest

import test_fleet_fakes as fakes
from fleetrun.reports import xlsx
from test_fleet_fakes import read_csv


def _parquet_equals_csv(out):
    """results.parquet holds exactly results.csv's rows, columns and values (CSV text cells
    that start like a formula carry a leading ' only in the CSV)."""
    csv = read_csv(out / "results.csv")
    parquet = pd.read_parquet(out / "results.parquet")
    assert list(parquet.columns) == list(csv.columns)
    assert len(parquet) == len(csv)
    pd.testing.assert_frame_equal(parquet.reset_index(drop=True), csv, check_dtype=False, check_exact=True)
    return csv


def test_within_the_limit_the_workbook_holds_every_row(tmp_path):
    out = fakes.run_small_fleet_with_fake(tmp_path)
    csv = _parquet_equals_csv(out)
    wb = openpyxl.load_workbook(out / "report.xlsx", read_only=True)
    rows = list(wb["ByVehicle"].iter_rows(values_only=True))
    assert len(rows) == 1 + len(csv) == 13


def test_over_the_limit_the_workbook_says_where_the_rows_are(tmp_path, monkeypatch):
    monkeypatch.setattr(xlsx, "DETAIL_ROWS", 3)
    monkeypatch.setattr(xlsx, "INPUT_ROWS", 3)
    out = fakes.run_small_fleet_with_fake(tmp_path)
    csv = _parquet_equals_csv(out)            # no row lost: all 12 in both files
    assert len(csv) == 12 and set(csv.scenario_id) == {"baseline", "hot", "urban"}
    wb = openpyxl.load_workbook(out / "report.xlsx", read_only=True)
    rows = [r for r in wb["ByVehicle"].iter_rows(values_only=True)]
    assert list(rows[0][:len(csv.columns)]) == list(csv.columns)   # the columns, for reference
    note = " ".join(str(v) for r in rows[1:] for v in r if v is not None)
    assert "12 per-vehicle rows" in note and "3 this workbook holds" in note
    assert "results.csv" in note and "results.parquet" in note
    assert len(rows) == 3                      # header and the two lines of the note, no data
    inputs = [r for r in wb["Inputs"].iter_rows(values_only=True)]
    said = " ".join(str(v) for r in inputs for v in r if v is not None)
    assert "4 Vehicles rows" in said and "fleet.xlsx" in said
    assert not any(r[0] == "CAR-1" for r in inputs)


def test_a_sheet_past_excels_last_row_is_an_error_not_a_cut(tmp_path, monkeypatch):
    monkeypatch.setattr(xlsx, "EXCEL_MAX_ROWS", 3)
    book = xlsx.Book(tmp_path / "r.xlsx", cells=0)
    sheet = xlsx.Sheet(book, "S")
    sheet.append(["a"])
    sheet.rows([[1.0, 2.0]], [None])
    with pytest.raises(RuntimeError, match="would pass Excel's 3"):
        sheet.append(["too many"])
    with pytest.raises(RuntimeError, match="'S': 5 rows"):
        sheet.rows([[1.0, 2.0]], [None])
    book.close()
