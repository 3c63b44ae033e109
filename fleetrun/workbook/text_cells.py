"""Text that a spreadsheet would take for a formula: the one rule both CSV and XLSX outputs use.

OWASP, "CSV Injection": a cell starting with one of :data:`FORMULA_START` is taken as a
formula by Excel, LibreOffice and Google Sheets. The CSVs get a leading apostrophe
(:func:`neutralised`, column by column: run outputs and import-epa's measured results); report.xlsx writes such text as
a text cell with Excel's quote prefix (the stored form of a typed ``'``), so it shows as
typed and stays text when edited.
"""
from __future__ import annotations

FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def looks_like_formula(value: str) -> bool:
    """True when a spreadsheet would read the text ``value`` as a formula."""
    return value.startswith(FORMULA_START)


def neutralised(frame):
    """A shallow copy of the pandas ``frame`` with a leading ``'`` on every text cell that
    starts like a formula; numeric columns unchanged."""
    safe = frame.copy(deep=False)
    for name in safe.columns:
        column = safe[name]
        if column.dtype.kind == "O" or str(column.dtype) in ("string", "str"):
            texts = column.astype("string")
            risky = texts.str.startswith(FORMULA_START).fillna(False).to_numpy(dtype=bool)
            if risky.any():
                safe[name] = column.where(~risky, "'" + texts)
    return safe
