"""The ``fleetrun`` command line: a thin layer over the library.

Each command lives in ``fleetrun/commands/<name>.py`` and exposes ``command``. Library errors
(:class:`fleetrun.errors.FleetrunError`) and the file system refusing a path the user gave
become one ``Error: ...`` line and exit code 1. Anything else is an internal error (a bug):
its traceback goes to a log file (:func:`fleetrun.fileio.write_error_log`) that the one
``Error:`` line names, exit code 4 (as ``fleetrun run``, docs/batch.md).
"""
from __future__ import annotations

import importlib
import sys
import traceback
from pathlib import Path

import click

from fleetrun import __version__
from fleetrun.errors import FleetrunError

EXIT_INTERNAL = 4

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
        try:
            return super().invoke(ctx)
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
    from fleetrun.fileio import write_error_log

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
    try:
        cli.main(args=argv, prog_name="fleetrun", standalone_mode=True)
    except KeyboardInterrupt:  # pragma: no cover - interactive only
        click.echo("Error: interrupted", err=True)
        sys.exit(1)
