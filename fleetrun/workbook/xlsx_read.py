"""The cell values of a fleet workbook's sheets, read by python-calamine.

python-calamine (Rust calamine) reads a 100,000-row sheet in about 2 s and does not expand XML
entities. What it does not report, the pre-scan of :mod:`fleetrun.workbook.xlsx_safety` does in
the same safety pass: formulas whose result was never saved, hidden rows and columns. That
pre-scan must run first: it refuses the cell references that would make any reader of a dense
table allocate without bound.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from python_calamine import CalamineWorkbook, SheetTypeEnum, SheetVisibleEnum
from xlsxwriter.utility import xl_col_to_name

from fleetrun.workbook.xlsx_safety import SheetScan


def _state(visible) -> str:
    if visible == SheetVisibleEnum.Hidden:
        return "hidden"
    if visible == SheetVisibleEnum.VeryHidden:
        return "veryHidden"
    return "visible"


@dataclass
class SheetInfo:
    name: str
    state: str = "visible"


@dataclass
class SheetValues:
    rows: list[tuple[int, tuple]]                       # (Excel row number, values from column A)
    merged: list[str] = field(default_factory=list)     # e.g. "B3:C3"
    hidden_rows: list[int] = field(default_factory=list)
    hidden_columns: list[int] = field(default_factory=list)
    uncached_formulas: dict[tuple[int, int], str] = field(default_factory=dict)  # (row, col) -> "=..."


class XlsxBook:
    """The worksheets of one workbook; a sheet's values are read on demand."""

    def __init__(self, path: Path, scans: dict[str, SheetScan] | None = None):
        self.path = Path(path)
        self.book = CalamineWorkbook.from_path(str(self.path))
        self.scans = scans or {}
        self.sheets = [SheetInfo(m.name, _state(m.visible))
                       for m in self.book.sheets_metadata if m.typ == SheetTypeEnum.WorkSheet]

    def close(self):
        self.book.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def read(self, sheet: SheetInfo) -> SheetValues:
        """Every non-empty row of ``sheet`` (None for empty cells), with what the pre-scan
        found in it."""
        data = self.book.get_sheet_by_name(sheet.name)
        rows = []
        for number, values in enumerate(data.to_python(skip_empty_area=False), start=1):
            if "" in values:   # calamine's empty cell: None, and trailing empties dropped
                cells = [None if v == "" else v for v in values]
                width = len(cells)
                while width and cells[width - 1] is None:
                    width -= 1
                if width:
                    rows.append((number, tuple(cells[:width])))
            elif values:       # a full row (the common case in a fleet table): as it is
                rows.append((number, tuple(values)))
        merged = [f"{xl_col_to_name(c0)}{r0 + 1}:{xl_col_to_name(c1)}{r1 + 1}"
                  for (r0, c0), (r1, c1) in (data.merged_cell_ranges or [])]
        scan = self.scans.get(sheet.name) or SheetScan()
        return SheetValues(rows=rows, merged=merged, hidden_rows=scan.hidden_rows,
                           hidden_columns=scan.hidden_columns, uncached_formulas=scan.uncached_formulas)
