"""Atomic run output: a failed run leaves no half-written file and keeps the previous good one.

Single files are written by :func:`fleetrun.fileio.atomic_file`. A run's output folder is
assembled in a temporary sibling folder and its files moved in one by one only after every
output has been written.
"""
from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path

from fleetrun.errors import InputError
from fleetrun.fileio import prepare_output_folder


@contextlib.contextmanager
def staging_dir(out_dir: Path):
    """Yield a temporary folder beside ``out_dir``; on success its files move into ``out_dir``.

    Each file is moved with ``os.replace``: readers never see a partial file, and if anything
    fails before the move, ``out_dir`` is untouched.
    """
    out_dir = Path(out_dir)
    prepare_output_folder(out_dir.parent, out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"{out_dir}: exists and is not a folder", hint="Choose another output folder")
    try:
        staging = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}-staging-", dir=out_dir.parent))
    except OSError as exc:
        raise InputError(f"{out_dir}: cannot write here ({exc.strerror or exc})",
                         hint="Choose an output folder you can write to") from None
    try:
        yield staging
        out_dir.mkdir(parents=True, exist_ok=True)
        for item in sorted(staging.iterdir()):
            target = out_dir / item.name
            if item.is_dir():
                if target.exists():
                    shutil.rmtree(target)
                os.replace(item, target)
            else:
                os.replace(item, target)
    finally:
        shutil.rmtree(staging, ignore_errors=True)


OUTPUT_FILES = ("report.xlsx", "summary.html", "results.csv", "class_summary.csv", "fiscal_summary.csv",
                "manifest.json")


def write_run_outputs(result, out_dir: Path, earlier: dict | None = None) -> dict[str, Path]:
    """Write the six outputs of a run into ``out_dir``, all or nothing. ``earlier``: the
    manifest of the run already there, whose files are then kept in ``earlier-runs/``
    (:func:`fleetrun.fleet.changes.keep_earlier_run`); None replaces it."""
    from fleetrun.fleet.changes import keep_earlier_run
    from fleetrun.fleet.manifest import write_manifest
    from fleetrun.fleet.report_html import write_summary_html
    from fleetrun.fleet.report_xlsx import write_report_xlsx
    from fleetrun.fleet.workbook import file_sha256

    out_dir = Path(out_dir)
    with staging_dir(out_dir) as staging:
        if earlier is not None:
            keep_earlier_run(out_dir, staging, earlier, OUTPUT_FILES)
        result.results.to_csv(staging / "results.csv", index=False)
        result.classes.to_csv(staging / "class_summary.csv", index=False)
        result.fiscal.to_csv(staging / "fiscal_summary.csv", index=False)
        write_report_xlsx(result, staging / "report.xlsx")
        write_summary_html(result, staging / "summary.html")
        digests = {name: file_sha256(staging / name) for name in OUTPUT_FILES[:-1]}
        write_manifest(result, staging / "manifest.json", digests)
    return {name: out_dir / name for name in OUTPUT_FILES}
