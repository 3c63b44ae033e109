"""Atomic output: a failed run leaves no half-written file and keeps the previous good one.

Files are written to a temporary name in the destination folder (same filesystem, so the
final ``os.replace`` is atomic) and renamed only once complete. A run's output folder is
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


def write_run_outputs(result, out_dir: Path) -> dict[str, Path]:
    """Write the six outputs of a run into ``out_dir``, all or nothing."""
    from fleetrun.fleet.manifest import write_manifest
    from fleetrun.fleet.report_html import write_summary_html
    from fleetrun.fleet.report_xlsx import write_report_xlsx
    from fleetrun.fleet.workbook import file_sha256

    out_dir = Path(out_dir)
    with staging_dir(out_dir) as staging:
        result.results.to_csv(staging / "results.csv", index=False)
        result.classes.to_csv(staging / "class_summary.csv", index=False)
        result.fiscal.to_csv(staging / "fiscal_summary.csv", index=False)
        write_report_xlsx(result, staging / "report.xlsx")
        write_summary_html(result, staging / "summary.html")
        digests = {name: file_sha256(staging / name) for name in OUTPUT_FILES[:-1]}
        write_manifest(result, staging / "manifest.json", digests)
    return {name: out_dir / name for name in OUTPUT_FILES}
