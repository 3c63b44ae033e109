"""The schema is the one place of every column's physical range (issue 9): each number has
one, the template's Instructions sheet and docs/workbook.md show it, the reader enforces it."""
from __future__ import annotations

from pathlib import Path

import openpyxl
import pytest

from fleetrun.workbook.cells import CellProblem
from fleetrun.workbook.rows import parse_value
from fleetrun.workbook.schema import SCENARIO_COLUMNS, SIDECAR_COLUMNS, VEHICLE_COLUMNS
from fleetrun.workbook.template import write_template

DOCS = Path(__file__).resolve().parents[1] / "docs" / "workbook.md"
NUMERIC = [c for c in VEHICLE_COLUMNS + SCENARIO_COLUMNS + SIDECAR_COLUMNS if c.numeric]


@pytest.mark.parametrize("column", NUMERIC, ids=lambda c: c.name)
def test_every_number_has_a_physical_range(column):
    assert column.maximum is not None, column.name
    assert column.minimum is not None or column.strictly_positive, column.name
    low = column.minimum if column.minimum is not None else 0.0
    inside = (low + column.maximum) / 2 if column.kind != "integer" else int((low + column.maximum) // 2)
    raw = str(inside) if column.kind == "ratios" else inside
    parse_value(column, raw)
    above, below = column.maximum * 2 + 1, low - abs(low) - 1
    with pytest.raises(CellProblem, match=f"the range of {column.name} is"):
        parse_value(column, str(above) if column.kind == "ratios" else above)
    with pytest.raises(CellProblem):     # ratios and factors below 0 have their own words
        parse_value(column, str(below) if column.kind == "ratios" else below)


def test_ranges_documented_in_the_template_and_the_docs(tmp_path):
    path = tmp_path / "t.xlsx"
    write_template(path)
    rows = {r[0].value: r for r in openpyxl.load_workbook(path)["Instructions"].iter_rows()}
    docs = DOCS.read_text(encoding="utf-8")
    for sheet, columns in (("Vehicles", VEHICLE_COLUMNS), ("Scenarios", SCENARIO_COLUMNS)):
        for column in columns:
            if column.numeric:
                assert rows[f"{sheet}.{column.name}"][3].value == column.range_text()
                assert f"| `{column.name}` | {'yes' if column.required else 'no'} | {column.range_text()} |" in docs
