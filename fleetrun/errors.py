"""Errors a user can act on.

Library code raises :class:`FleetrunError` for bad input or a domain problem; the CLI turns it
into one ``Error: ...`` line on stderr and exit code 1, never a traceback.
"""
from __future__ import annotations

import contextlib
import difflib
import signal
import threading
from collections.abc import Iterable, Iterator


class FleetrunError(Exception):
    """A user-facing error that says where the problem is and what to do.

    ``file``, ``sheet``, ``row`` (as Excel shows it), ``column`` and ``value`` locate the
    problem; ``hint`` says what to do about it.
    """

    def __init__(self, message: str, *, file=None, sheet=None, row=None, column=None,
                 value=None, hint: str | None = None):
        super().__init__(message)
        self.message = message
        self.file = file
        self.sheet = sheet
        self.row = row
        self.column = column
        self.value = value
        self.hint = hint

    def location(self) -> str:
        parts = []
        if self.file is not None:
            parts.append(str(self.file))
        if self.sheet is not None:
            cell = f"{self.sheet}!"
            if self.column is not None and self.row is not None:
                cell += f"{self.column}{self.row}"
            elif self.row is not None:
                cell += f"row {self.row}"
            parts.append(cell)
        elif self.row is not None:
            parts.append(f"row {self.row}" + (f", column {self.column}" if self.column is not None else ""))
        elif self.column is not None:
            # in a TOML sidecar or config the "column" is a key
            label = "key" if str(self.file or "").endswith(".toml") else "column"
            parts.append(f"{label} {self.column}")
        return ": ".join(parts)

    def __str__(self) -> str:
        text = self.message
        loc = self.location()
        if loc:
            text = f"{loc}: {text}"
        if self.hint:
            text = f"{text}. {self.hint}" if not text.endswith(".") else f"{text} {self.hint}"
        return text


class InputError(FleetrunError):
    """Bad input: a file, argument or value the user can fix."""


class DomainError(FleetrunError):
    """The input is well-formed but outside what the models can do."""


class MissingExtraError(FleetrunError):
    """An optional part of fleetrun (an extra of pyproject.toml) is not installed."""


def closest_names(name: str, valid, n: int = 1) -> list[str]:
    """The valid names closest to ``name`` (case-insensitive), best first."""
    valid = list(valid)
    lower = {v.lower(): v for v in valid}
    hits = difflib.get_close_matches(name.lower(), list(lower), n=n, cutoff=0.4)
    return [lower[h] for h in hits]


def unknown_name_error(kind: str, name: str, valid, hint: str | None = None) -> InputError:
    """An error for an unknown name that lists the valid ones and the closest match."""
    valid = sorted(valid)
    near = closest_names(name, valid)
    msg = f"unknown {kind} '{name}'"
    if near:
        msg += f" (did you mean '{near[0]}'?)"
    msg += f"; valid: {', '.join(valid)}"
    return InputError(msg, hint=hint)


class Terminated(KeyboardInterrupt):
    """SIGTERM (a scheduler's time limit, ``kill``, a shutdown) or SIGHUP (the terminal or ssh
    session closed) raised in the main thread as Ctrl-C is: every ``finally`` runs, so a run
    stops with its output folder as it was, its staging folder removed and its lock released
    (docs/batch.md). ``signal_name``: which."""

    def __init__(self, signal_name: str = "SIGTERM"):
        super().__init__(signal_name)
        self.signal_name = signal_name


def interruption(exc: KeyboardInterrupt) -> str:
    """What stopped the command, as the ``Error:`` line says it."""
    return f"stopped by {exc.signal_name}" if isinstance(exc, Terminated) else "interrupted (Ctrl-C)"


def interrupted_outputs(exc: KeyboardInterrupt, folder: str) -> str:
    """What an interruption left of the output ``folder``: as it was, or, for a signal held
    until an output folder's swap ended (fleetrun.output_folder), the new outputs in place."""
    done = getattr(exc, "outputs_in_place", None)
    if done:
        return f"it came as the outputs were moved in: {done} holds this run's complete outputs; nothing more was written"
    return f"nothing more was written and {folder} is as it was"


@contextlib.contextmanager
def signal_handlers(numbers: Iterable[int], handler) -> Iterator[None]:
    """``handler`` for the signals ``numbers`` in the block, the earlier handlers back after it.
    A signal the caller ignores stays ignored (`nohup fleetrun run ...` must outlive the
    terminal), as does one whose handler Python did not set; off the main thread, where Python
    cannot set handlers, the block runs as it is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {number: signal.signal(number, handler) for number in numbers
                if signal.getsignal(number) not in (signal.SIG_IGN, None)}
    try:
        yield
    finally:
        for number, earlier in previous.items():
            signal.signal(number, earlier)
