"""DMV-style registration extracts (CSV): read in chunks and aggregated, never loaded whole.

An extract has the Registrations sheet's columns (docs/registrations.md): ``vehicle_class``
required; ``count`` optional (without it every line is one vehicle); ``model_year``, ``fuel``,
``make``, ``model`` optional; other columns are ignored. Lines are read ``chunk_rows`` at a
time and added into one count per distinct (class, fuel, make, model, model year), so memory
is bounded by the number of distinct combinations, not by the lines (a million-vehicle
extract of a state's 50,000 make/model/year combinations needs a few megabytes).
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pandas as pd

from fleetrun.errors import InputError
from fleetrun.workbook.cells import NAME_SPACING, THOUSANDS_PATTERN, TOTAL_ROW, as_name, is_total_label
from fleetrun.workbook.schema import FUELS, REGISTRATION_CLASSES

KEYS = ("vehicle_class", "fuel", "make", "model", "model_year")
CHUNK_ROWS = 200_000
MAX_COUNT = 1e9


def _columns(path: Path) -> tuple[list[str], str]:
    """The extract's columns to read and its separator: a comma, or the semicolon or tab that
    Excel writes in locales whose decimal mark is a comma."""
    if path.stat().st_size == 0:
        raise InputError("is empty (0 bytes)", file=path, hint="Export the extract again")
    for sep in (",", ";", "\t"):
        header = pd.read_csv(path, nrows=0, encoding="utf-8-sig", sep=sep)
        names = {as_name(c): c for c in header.columns}
        if "vehicle_class" in names:
            return [names[k] for k in (*KEYS, "count") if k in names], sep
    header = pd.read_csv(path, nrows=0, encoding="utf-8-sig")
    raise InputError(f"has no vehicle_class column (columns: {', '.join(map(str, header.columns))})", file=path,
                     hint="Name the FHWA class column vehicle_class (docs/registrations.md)")


def _file_line(path: Path, sep: str, data_row: int) -> int:
    """The file's line number (1-based) of data row ``data_row`` (0-based) as pandas counts
    them: blank and whitespace-only lines are skipped, so after one the rows' count and the
    file's lines part (a quoted value may also span lines)."""
    with open(path, encoding="utf-8-sig", newline="") as handle:
        reader = csv.reader(handle, delimiter=sep)
        rows = -1          # the first line that is not blank is the header
        for cells in reader:
            if not cells or (len(cells) == 1 and not cells[0].strip()):
                continue
            if rows == data_row:
                return reader.line_num
            rows += 1
    return data_row + 2


def _check(chunk: pd.DataFrame, first_row: int, path: Path, sep: str) -> None:
    """InputError naming the file's line of the first bad value in ``chunk``, whose first row
    is data row ``first_row`` (0-based) of the file."""
    for name, allowed in (("vehicle_class", REGISTRATION_CLASSES), ("fuel", FUELS)):
        if name not in chunk:
            continue
        values = chunk[name]
        bad = values.notna() & ~values.isin(allowed)
        if bad.any():
            where = int(np.flatnonzero(bad.to_numpy())[0])
            what = TOTAL_ROW if is_total_label(values.iloc[where]) else f"is not one of {', '.join(allowed)}"
            line = _file_line(path, sep, first_row + where)
            raise InputError(f"line {line}: {name} {values.iloc[where]!r} {what}", file=path,
                             hint="Fix the extract (docs/registrations.md)")
    if sep == ";" and "count" in chunk:
        _refuse_one_group(chunk["count"], first_row, path, sep)
    for name, low, high in (("model_year", 1900, 2200), ("count", 0, MAX_COUNT)):
        if name not in chunk:
            continue
        grouped = chunk[name].str.fullmatch(THOUSANDS_PATTERN, na=False)   # "2,524,145": the number shown
        numbers = pd.to_numeric(chunk[name].where(~grouped, chunk[name].str.replace(",", "")), errors="coerce")
        bad = (chunk[name].notna() & numbers.isna()) | (numbers < low) | (numbers > high)
        if bad.any():
            where = int(np.flatnonzero(bad.to_numpy())[0])
            line = _file_line(path, sep, first_row + where)
            raise InputError(f"line {line}: {name} {chunk[name].iloc[where]!r} is not a number "
                             f"from {low} to {high:g}", file=path, hint="Fix the extract (docs/registrations.md)")
        chunk[name] = numbers


# 2.524 or 2,524: in a semicolon-separated export (Excel's in locales whose decimal mark is a
# comma and whose thousands separator a point) either mark may be either
_ONE_GROUP = r"[+-]?[1-9]\d{0,2}[.,]\d{3}"


def _refuse_one_group(counts: pd.Series, first_row: int, path: Path, sep: str) -> None:
    """InputError for a count of a semicolon-separated export that reads as two numbers a
    thousand times apart (``2.524``: 2524 vehicles, or 2.524 read with a decimal point)."""
    ambiguous = counts.str.fullmatch(_ONE_GROUP, na=False)
    if ambiguous.any():
        where = int(np.flatnonzero(ambiguous.to_numpy())[0])
        raise InputError(f"line {_file_line(path, sep, first_row + where)}: count {counts.iloc[where]!r} could be "
                         f"{counts.iloc[where].replace(',', '').replace('.', '')} (a thousands separator) or "
                         f"{counts.iloc[where].replace(',', '.')} (a decimal mark) in a semicolon-separated export",
                         file=path, hint="Export the counts without thousands separators (Number format, no "
                                         "1000 separator) and try again")


def read_extract(path, chunk_rows: int = CHUNK_ROWS) -> pd.DataFrame:
    """One row per distinct (vehicle_class, fuel, make, model, model_year) with its ``count``
    (the sum of the counts, or of the lines when the extract has none)."""
    path = Path(path)
    if not path.is_file():
        raise InputError("does not exist", file=path, hint="Check the path of the registration extract")
    try:
        return _aggregate(path, chunk_rows)
    except UnicodeDecodeError as exc:
        raise InputError(f"is not UTF-8 text (byte 0x{exc.object[exc.start]:02x}; a Windows code page?)", file=path,
                         hint="Save it as 'CSV UTF-8' (Excel) or re-export it in UTF-8") from None


def _aggregate(path: Path, chunk_rows: int) -> pd.DataFrame:
    usecols, sep = _columns(path)
    totals: pd.Series | None = None
    row = 0
    reader = pd.read_csv(path, usecols=usecols, chunksize=chunk_rows, dtype=str, encoding="utf-8-sig",
                         keep_default_na=False, na_values=[""], sep=sep)
    for chunk in reader:
        chunk.columns = [as_name(c) for c in chunk.columns]
        for name in ("vehicle_class", "fuel"):
            if name in chunk:
                chunk[name] = chunk[name].str.strip().str.lower().str.replace(NAME_SPACING, "_", regex=True)
        _check(chunk, row, path, sep)
        row += len(chunk)
        if "count" not in chunk:
            chunk["count"] = 1.0
        keys = [k for k in KEYS if k in chunk]
        part = chunk.groupby(keys, dropna=False, sort=False)["count"].sum()
        totals = part if totals is None else totals.add(part, fill_value=0.0)
    if totals is None or totals.empty:
        raise InputError("has no data lines below the header", file=path, hint="Export the extract again")
    frame = totals.reset_index()
    for k in KEYS:
        if k not in frame:
            frame[k] = None
    return frame[list(KEYS) + ["count"]]

