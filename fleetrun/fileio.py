"""Atomic file writing: the bottom-layer I/O every other layer uses (simulation's map cache,
fleet reports, diagnose, plots, commands).

A file is written to a temporary name in its destination folder (same filesystem, so the final
``os.replace`` is atomic) and renamed only once complete: a failed write leaves no half-written
file and keeps the previous good one. Imports nothing of fleetrun but :mod:`fleetrun.errors`.
"""
from __future__ import annotations

import contextlib
import errno
import os
import shutil
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from fleetrun.errors import InputError

#: A JSON object about to be written (``json.dumps``) or just read: the files' form, whose keys
#: docs/interface.md lists. Code passes typed records between modules, never these.
JsonDocument = dict[str, Any]


def prepare_output_folder(folder: Path, what: Path) -> None:
    """Create ``folder`` (and parents) for output ``what``, or say plainly why it cannot be."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{what}: cannot create the output folder {folder} ({exc.strerror or exc})",
                         hint="Choose an output path in a folder you can write to") from None
    if not folder.is_dir():
        raise InputError(f"{what}: {folder} is not a folder", hint="Choose another output path")


def why_not_writable(path: Path, exc: OSError) -> str:
    """Why ``path`` could not be created, for a message: a file standing where a folder of its
    path should be (``results`` a file, ``--out results/may``), else the system's reason."""
    blocking = next((p for p in Path(path).parents if p.exists() and not p.is_dir()), None)
    return f"{blocking} is a file, not a folder" if blocking else str(exc.strerror or exc)


def is_same_file(path: Path, other: Path) -> bool:
    """True when ``path`` and ``other`` both exist and are one file (by any name or link)."""
    return Path(path).exists() and Path(other).exists() and os.path.samefile(path, other)


def refuse_replacing_inputs(output: Path, inputs, option: str = "-o") -> None:
    """InputError if writing ``output`` would replace one of ``inputs`` (None entries skipped):
    a command's output never overwrites what it reads."""
    for source in inputs:
        if source is not None and is_same_file(output, source):
            raise InputError(f"{source}: is an input of this command, and {option} {output} would replace it",
                             hint=f"Choose another output path ({option})")


def refuse_outputs_replacing_inputs(folder: Path, names, inputs, option: str = "--out") -> None:
    """:func:`refuse_replacing_inputs` for each file ``names`` a command writes into ``folder``
    (e.g. ``diagnose-fleet --measured out/diagnosis.json --out out``)."""
    for name in names:
        refuse_replacing_inputs(Path(folder) / name, inputs, f"{option} {folder} (its {name})")


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
        try:
            yield Path(temporary)
            os.chmod(temporary, default_file_mode())
            os.replace(temporary, path)
        except OSError as exc:   # disk full, quota, a file system that refuses: the user's to fix
            raise InputError(f"{path}: cannot write it ({exc.strerror or exc}); the previous file, if "
                             "any, is unchanged", hint=_write_hint(exc)) from None
    finally:
        if os.path.exists(temporary):
            os.unlink(temporary)


def _write_hint(exc: OSError) -> str:
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return "Free some space or choose an output path on another disk"
    return "Choose an output path in a folder you can write to"


def write_text_atomic(path: Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_file(path) as temporary:
        temporary.write_text(text, encoding="utf-8")


def link_or_copy(source, target) -> None:
    """``target`` as a hard link of ``source`` (a symlink as a symlink), a copy where the file
    system has no hard links. For fleetrun's own outputs, which are replaced, never written in
    place: a kept earlier run then costs no bytes and no copying time."""
    if os.path.islink(source):
        os.symlink(os.readlink(source), target)
        return
    try:
        os.link(source, target)
    except OSError:
        shutil.copy2(source, target)


EARLIER_IMPORTS = "earlier-imports"   # beside an import's workbook: the workbooks it replaced
FORCE_IMPORT_HELP = f"Replace an existing workbook without keeping it in {EARLIER_IMPORTS}/."   # both imports' --force


def keep_earlier_import(path: Path) -> Path | None:
    """Before an import command replaces the workbook ``path`` (whose Scenarios sheet the
    analyst may have filled in since): a hard link of it (a copy where the file system has none)
    as ``earlier-imports/<stem>-<UTC time><suffix>`` beside it; None when there is no such file.
    The import then writes ``path`` anew (atomically, a new file), so the link keeps the earlier
    bytes. A folder of its own keeps the kept workbooks out of a batch's ``*.xlsx``."""
    path = Path(path)
    if not path.is_file():
        return None
    folder = path.parent / EARLIER_IMPORTS
    folder.mkdir(exist_ok=True)
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    kept, n = folder / f"{path.stem}-{stamp}{path.suffix}", 1
    while os.path.lexists(kept):
        n += 1
        kept = folder / f"{path.stem}-{stamp}-{n}{path.suffix}"
    link_or_copy(path, kept)
    return kept


@contextlib.contextmanager
def replacing_import(path: Path, force: bool) -> Iterator[Path | None]:
    """Around an import's write of ``path``: unless ``force``, the earlier workbook is kept
    first (:func:`keep_earlier_import`, yielded); if the write fails, ``path`` is as it was and
    the kept link is removed again."""
    kept = None if force else keep_earlier_import(path)
    try:
        yield kept
    except BaseException:
        if kept is not None:
            kept.unlink(missing_ok=True)
        raise


def kept_note(kept: Path | None) -> str:
    """The sentence an import adds when it kept the workbook it replaced."""
    return (f" The earlier workbook it replaced is kept as {kept} (its Scenarios sheet too: copy back what "
            "you had typed there).") if kept is not None else ""


def write_error_log(text: str, log_file: Path | None = None) -> Path:
    """Append ``text`` (an internal error's traceback) to ``log_file``, or without one to a new
    file ``fleetrun-error-<UTC time>-<pid>.log`` in the temporary folder; return its path.

    Every internal error leaves its traceback in a file whose path the ``Error:`` message names.
    """
    if log_file is None:
        stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
        log_file = Path(tempfile.gettempdir()) / f"fleetrun-error-{stamp}-{os.getpid()}.log"
    log_file = Path(log_file)
    with open(log_file, "a", encoding="utf-8") as fh:
        fh.write(text if text.endswith("\n") else text + "\n")
    return log_file


def refuse_unreadable_size(path: Path, max_bytes: int, kind: str, path_hint: str,
                           too_large_hint: str) -> None:
    """InputError unless ``path`` is a regular file (not a device, pipe or socket such as
    ``/dev/zero``) of at most ``max_bytes``: checked before any reader opens it. ``kind``: what
    such files are called in the message ("drive cycles", "workbooks")."""
    if not path.is_file():
        raise InputError("is not a regular file (a device, pipe or socket)", file=path, hint=path_hint)
    size = path.stat().st_size
    if size > max_bytes:
        raise InputError(f"is {size / 1e6:,.0f} MB; fleetrun reads {kind} up to "
                         f"{max_bytes / 1e6:,.0f} MB", file=path, hint=too_large_hint)
