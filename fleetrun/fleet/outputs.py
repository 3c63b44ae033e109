"""Atomic output: a failed run leaves no half-written file and keeps the previous good one.

Files are written to a temporary name in the destination folder (same filesystem, so the
final ``os.replace`` is atomic) and renamed only once complete. A run's output folder is
assembled in a staging folder and swapped in as one step (:mod:`fleetrun.output_folder`).
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from fleetrun.errors import InputError


def prepare_output_folder(folder: Path, what: Path) -> None:
    """Create ``folder`` (and parents) for output ``what``, or say plainly why it cannot be."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{what}: cannot create the output folder {folder} ({exc.strerror or exc})",
                         hint="Choose an output path in a folder you can write to") from None
    if not folder.is_dir():
        raise InputError(f"{what}: {folder} is not a folder", hint="Choose another output path")


def default_file_mode() -> int:
    """The mode a new file gets (0o666 less the umask): temporary files start as 0o600."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


@contextlib.contextmanager
def atomic_file(path: Path):
    """Yield a temporary path beside ``path``; on success it replaces ``path``."""
    path = Path(path)
    prepare_output_folder(path.parent, path)
    if path.is_dir():
        raise InputError(f"{path}: is a folder, not a file", hint="Give a file name for the output")
    try:
        handle, temporary = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=path.suffix + ".tmp",
                                             dir=path.parent)
    except OSError as exc:
        raise InputError(f"{path}: cannot write here ({exc.strerror or exc})",
                         hint="Choose an output path in a folder you can write to") from None
    os.close(handle)
    try:
        yield Path(temporary)
        os.chmod(temporary, default_file_mode())
        os.replace(temporary, path)
    finally:
        if os.path.exists(temporary):
            os.unlink(temporary)


OUTPUT_FILES = ("report.xlsx", "summary.html", "results.csv", "class_summary.csv", "manifest.json")

# OWASP, "CSV Injection": a cell starting with one of these is taken as a formula by Excel,
# LibreOffice and Google Sheets. Such text cells get a leading apostrophe.
FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def csv_safe_text(value: str) -> str:
    """``value`` with a leading ``'`` when a spreadsheet would read it as a formula."""
    return "'" + value if value.startswith(FORMULA_START) else value


def write_csv(frame, path: Path) -> None:
    """``frame`` as CSV with every text cell neutralised (:func:`csv_safe_text`); numeric
    columns are written as numbers, unchanged."""
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
            if target.exists() and source.exists() and os.path.samefile(target, source):
                raise InputError(f"{source}: is an input of this run, and --out {out_dir} would "
                                 f"replace it with the run's {name}",
                                 hint="Choose another output folder (--out)")


def write_run_outputs(result, out_dir: Path) -> dict[str, Path]:
    """Write the five outputs of a run into ``out_dir``, all or nothing (the folder changes as
    one step: :func:`fleetrun.output_folder.new_output_folder`)."""
    from fleetrun.fleet.manifest import write_manifest
    from fleetrun.fleet.report_html import write_summary_html
    from fleetrun.fleet.report_xlsx import write_report_xlsx
    from fleetrun.fleet.workbook import file_sha256
    from fleetrun.output_folder import new_output_folder

    out_dir = Path(out_dir)
    refuse_overwriting_inputs(out_dir, [result.fleet.path, *result.cycle_inputs])
    with new_output_folder(out_dir, replaces=OUTPUT_FILES) as staging:
        write_csv(result.results, staging / "results.csv")
        write_csv(result.classes, staging / "class_summary.csv")
        write_report_xlsx(result, staging / "report.xlsx")
        write_summary_html(result, staging / "summary.html")
        digests = {name: file_sha256(staging / name) for name in OUTPUT_FILES[:-1]}
        write_manifest(result, staging / "manifest.json", digests)
    return {name: out_dir / name for name in OUTPUT_FILES}
