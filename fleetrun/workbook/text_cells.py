"""Text that a spreadsheet would take for a formula: the one rule both CSV and XLSX outputs use.

OWASP, "CSV Injection": a cell starting with one of :data:`FORMULA_START` is taken as a
formula by Excel, LibreOffice and Google Sheets. The CSVs get a leading apostrophe
(:func:`fleetrun.run.outputs.write_csv`, column by column); report.xlsx writes such text as
a text cell with Excel's quote prefix (the stored form of a typed ``'``), so it shows as
typed and stays text when edited.
"""
from __future__ import annotations

FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def looks_like_formula(value: str) -> bool:
    """True when a spreadsheet would read the text ``value`` as a formula."""
    return value.startswith(FORMULA_START)
