"""A table's rows as worksheet XML in one piece: what XlsxWriter writes cell by cell, column by column.

XlsxWriter's ``constant_memory`` mode (reports/xlsx.py) spends ~5-6 us of Python per cell
(argument checks, a cell record, then the cell's XML when the row is flushed); a 7,600-vehicle
ByVehicle sheet is 190,000 cells, a second of a run that simulates in about as long. Here each
column's cells are formatted in one pass (a number as XlsxWriter writes it, ``%.16G``; a text
as its own inline-string code writes it, once per distinct text) and the rows joined and
appended to the sheet's row file, with the sheet's dimensions and row pointer set as XlsxWriter
would have set them. The output is the same bytes: every template is checked against
XlsxWriter's own ``_write_row`` / ``_write_cell`` on the sheet first, style indices are taken
in the order XlsxWriter would take them, and a table this cannot write exactly (a row with its
own height or format, a rich-string marker, a value of another type, not constant_memory) is
left to the cell-by-cell path (:func:`write_rows` returns False).
``tests/test_sheet_rows.py`` compares the two, byte for byte, on hostile values and a whole report.
"""
from __future__ import annotations

import io
import math
import re
from functools import lru_cache
from typing import Callable

from xlsxwriter.utility import xl_col_to_name
from xlsxwriter.worksheet import CellNumberTuple, CellStringTuple

_USED = ("_write_cell", "_write_row", "_write_single_row", "_check_dimensions")   # XlsxWriter's own
MIN_ROWS = 8   # below this, the cell-by-cell path is as fast and there is nothing to gain


def _xml(ws, write: Callable[[], None]) -> str:
    """What ``write`` (a call of the worksheet's own XML writer) writes, as text."""
    fh, ws.fh = ws.fh, io.StringIO()
    try:
        write()
        return ws.fh.getvalue()
    finally:
        ws.fh = fh


def _column_kind(values: list) -> str | None:
    """'number' (floats and ints, None/NaN/inf as empty), 'text' (str and None, or NaN for a
    missing text) or None (anything else: booleans, numpy scalars, rich-string markers)."""
    types = set(map(type, values))
    types.discard(type(None))
    if types <= {float, int}:
        return "number"
    if types <= {str, float} and all(type(v) is not float or not math.isfinite(v) for v in values):
        return None if any(type(v) is str and v.startswith("<r>") and v.endswith("</r>") for v in values) else "text"
    return None


def _present(value) -> bool:
    """Whether the cell-by-cell path writes a cell for ``value`` (finite numbers and texts)."""
    return value is not None and (type(value) is str or math.isfinite(value))


def _first_uses(ws, columns: list[list], formats: list) -> list:
    """The formats of the block (one per column, or a function of the value for texts; a cell
    without one takes its column's) in the order XlsxWriter's row-by-row flush would first ask
    for their style index."""
    seen: dict[int, tuple] = {}
    for k, (values, fmt) in enumerate(zip(columns, formats)):
        info = ws.col_info.get(k)
        fallback = info.column_format if info is not None else None
        picked: dict = {}
        for i, value in enumerate(values):
            if not _present(value):
                continue
            key = value if callable(fmt) else None
            if key in picked:
                continue
            f = picked[key] = (fmt(value) if callable(fmt) else fmt) or fallback
            if f is not None and (id(f) not in seen or (i, k) < seen[id(f)][0]):
                seen[id(f)] = ((i, k), f)
            if not callable(fmt):
                break
    return [f for _, f in sorted(seen.values(), key=lambda item: item[0])]


def _number_cells(ws, col: int, first_row: int, values: list, fmt) -> list[str] | None:
    """The column's number cells as XML ('' for an empty cell), or None if the template does not
    match XlsxWriter's own cell XML."""
    head, tail, finite = f'<c r="{xl_col_to_name(col)}', f'"{_style(ws, col, fmt)}><v>', math.isfinite
    cells = [f"{head}{row}{tail}{v:.16G}</v></c>" if v is not None and finite(v) else ""
             for row, v in zip(_row_numbers(first_row, len(values)), values)]
    for i, v in enumerate(values):
        if cells[i]:
            own = _xml(ws, lambda: ws._write_cell(first_row + i, col, CellNumberTuple(v, fmt)))
            return cells if own == cells[i] else None
    return cells


def _text_cells(ws, col: int, first_row: int, values: list, pick) -> list[str]:
    """The column's text cells as XML ('' for an empty cell): a plain text (:data:`PLAIN`) in the
    inline-string template XlsxWriter's own XML of the first one confirmed; any other text as
    XlsxWriter writes it; each once per distinct text (its format is ``pick(text)``), with the
    cell reference put in front."""
    head = f'<c r="{xl_col_to_name(col)}'
    tails: dict = {}   # text -> its cell's XML after the cell reference
    plain: dict = {}   # id(format) -> the plain-text template's (head, tail), or None: not confirmed
    cells = []
    for row, v in zip(_row_numbers(first_row, len(values)), values):
        if type(v) is not str:
            cells.append("")
            continue
        tail = tails.get(v)
        if tail is None:
            tail = tails[v] = _text_tail(ws, col, int(row) - 1, v, pick(v), plain)
        cells.append(f"{head}{row}{tail}")
    return cells


def _text_tail(ws, col: int, row: int, text: str, fmt, plain: dict) -> str:
    """A text cell's XML after its cell reference (the same in every row): the plain-text
    template where XlsxWriter's own XML of the format's first plain text confirmed it, else
    XlsxWriter's own XML of this cell."""
    if "_x" not in text and PLAIN.match(text):
        template = plain.get(id(fmt), False)
        if template is False:
            template = plain[id(fmt)] = _plain_template(ws, col, row, text, fmt)
        if template is not None:
            return f"{template[0]}{text}{template[1]}"
    own = _xml(ws, lambda: ws._write_cell(row, col, CellStringTuple(text, fmt)))
    return own[len(f'<c r="{xl_col_to_name(col)}{row + 1}'):]


@lru_cache(maxsize=8)
def _row_numbers(first_row: int, rows: int) -> tuple[str, ...]:
    """The 1-based numbers of rows ``first_row`` .. ``first_row + rows - 1`` (0-based) as text,
    made once for all the columns of a block."""
    return tuple(map(str, range(first_row + 1, first_row + rows + 1)))


#: A text XlsxWriter writes as it is: no character it escapes (XML, control characters, its
#: ``_xHHHH_`` escapes, the non-characters), no leading or trailing space.
PLAIN = re.compile(r'(?!\s)[^\x00-\x1f&<>"\ufffe\uffff]+(?<!\s)\Z')


def _plain_template(ws, col: int, row: int, text: str, fmt) -> tuple[str, str] | None:
    """(head, tail) around a plain text in its cell XML after the cell reference, if XlsxWriter's
    own cell XML of ``text`` is that; else None."""
    head, tail = f'"{_style(ws, col, fmt)} t="inlineStr"><is><t>', "</t></is></c>"
    own = _xml(ws, lambda: ws._write_cell(row, col, CellStringTuple(text, fmt)))
    return (head, tail) if own == f'<c r="{xl_col_to_name(col)}{row + 1}{head}{text}{tail}' else None


def _style(ws, col: int, fmt) -> str:
    """The ``s`` attribute XlsxWriter gives a cell of this format in this column."""
    if fmt is not None:
        return f' s="{fmt._get_xf_index()}"'
    info = ws.col_info.get(col)
    if info is not None and info.column_format is not None:
        return f' s="{info.column_format._get_xf_index()}"'
    return ""


def _fits(ws, first_row: int, rows: int, columns: list[list], kinds: list) -> bool:
    """Whether the block can be written as one piece: constant_memory, nothing pending at or past
    ``first_row``, no row of the block (bar the last) with its own height or format, only
    plain numbers and texts, no text past Excel's cell limit, plain ``<row>`` tags; and the
    XlsxWriter internals this module uses are there (another version may lack them: then the
    cell-by-cell path, and ``tests/test_sheet_rows.py`` says the block path is no longer used)."""
    try:
        return _fits_here(ws, first_row, rows, columns, kinds)
    except (AttributeError, TypeError):
        return False


def _fits_here(ws, first_row: int, rows: int, columns: list[list], kinds: list) -> bool:
    if not all(callable(getattr(ws, name, None)) for name in _USED):
        return False
    if not ws.constant_memory or rows < MIN_ROWS or first_row < ws.previous_row:
        return False
    if any(r >= first_row for r in ws.table) or ws.comments:
        return False
    if any(first_row <= r < first_row + rows for r in ws.row_info):
        return False
    if None in kinds:
        return False
    limit = ws.xls_strmax // 2   # texts are only in "text" columns ("number" ones hold floats and ints)
    if any(type(v) is str and len(v) > limit for values, kind in zip(columns, kinds) if kind == "text" for v in values):
        return False
    return _xml(ws, lambda: ws._write_row(first_row, None)) == f'<row r="{first_row + 1}">'


def write_rows(ws, first_row: int, columns: list[list], formats: list) -> bool:
    """Write rows ``first_row`` .. ``first_row + n - 2`` (0-based) of the table whose columns are
    ``columns`` (n values each) into ``ws`` as XlsxWriter would, and return True; the last row is
    left to the caller (written cell by cell, so the sheet's end is XlsxWriter's own). ``formats``:
    per column the Format, or for text columns a function of the text giving it. False: the block
    is not one this can write exactly; write it cell by cell (what may have been done already,
    the pending row flushed and style indices taken, is what that path does first, in the
    same order)."""
    rows = len(columns[0]) if columns else 0
    kinds = [_column_kind(values) for values in columns]
    if not _fits(ws, first_row, rows, columns, kinds):
        return False
    body = [values[:-1] for values in columns]
    ws._write_single_row(first_row)    # the row pending before the block (the header): its styles first
    for fmt in _first_uses(ws, body, formats):
        fmt._get_xf_index()
    cells = []
    for k, (values, fmt, kind) in enumerate(zip(body, formats, kinds)):
        if kind == "number":
            column = _number_cells(ws, k, first_row, values, fmt)
            if column is None:
                return False
        else:
            column = _text_cells(ws, k, first_row, values, fmt if callable(fmt) else (lambda v, fmt=fmt: fmt))
        cells.append(column)
    _append(ws, first_row, cells)
    return True


def _append(ws, first_row: int, cells: list[list[str]]) -> None:
    """The rows' XML into the sheet's row file; dimensions and the row pointer as XlsxWriter's
    cell writes would leave them (empty rows write nothing)."""
    rows = ["".join(parts) for parts in zip(*cells)]
    filled = [i for i, xml in enumerate(rows) if xml]
    if not filled:
        return
    used = [k for k, column in enumerate(cells) if any(column)]
    ws._check_dimensions(first_row + filled[0], used[0])
    ws._check_dimensions(first_row + filled[-1], used[-1])
    ws.fh.write("".join([f'<row r="{first_row + i + 1}">{rows[i]}</row>' for i in filled]))
    ws.previous_row = first_row + filled[-1]
