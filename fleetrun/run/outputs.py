"""Atomic run output: a failed run leaves no half-written file and keeps the previous good one.

Single files are written by :func:`fleetrun.fileio.atomic_file`. A run's output folder is
assembled in a staging folder and swapped in as one step (:mod:`fleetrun.output_folder`).
"""
from __future__ import annotations

import csv
import io
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

from fleetrun.errors import InputError
from fleetrun.fileio import is_same_file
from fleetrun.output_folder import new_output_folder
from fleetrun.reports.changes import (KEEP_RUNS, EarlierRun, keep_earlier_run, prune_earlier_runs, read_manifest,
                                      same_schema)
from fleetrun.reports.html import write_summary_html
from fleetrun.reports.manifest import SCHEMA, write_manifest
from fleetrun.reports.xlsx import write_report_xlsx
from fleetrun.workbook.reader import file_sha256
from fleetrun.workbook.text_cells import neutralised

OUTPUT_FILES = ("report.xlsx", "summary.html", "results.csv", "results.parquet", "class_summary.csv",
                "fiscal_summary.csv", "revenue_memo.csv", "fiscal_periods.csv",
                "manifest.json")   # manifest.json last: it lists the others' sha256
# written when the fleet has Registrations (docs/registrations.md); an older run's are replaced
REGISTRATION_FILES = ("registrations.csv", "turnover.csv")

CSV_CHUNK_ROWS = 50_000    # rows formatted at a time: bounds the memory of the text
_NEEDS_QUOTES = re.compile(r'[,"\r\n]')


def write_csv(frame, path: Path) -> None:
    """``frame`` as CSV with a leading ``'`` on every text cell that starts like a formula
    (:func:`fleetrun.workbook.text_cells.neutralised`); numeric columns are written as numbers,
    unchanged.

    The bytes are those of ``pandas.DataFrame.to_csv(index=False)`` (numbers in Python's
    shortest round-trip ``repr``, missing values empty, text quoted only where it holds a
    comma, a quote or a line break), formatted column by column, which is several times faster
    for large tables (docs/benchmarks-run.md). Columns of other kinds go through pandas."""
    safe = neutralised(frame)
    if not all(_column_kind(safe[name]) for name in safe.columns):
        safe.to_csv(path, index=False)
        return
    with open(path, "w", encoding="utf-8", newline="") as handle:
        handle.write(",".join(_quoted(str(name)) for name in safe.columns) + "\n")
        for start in range(0, len(safe), CSV_CHUNK_ROWS):
            part = safe.iloc[start:start + CSV_CHUNK_ROWS]
            texts = [_column_texts(part[name]) for name in part.columns]
            handle.write("".join([",".join(row) + "\n" for row in zip(*texts)]))


def _column_kind(column) -> str | None:
    """How :func:`_column_texts` formats ``column`` ("float", "int", "text"); None: not handled."""
    kind = column.dtype.kind
    if isinstance(column.dtype, np.dtype) and column.dtype == np.float64:
        return "float"
    if isinstance(column.dtype, np.dtype) and kind in "iu":
        return "int"
    if isinstance(column.dtype, pd.api.extensions.ExtensionDtype) and kind in "iu":
        return "nullable int"             # pandas' Int64: <NA> is written empty
    if kind == "O" or str(column.dtype) in ("string", "str"):
        return "text"
    return None


def _column_texts(column) -> list[str]:
    """The CSV fields of one column, as pandas.to_csv writes them."""
    kind = _column_kind(column)
    if kind == "float":
        return _float_texts(column.to_numpy())
    if kind == "int":
        return list(map(str, column.to_numpy().tolist()))
    if kind == "nullable int":
        return ["" if value is pd.NA else str(value) for value in column.astype(object).tolist()]
    if str(column.dtype) in ("str", "string") and not column.isna().any() \
            and not column.str.contains(_NEEDS_QUOTES.pattern, regex=True).any():
        return column.astype(object).tolist()   # plain texts only (the common case): each its own field
    known: dict[str, str] = {}   # a text's field, once per distinct text (classes, fuels, scenarios repeat)
    texts = []
    for value in column.astype(object).tolist():
        if type(value) is str:
            text = known.get(value)
            if text is None:
                text = known[value] = _quoted(value)
        else:
            text = _text_field(value)
        texts.append(text)
    return texts


# repr writes a float without an exponent where 1e-4 <= |x| < 1e16 (and 0); Arrow's cast to
# text writes the same shortest round-trip digits, without an exponent below ~1e10
POSITIONAL_LOW, POSITIONAL_HIGH = 1e-4, 1e16
ARROW_POSITIONAL_HIGH = 1e10


def _float_texts(values: np.ndarray) -> list[str]:
    """``float.__repr__`` of each value, ``""`` for NaN (what pandas.to_csv writes).

    Where both write the number without an exponent, Arrow's cast of a float to text
    (double-conversion's shortest round-trip digits, as Python's repr: David Gay's shortest,
    closest to the value) gives repr's text but for the ``.0`` repr adds to a whole number, and
    takes ~0.1 us a value where repr takes ~0.5 (results.csv of 1,080,000 rows holds 18 million
    floats: docs/benchmarks-run.md). Every other value (an exponent in either text, NaN, inf)
    is formatted by repr itself. ``tests/test_csv_writer.py`` compares with repr on random bit
    patterns over the whole range of doubles."""
    magnitude = np.abs(values)
    with np.errstate(invalid="ignore"):
        positional = ((magnitude >= POSITIONAL_LOW) & (magnitude < POSITIONAL_HIGH)) | (values == 0.0)
    if np.count_nonzero(positional & (magnitude < ARROW_POSITIONAL_HIGH)) * 2 < len(values):
        texts = list(map(float.__repr__, values.tolist()))     # mostly values Arrow writes otherwise
        for i in np.flatnonzero(np.isnan(values)).tolist():
            texts[i] = ""
        return texts
    arrow = pc.cast(pa.array(values), pa.string())
    taken = positional & ~pc.match_substring(arrow, "e").to_numpy(zero_copy_only=False)
    whole = pa.array(taken & ~pc.match_substring(arrow, ".").to_numpy(zero_copy_only=False))
    texts = pc.if_else(whole, pc.binary_join_element_wise(arrow, ".0", ""), arrow).to_pylist()
    for i in np.flatnonzero(~taken).tolist():
        value = values[i]
        texts[i] = "" if value != value else float.__repr__(float(value))
    return texts


def _text_field(value) -> str:
    if value is None or value is pd.NA or (type(value) is float and math.isnan(value)):
        return ""
    return _quoted(str(value))


def _quoted(text: str) -> str:
    """A CSV field as pandas writes it: Python's csv module (QUOTE_MINIMAL, line terminator
    ``\\n``) decides for the rare text with a comma, quote or line-break character."""
    if _NEEDS_QUOTES.search(text):
        buffer = io.StringIO()
        csv.writer(buffer, lineterminator="\n").writerow([text])
        return buffer.getvalue()[:-1]
    return text


def write_parquet(frame, path: Path) -> None:
    """``frame`` (results.csv's table) as an Apache Parquet file, same columns and values:
    the per-vehicle detail at any size, for pandas, Arrow, DuckDB, Power BI (docs/report.md).
    Text is stored as typed (no formula prefix: nothing evaluates a Parquet cell)."""
    frame.to_parquet(path, engine="pyarrow", index=False, compression="zstd")


def refuse_overwriting_inputs(out_dir: Path, inputs, outputs=OUTPUT_FILES) -> None:
    """InputError if writing ``outputs`` into ``out_dir`` would replace one of ``inputs``."""
    out_dir = Path(out_dir)
    for name in outputs:
        target = out_dir / name
        for source in inputs:
            source = Path(source)
            if is_same_file(target, source):
                raise InputError(f"{source}: is an input of this run, and --out {out_dir} would "
                                 f"replace it with the run's {name}",
                                 hint="Choose another output folder (--out)")


def refuse_foreign_outputs(out_dir: Path) -> None:
    """InputError if ``out_dir`` holds a file with an output's name that fleetrun did not write
    (no fleetrun ``manifest.json`` beside it listing it): a run moves or deletes only its own
    files; a damaged manifest is said to be one."""
    out_dir = Path(out_dir)
    present = [name for name in OUTPUT_FILES if (out_dir / name).exists()]
    if not present:
        return
    manifest = out_dir / "manifest.json"
    data, damage = read_manifest(manifest)
    ours = same_schema(data, SCHEMA)
    if ours and not isinstance(data.get("outputs"), dict):
        damage = "has no list of the outputs"
    if damage:   # a crash, a full disk or a hand edit: the files may well be fleetrun's own
        raise InputError(f"{manifest}: is damaged ({damage}), so fleetrun cannot tell whether "
                         f"{', '.join(n for n in present if n != 'manifest.json') or 'the files'} beside it are an earlier run's outputs or someone else's files",
                         hint="If they are fleetrun's outputs, delete manifest.json and them (or move them "
                              "away) and run again; otherwise choose another output folder (--out)")
    listed = set(data["outputs"]) | {"manifest.json"} if ours else set()
    foreign = [name for name in present if name not in listed]
    if foreign:
        raise InputError(f"{out_dir}: holds {', '.join(foreign)} that fleetrun did not write "
                         "(no fleetrun manifest.json lists them); a run would replace them",
                         hint="Move them away, or choose another output folder (--out)")


def write_run_outputs(result, out_dir: Path, earlier: EarlierRun | None = None,
                      keep_runs: int = KEEP_RUNS) -> dict[str, Path]:
    """Write the outputs (docs/report.md) of a run into ``out_dir``, all or nothing: the folder changes as
    one step (:func:`fleetrun.output_folder.new_output_folder`). ``earlier``: the run
    already there (its manifest), whose files are then kept in ``earlier-runs/``
    (:func:`fleetrun.reports.changes.keep_earlier_run`); None replaces it. Of the runs kept
    there, the newest ``keep_runs`` stay (:func:`fleetrun.reports.changes.prune_earlier_runs`)."""

    out_dir = Path(out_dir)
    refuse_overwriting_inputs(out_dir, [result.fleet.path, *result.cycle_inputs])
    with new_output_folder(out_dir, replaces=OUTPUT_FILES + REGISTRATION_FILES) as staging:
        if earlier is not None:
            keep_earlier_run(out_dir, staging, earlier, OUTPUT_FILES)
        write_csv(result.results, staging / "results.csv")
        write_parquet(result.results, staging / "results.parquet")
        write_csv(result.classes, staging / "class_summary.csv")
        write_csv(result.fiscal, staging / "fiscal_summary.csv")
        write_csv(result.memo, staging / "revenue_memo.csv")
        write_csv(result.periods, staging / "fiscal_periods.csv")
        if result.registrations is not None:
            write_csv(result.registrations, staging / "registrations.csv")
            write_csv(result.turnover, staging / "turnover.csv")
        write_report_xlsx(result, staging / "report.xlsx")
        write_summary_html(result, staging / "summary.html")
        digests = {name: file_sha256(staging / name) for name in OUTPUT_FILES[:-1]}
        write_manifest(result, staging / "manifest.json", digests)
    prune_earlier_runs(out_dir, keep_runs, SCHEMA)   # after the swap: the new folder holds them all
    return {name: out_dir / name for name in OUTPUT_FILES}
