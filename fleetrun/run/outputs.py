"""Atomic run output: a failed run leaves no half-written file and keeps the previous good one.

Single files are written by :func:`fleetrun.fileio.atomic_file`. A run's output folder is
assembled in a staging folder and swapped in as one step (:mod:`fleetrun.output_folder`).
"""
from __future__ import annotations

from pathlib import Path

from fleetrun.errors import InputError
from fleetrun.fileio import is_same_file
from fleetrun.workbook.text_cells import FORMULA_START

OUTPUT_FILES = ("report.xlsx", "summary.html", "results.csv", "class_summary.csv", "fiscal_summary.csv",
                "revenue_memo.csv", "fiscal_periods.csv", "manifest.json")
# written when the fleet has Registrations (docs/registrations.md); an older run's are replaced
REGISTRATION_FILES = ("registrations.csv", "turnover.csv")


def write_csv(frame, path: Path) -> None:
    """``frame`` as CSV with a leading ``'`` on every text cell that starts like a formula
    (:data:`fleetrun.workbook.text_cells.FORMULA_START`); numeric columns are written as numbers,
    unchanged."""
    safe = frame.copy(deep=False)
    for name in safe.columns:
        column = safe[name]
        if column.dtype.kind == "O" or str(column.dtype) in ("string", "str"):
            texts = column.astype("string")
            risky = texts.str.startswith(FORMULA_START).fillna(False).to_numpy(dtype=bool)
            if risky.any():
                safe[name] = column.where(~risky, "'" + texts)
    safe.to_csv(path, index=False)


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


def write_run_outputs(result, out_dir: Path, earlier: dict | None = None) -> dict[str, Path]:
    """Write the outputs (docs/report.md) of a run into ``out_dir``, all or nothing: the folder changes as
    one step (:func:`fleetrun.output_folder.new_output_folder`). ``earlier``: the manifest of
    the run already there, whose files are then kept in ``earlier-runs/``
    (:func:`fleetrun.reports.changes.keep_earlier_run`); None replaces it."""
    from fleetrun.reports.changes import keep_earlier_run
    from fleetrun.reports.manifest import write_manifest
    from fleetrun.reports.html import write_summary_html
    from fleetrun.reports.xlsx import write_report_xlsx
    from fleetrun.workbook.reader import file_sha256
    from fleetrun.output_folder import new_output_folder

    out_dir = Path(out_dir)
    refuse_overwriting_inputs(out_dir, [result.fleet.path, *result.cycle_inputs])
    with new_output_folder(out_dir, replaces=OUTPUT_FILES + REGISTRATION_FILES) as staging:
        if earlier is not None:
            keep_earlier_run(out_dir, staging, earlier, OUTPUT_FILES)
        write_csv(result.results, staging / "results.csv")
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
    return {name: out_dir / name for name in OUTPUT_FILES}
