"""The ``fleetrun`` command line: a thin layer over the library.

Each command lives in ``fleetrun/commands/<name>.py`` and exposes ``command``. Library errors
(:class:`fleetrun.errors.FleetrunError`) become one ``Error: ...`` line and exit code 1.
"""
from __future__ import annotations

import importlib
import sys

import click

from fleetrun import __version__
from fleetrun.errors import FleetrunError

# Command modules in fleetrun/commands, in the order `fleetrun --help` lists them.
COMMANDS = ("map", "cycles", "simulate", "run", "template", "validate", "diagnose", "import-epa",
            "diagnose-fleet")


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

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except FleetrunError as exc:
            click.echo(f"Error: {exc}", err=True)
            ctx.exit(1)
        except OSError as exc:
            # the file system refused a path the user gave (missing, a folder, no permission):
            # a user mistake, so one Error line and exit 1, not a traceback
            where = exc.filename or ""
            click.echo(f"Error: {where}{': ' if where else ''}{exc.strerror or exc}. "
                       "Check the path and its permissions", err=True)
            ctx.exit(1)


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
