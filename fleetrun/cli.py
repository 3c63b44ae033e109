"""The ``fleetrun`` command line: a thin layer over the library.

Each command lives in ``fleetrun/commands/<name>.py`` and exposes ``command``. Library errors
(:class:`fleetrun.errors.FleetrunError`) and the file system refusing a path the user gave
become one ``Error: ...`` line and exit code 1. Anything else is an internal error (a bug):
its traceback goes to a log file (:func:`fleetrun.fileio.write_error_log`) that the one
``Error:`` line names, exit code 4 (as ``fleetrun run``, docs/batch.md). Ctrl-C is an
``Error:`` line and exit code 1 (the outputs are as they were).

Whatever a command prints passes through :class:`Printable`: control characters and escape
sequences from a workbook cell or a file name (``ESC ] 0 ; ...`` retitles a terminal, others
recolour it or move the cursor) are shown as ``\x1b`` and never reach a terminal raw.
"""
from __future__ import annotations

import gc
import importlib
import re
import signal
import sys
import traceback
from pathlib import Path

import click

from fleetrun import __version__
from fleetrun.errors import FleetrunError, Terminated, interruption, signal_handlers
from fleetrun.fileio import write_error_log

EXIT_INTERNAL = 4
# The cyclic garbage collector in a command's process (docs/benchmarks-run.md, "Fourth pass"):
# a young generation collected every 50,000 new objects instead of 700 (a command allocates
# millions, nearly all freed by reference counting; 510 collections took 0.16 s of a 7,600-row
# run, 5 take 0.04 s), and the modules a command imports frozen out of the collector's view.
GC_YOUNG_THRESHOLD = 50_000

# Command modules in fleetrun/commands, in the order `fleetrun --help` lists them.
COMMANDS = ("map", "cycles", "simulate", "run", "template", "validate", "diagnose", "import-epa",
            "import-registrations", "diagnose-fleet")


class FleetrunGroup(click.Group):
    """A click group that turns library errors into ``Error:`` lines with exit code 1."""

    def list_commands(self, ctx):
        return [name for name in COMMANDS if self._load(name) is not None]

    def get_command(self, ctx, name):
        return self._load(name)

    @staticmethod
    def _load(name):
        if name not in COMMANDS:
            return None
        try:
            module_name = f"fleetrun.commands.{name.replace('-', '_')}"
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name == module_name:
                return None  # command not part of this build
            raise
        return module.command

    def parse_args(self, ctx, args):
        ctx.meta["fleetrun.argv"] = list(args)  # to tell the user's paths from internal ones
        return super().parse_args(ctx, args)

    def invoke(self, ctx):
        streams = sys.stdout, sys.stderr
        sys.stdout, sys.stderr = Printable(sys.stdout), Printable(sys.stderr)
        try:
            with _sigterm_as_interrupt():
                return self._invoke(ctx)
        finally:
            sys.stdout, sys.stderr = streams

    def _invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt as exc:
            click.echo(f"Error: {interruption(exc)}; nothing more was written and the output folder "
                       "is as it was", err=True)
            ctx.exit(1)
        except FleetrunError as exc:
            click.echo(f"Error: {exc}", err=True)
            ctx.exit(1)
        except (click.ClickException, click.exceptions.Exit, click.Abort):
            raise
        except OSError as exc:
            if not _names_user_path(exc, ctx.meta.get("fleetrun.argv", ())):
                _internal_error(ctx)
            # the file system refused a path the user gave (missing, a folder, no permission):
            # a user mistake, so one Error line and exit 1, not a traceback
            where = exc.filename or ""
            click.echo(f"Error: {where}{': ' if where else ''}{exc.strerror or exc}. "
                       "Check the path and its permissions", err=True)
            ctx.exit(1)
        except Exception:  # a bug: its traceback in a log file, one Error line naming it
            _internal_error(ctx)


def _stop(signum, _frame):
    raise Terminated(signal.Signals(signum).name)


def _sigterm_as_interrupt():
    """SIGTERM and SIGHUP raise :class:`Terminated` (a KeyboardInterrupt) while a command runs, so
    a scheduler's kill or a closed ssh session stops it as Ctrl-C does: an ``Error:`` line, exit 1,
    the log told, the staging folder and lock removed (errors.signal_handlers: not where ignored)."""
    return signal_handlers([getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name)], _stop)


# C0 and C1 control characters but tab, newline and carriage return (the progress bar's), DEL,
# and the bidirectional overrides (which reorder what a terminal shows)
_UNPRINTABLE = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069]")


def printable(text: str) -> str:
    """``text`` with every control character shown as an escape (``\\x1b``)."""
    return _UNPRINTABLE.sub(lambda m: f"\\x{ord(m.group()):02x}" if ord(m.group()) < 256
                            else f"\\u{ord(m.group()):04x}", text)


class Printable:
    """A text stream that writes :func:`printable` text to ``stream`` (everything else is
    ``stream``'s: encoding, isatty, flush, ...)."""

    def __init__(self, stream):
        self._stream = stream

    def write(self, text):
        return self._stream.write(printable(text) if isinstance(text, str) else text)

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _names_user_path(exc: OSError, argv) -> bool:
    """Whether the failing path is one the user gave on the command line (or lies inside one)."""
    if not exc.filename:
        return False
    failing = Path(str(exc.filename)).absolute()
    for arg in argv:
        given = Path(str(arg).partition("=")[2] or str(arg)).absolute()
        if failing == given or given in failing.parents:
            return True
    return False


def _internal_error(ctx):
    kind, exc, _ = sys.exc_info()
    log_file = write_error_log(traceback.format_exc())
    click.echo(f"Error: internal error ({kind.__name__}: {exc}); the traceback is in {log_file}; "
               "please report it with that file", err=True)
    ctx.exit(EXIT_INTERNAL)


@click.group(cls=FleetrunGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="fleetrun")
def cli():
    """Differential efficiency, drive-cycle fuel and fleet fuel-tax forecasts (Vaughn 2012)."""


def main(argv=None):
    """Console-script entry point."""
    _collect_less(sys.argv[1:] if argv is None else argv)
    try:
        cli.main(args=argv, prog_name="fleetrun", standalone_mode=True)
    except KeyboardInterrupt:  # pragma: no cover - interactive only
        click.echo("Error: interrupted", err=True)
        sys.exit(1)


def _collect_less(argv) -> None:
    """This process's garbage collector set for a batch command: a larger young generation,
    and the command's modules (imported here first; click finds them loaded) moved to the
    permanent generation, which no collection walks again. Only the console entry point does
    this, not a program or test that imports the library."""
    gc.set_threshold(GC_YOUNG_THRESHOLD, *gc.get_threshold()[1:])
    name = next((arg for arg in argv if not str(arg).startswith("-")), None)
    if name in COMMANDS:
        try:
            FleetrunGroup._load(name)
        except Exception:   # noqa: BLE001 - click loads it again below and reports the failure as it does
            pass
    gc.freeze()
