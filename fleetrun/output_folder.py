"""An output folder that changes as one step: build a new folder, then swap it in.

A run's outputs (``report.xlsx``, ``results.csv``, ``manifest.json``, ...) must change together
or not at all: a reader, or a crash, must never meet a new manifest beside old results. So the
outputs are written into a staging folder beside the target, and only when every file is
complete is the staging folder swapped in for the target::

    with new_output_folder(out, replaces=OUTPUT_FILES) as staging:
        write everything into staging
    # here out holds the new outputs (and every other file the old out held)

The swap is two renames in the target's parent: ``out -> .out-old-<pid>-<token>``, then
``staging -> out``; the old folder is removed afterwards. Files of the old folder that the new
run does not write (an input workbook, the user's notes) are carried into the new folder first
as hard links (copies where the file system has none), so the swap loses nothing.

Crashes: a process killed while writing leaves ``.out-staging-<pid>-<token>``; one killed
(SIGKILL, a power cut) between the two renames leaves ``.out-old-...`` and no ``out``. Ctrl-C,
SIGTERM and SIGHUP are held back from the first rename until the old folder's late files are
rescued (:func:`_signals_held`), so a signal stops the run before or after the swap, never
within it. The next run into the same
folder removes stale staging folders and puts a stranded old folder back first
(:func:`clean_leftovers`); folders of a process that is still running are left alone.

Failures (a file of the old folder open in another program, which on Windows locks it; no
permission; disk full) raise :class:`~fleetrun.errors.InputError` naming the path, with the
previous folder unchanged. A read-only output folder is refused, not replaced.

Concurrency: one lock per output folder (:func:`folder_lock`, a lock file
``.out.fleetrun-lock`` beside ``out`` holding the owner's pid, removed on release). A second
run into the same folder waits for the first (up to ``$FLEETRUN_LOCK_WAIT_S``, default 600 s)
and then exits 1 naming the holder; so two runs never both read the same earlier run and
overwrite each other.

Only fleetrun's own files are moved or deleted: whatever another program writes into ``out``
while the run assembles its staging folder (before the swap) is moved into the new folder
after it, never removed with the old one.
"""
from __future__ import annotations

import contextlib
import errno
import os
import secrets
import shutil
import signal
import sys
import time
from collections.abc import Iterable, Iterator
from pathlib import Path

from fleetrun.errors import InputError, signal_handlers
from fleetrun.fileio import link_or_copy, why_not_writable

STAGING = "staging"
OLD = "old"
STALE_AFTER_S = 24 * 3600     # where a process cannot be asked whether it runs (Windows)
LOCK_WAIT_S = 600.0           # default wait for another run's lock ($FLEETRUN_LOCK_WAIT_S)
_HELD: dict[str, int] = {}    # locks this process holds (resolved folder -> depth)


HELD_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


@contextlib.contextmanager
def _signals_held(done: Path | None = None) -> Iterator[None]:
    """Hold Ctrl-C, SIGTERM and SIGHUP back in the block; one that arrives meanwhile is raised
    again when the block ends (its KeyboardInterrupt carrying ``outputs_in_place = done`` when
    the block ended normally, so the message says the new outputs are in ``done``; a block that
    failed, such as a rename undone, did not put them there). Python runs every signal handler in the main thread, whichever
    thread the system handed the signal to, so the held signals get a handler that only notes
    them (a thread's signal mask would not do: the system gives a process's signal to any thread
    that does not block it, a pyarrow worker for one). An ignored signal stays ignored; off the
    main thread, where handlers cannot be set, the block runs as it is."""
    noted: list[int] = []
    completed = False
    try:
        with signal_handlers(HELD_SIGNALS, lambda signum, _frame: noted.append(signum)):
            yield
        completed = True
    finally:
        try:
            for number in dict.fromkeys(noted):
                signal.raise_signal(number)
        except KeyboardInterrupt as stop:
            if completed and done is not None:
                stop.outputs_in_place = str(done)
            raise


def _sibling(target: Path, kind: str) -> Path:
    return target.parent / f".{target.name}-{kind}-{os.getpid()}-{secrets.token_hex(4)}"


def _owner_alive(entry: Path) -> bool:
    """Whether the process that made ``.out-<kind>-<pid>-<token>`` may still be using it."""
    parts = entry.name.rsplit("-", 2)
    pid = int(parts[1]) if len(parts) == 3 and parts[1].isdigit() else None
    if pid is None:          # a name without a pid (older fleetrun): nobody owns it
        return False
    if pid == os.getpid():
        return True
    if os.name == "nt":      # os.kill(pid, 0) would terminate the process on Windows
        return time.time() - entry.stat().st_mtime < STALE_AFTER_S
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, another user's
        return True
    return True


def clean_leftovers(target: Path) -> list[Path]:
    """Remove staging folders that killed runs left beside ``target``; if a run was killed
    between its two renames (no ``target``, an old folder aside), put the old folder back.
    Returns what was removed or restored."""
    target = Path(target)
    parent = target.parent
    if not parent.is_dir():
        return []
    handled: list[Path] = []
    prefix = f".{target.name}-"
    entries = sorted(e for e in parent.iterdir() if e.name.startswith(prefix) and e.is_dir()
                     and e.name[len(prefix):].split("-", 1)[0] in (STAGING, OLD))
    for entry in entries:
        if _owner_alive(entry):
            continue
        kind = entry.name[len(prefix):].split("-", 1)[0]
        if kind == OLD and not target.exists():
            os.rename(entry, target)
        else:
            _remove_tree(entry)
        handled.append(entry)
    return handled


def _carry_over(old: Path, new: Path, replaced: set[str]) -> None:
    """Hard-link (or copy) every entry of ``old`` that ``new`` does not have and the run does
    not replace into ``new``."""
    for entry in old.iterdir():
        if entry.name in replaced or (new / entry.name).exists():
            continue
        if entry.is_dir() and not entry.is_symlink():
            shutil.copytree(entry, new / entry.name, symlinks=True, copy_function=link_or_copy)
        else:
            link_or_copy(entry, new / entry.name)



def _folder_mode(target: Path) -> int:
    if target.is_dir():
        return target.stat().st_mode & 0o7777
    umask = os.umask(0)
    os.umask(umask)
    return 0o777 & ~umask


def _error(target: Path, doing: str, exc: OSError) -> InputError:
    reason = exc.strerror or str(exc)
    hint = "Choose an output folder you can write to"
    if exc.errno in (errno.EACCES, errno.EPERM, errno.EBUSY):
        hint = ("A file in it may be open in another program (Excel locks open files on Windows) "
                "or the folder is not writable: close it, or choose another output folder")
    elif exc.errno == errno.ENOSPC:
        hint = "Free some space or choose an output folder on another disk"
    return InputError(f"{target}: {doing} ({reason}); the previous outputs there are unchanged",
                      hint=hint)


def _resolve_target(target: Path) -> Path:
    """``target`` as an absolute path without ``..`` or links (``--out ..`` must name the parent
    folder, so that the staging folder is its sibling and never inside it)."""
    target = Path(os.path.abspath(Path(target).expanduser()))
    if target.is_symlink() or target.exists():
        target = target.resolve()
    if target.parent == target:
        raise InputError(f"{target}: the root of a file system cannot be an output folder",
                         hint="Choose an output folder inside it")
    if target.exists() and not target.is_dir():
        raise InputError(f"{target}: exists and is not a folder", hint="Choose another output folder")
    if target.is_dir() and not _writable(target):
        raise InputError(f"{target}: the output folder is read-only; it is left as it is",
                         hint="Make it writable, or choose another output folder (--out)")
    return target


def _writable(folder: Path) -> bool:
    return os.access(folder, os.W_OK | os.X_OK)


def _remove_tree(path: Path) -> None:
    """Remove a folder of fleetrun's, read-only entries too (so no ``.out-old-*`` piles up)."""
    def retry(function, name, _exc):
        try:
            os.chmod(os.path.dirname(name) or ".", 0o700)
            os.chmod(name, 0o700)
            function(name)
        except OSError:
            pass

    if sys.version_info >= (3, 12):
        shutil.rmtree(path, onexc=retry)
    else:  # pragma: no cover
        shutil.rmtree(path, onerror=retry)


def _lock_wait_s() -> float:
    """``$FLEETRUN_LOCK_WAIT_S`` [s] (default :data:`LOCK_WAIT_S`); a value that is not a number
    of seconds is the scheduler's mistake to fix (exit 1), not a bug."""
    text = os.environ.get("FLEETRUN_LOCK_WAIT_S", "").strip()
    if not text:
        return LOCK_WAIT_S
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0 <= value < 1e7:
        raise InputError(f"$FLEETRUN_LOCK_WAIT_S '{text}' is not a number of seconds",
                         hint="Set it to the seconds a run may wait for another run's output folder, e.g. 600")
    return value


def _lock_path(target: Path) -> Path:
    return target.parent / f".{target.name}.fleetrun-lock"


def _try_lock(handle) -> bool:
    try:
        if os.name == "nt":  # pragma: no cover - Windows
            import msvcrt

            msvcrt.locking(handle.fileno(), msvcrt.LK_NBLCK, 1)
        else:
            import fcntl

            fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False
    return True


def _holder(lock: Path) -> str:
    try:
        text = lock.read_text(encoding="utf-8", errors="replace").strip()
    except OSError:
        text = ""
    return text[:200] or "another process"


def _acquire(lock: Path, target: Path, wait_s: float):
    """An open, locked handle of ``lock`` (the same file as the path names now); waits for
    another holder up to ``wait_s`` seconds, then InputError naming the holder."""
    deadline = time.monotonic() + wait_s
    while True:
        handle = open(lock, "a+", encoding="utf-8")
        if _try_lock(handle):
            try:
                same = os.path.samestat(os.fstat(handle.fileno()), os.stat(lock))
            except OSError:
                same = False
            if same:    # not a file the previous holder unlinked while we waited
                return handle
        handle.close()
        if time.monotonic() >= deadline:
            raise InputError(f"{target}: another fleetrun run "
                             f"is writing into this output folder ({_holder(lock)}; lock file {lock})",
                             hint="Wait for it to finish, or choose another output folder (--out)")
        time.sleep(0.05)


@contextlib.contextmanager
def folder_lock(target: Path, wait_s: float | None = None) -> Iterator[Path]:
    """Hold the lock of output folder ``target`` (re-entrant within this process); see the
    module doc. Yields the resolved target."""
    target = _resolve_target(target)
    key = str(target)
    if key in _HELD:
        _HELD[key] += 1
        try:
            yield target
        finally:
            _HELD[key] -= 1
        return
    if wait_s is None:
        wait_s = _lock_wait_s()
    lock = _lock_path(target)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        handle = _acquire(lock, target, wait_s)
    except OSError as exc:
        raise InputError(f"{target}: cannot write here ({why_not_writable(target, exc)})",
                         hint="Choose an output folder you can write to") from None
    try:
        handle.seek(0)
        handle.truncate()
        handle.write(f"pid {os.getpid()} since {time.strftime('%Y-%m-%dT%H:%M:%SZ', time.gmtime())}\n")
        handle.flush()
        _HELD[key] = 1
        yield target
    finally:
        _HELD.pop(key, None)
        with contextlib.suppress(OSError):
            os.unlink(lock)      # before unlocking: a waiter then sees a new file and retries
        handle.close()


def swap_in(staging: Path, target: Path, replaces: Iterable[str] = ()) -> None:
    """Make the complete folder ``staging`` the new ``target`` in one step (see the module doc).

    Entries of the old ``target`` that ``staging`` lacks and whose names are not in
    ``replaces`` are carried over; those in ``replaces`` disappear with the old folder.
    """
    staging, target = Path(staging), _resolve_target(target)
    if _holds_working_folder(target):
        with _signals_held(done=target):
            _replace_in_place(staging, target, set(replaces))
        return
    try:
        os.chmod(staging, _folder_mode(target))
        if target.exists():
            _carry_over(target, staging, set(replaces))
    except OSError as exc:
        raise _error(target, "cannot prepare the new output folder", exc) from None
    old = _sibling(target, OLD)
    had_old = target.exists()
    with _signals_held(done=target):   # a signal between the renames would leave no target until the next run
        _rename_pair(staging, target, old if had_old else None)
        if had_old:
            _rescue(old, target, set(replaces))
    if had_old:
        _remove_tree(old)   # a locked leftover (or a signal now): the next run removes it


def _rename_pair(staging: Path, target: Path, old: Path | None) -> None:
    """``target -> old`` (when ``old``), then ``staging -> target``; the first undone if the
    second fails."""
    try:
        if old is not None:
            os.rename(target, old)
    except OSError as exc:
        raise _error(target, "cannot replace the output folder", exc) from None
    try:
        os.rename(staging, target)
    except OSError as exc:
        if old is not None:
            os.rename(old, target)
        raise _error(target, "cannot replace the output folder", exc) from None


def _holds_working_folder(target: Path) -> bool:
    """Whether ``target`` is the working folder (``--out .``) or one of its parents (``--out ..``):
    renamed aside and removed, it would leave the shell that started fleetrun in a removed
    folder, where ``ls`` shows nothing: the outputs and the user's own files look lost."""
    try:
        here = Path(os.getcwd()).resolve()
    except OSError:
        return False
    return here == target or target in here.parents


def _replace_in_place(staging: Path, target: Path, replaced: set[str]) -> None:
    """The swap for a working folder: ``staging``'s entries moved into ``target`` one atomic
    rename each, ``manifest.json`` last (a reader that sees the new manifest sees every new
    output), then the replaced outputs this run did not write removed; ``target`` itself and
    every other entry of it stay where they are."""
    entries = sorted(staging.iterdir(), key=lambda entry: entry.name == "manifest.json")
    try:
        for entry in entries:
            twin = target / entry.name
            if entry.is_dir() and twin.is_dir() and not twin.is_symlink():
                _merge_new(entry, twin)     # earlier-runs/: the runs kept before stay
            else:
                os.replace(entry, twin)
        for name in replaced - {entry.name for entry in entries}:
            if (target / name).is_file():
                os.unlink(target / name)
    except OSError as exc:
        raise _error(target, "cannot replace the outputs", exc) from None


def _merge_new(source: Path, target: Path) -> None:
    """Move the entries of ``source`` that ``target`` lacks into it."""
    for entry in source.iterdir():
        if not os.path.lexists(target / entry.name):
            os.rename(entry, target / entry.name)


def _rescue(old: Path, new: Path, replaced: set[str]) -> None:
    """Move into ``new`` what appeared in ``old`` after the carry-over (another program writing
    into the folder during the run): only fleetrun's replaced outputs and the links it made
    remain in ``old`` to be removed."""
    for entry in list(old.iterdir()):
        if entry.name in replaced:
            continue
        twin = new / entry.name
        try:
            if not os.path.lexists(twin):
                os.rename(entry, twin)
            elif entry.is_dir() and not entry.is_symlink() and twin.is_dir():
                _rescue(entry, twin, set())
            elif not (entry.is_dir() or twin.is_dir()) and not os.path.samefile(entry, twin):
                os.replace(entry, twin)
        except OSError:
            continue


@contextlib.contextmanager
def new_output_folder(target: Path, replaces: Iterable[str] = ()) -> Iterator[Path]:
    """Yield an empty staging folder beside ``target``; when the block ends without an
    exception, it becomes ``target`` in one step (:func:`swap_in`). On an exception the
    staging folder is removed and ``target`` is untouched. Leftovers of killed runs beside
    ``target`` are cleaned first (:func:`clean_leftovers`)."""
    with folder_lock(target) as target:
        with _staged(target, replaces) as staging:
            yield staging


@contextlib.contextmanager
def _staged(target: Path, replaces: Iterable[str]) -> Iterator[Path]:
    try:
        clean_leftovers(target)
        staging = _sibling(target, STAGING)
        staging.mkdir()
    except OSError as exc:
        raise InputError(f"{target}: cannot write here ({exc.strerror or exc})",
                         hint="Choose an output folder you can write to") from None
    try:
        try:
            yield staging
        except OSError as exc:
            # the file system refused an output (disk full, quota, permissions): the user's to fix
            raise _error(target, "cannot write the outputs", exc) from None
        swap_in(staging, target, replaces)
    finally:
        if staging.exists():
            _remove_tree(staging)
