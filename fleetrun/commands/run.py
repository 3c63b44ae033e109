"""``fleetrun run``: simulate a fleet workbook over its scenarios and write the budget reports.

    fleetrun run FLEET.xlsx [--out DIR] [--scenario ID]... [--engine local|dask] [--scheduler ADDR]
                 [--with EFFECT[,EFFECT...]]
    fleetrun run --config batch.toml

Writes report.xlsx, summary.html, results.csv, results.parquet, class_summary.csv,
fiscal_summary.csv and manifest.json into DIR, all or nothing; an earlier run there is kept in DIR/earlier-runs/
unless --replace. Exit codes: docs/batch.md (0 ok, 1 input error, 2 usage, 3 partial,
4 internal).
"""
from __future__ import annotations

from pathlib import Path

import click

from fleetrun.effects import parse_with
from fleetrun.errors import InputError, interrupted_outputs, interruption, unknown_name_error
from fleetrun.fileio import refuse_replacing_inputs
from fleetrun.reports.changes import KEEP_RUNS
from fleetrun.run import batch
from fleetrun.run.batch import read_config
from fleetrun.run.outputs import OUTPUT_FILES, REGISTRATION_FILES

from fleetrun.run.engines import ENGINES
from fleetrun.simulation.diffmodes import default_cache_dir

CONFIG_KEY = "fleetrun.run.config"
# batch.toml keys that are defaults of an option of the same meaning (click's default_map):
# an option given on the command line overrides the file
OPTION_OF_KEY = {"out": "out", "scenarios": "scenarios", "engine": "engine", "scheduler": "scheduler",
                 "physics": "physics", "mode": "mode", "cache_dir": "cache_dir", "log": "log_file",
                 "keep_runs": "keep_runs"}


def _load_config(ctx, config):
    """--config (read first): its keys become the options' defaults (``ctx.default_map``)."""
    if config is None:
        return None
    try:
        settings = read_config(config)
    except InputError as exc:   # raised after the usage checks (WORKBOOK and --config: exit 2)
        ctx.meta[CONFIG_KEY] = exc
        return config
    given = {option: getattr(settings, key) for key, option in OPTION_OF_KEY.items()}
    ctx.default_map = {**(ctx.default_map or {}),
                       **{option: value for option, value in given.items() if value is not None}}
    ctx.meta[CONFIG_KEY] = settings
    return config


@click.command("run")
@click.argument("workbook", required=False, type=click.Path(path_type=Path))
@click.option("--out", "out", type=click.Path(file_okay=False, path_type=Path),
              help="Output folder [default: ./run-<workbook name>].")
@click.option("--scenario", "scenarios", multiple=True, metavar="ID",
              help="Run only this scenario (repeatable) [default: all].")
@click.option("--engine", type=click.Choice(ENGINES), default=None, help="Where to simulate [local].")
@click.option("--scheduler", metavar="ADDRESS", default=None,
              help="Dask scheduler address (with --engine dask); none: a local cluster.")
@click.option("--config", "config", type=click.Path(dir_okay=False, path_type=Path), is_eager=True,
              callback=lambda ctx, _param, value: _load_config(ctx, value),
              help="Batch config (TOML): inputs, scenarios, out, engine, ... (docs/batch.md).")
@click.option("--physics", default=None, help="Physics baseline [thesis].")
@click.option("--mode", type=click.Choice(["auto", "direct", "map2d", "map3d"]), default=None,
              help="Simulation mode (thesis Ch. 6) [auto].")
@click.option("--with", "with_effects", metavar="EFFECT[,EFFECT...]", default=None,
              help="Add physics the thesis left out (docs/effects.md), e.g. bearing_preload:drag_torque_Nm=3,warmup "
                   "[batch: the config's 'with'].")
@click.option("--cache-dir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Where efficiency maps are cached between runs [$FLEETRUN_CACHE_DIR, else ~/.cache/fleetrun].")
@click.option("--no-cache", is_flag=True, help="Do not read or write cached maps.")
@click.option("--log", "log_file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Append log lines to this file [batch: <out>/fleetrun-run.log].")
@click.option("--replace", is_flag=True,
              help="Replace the run already in the output folder instead of keeping it in earlier-runs/.")
@click.option("--keep-runs", type=click.IntRange(min=0), default=None, metavar="N",
              help=f"Keep the newest N earlier runs in earlier-runs/, remove older ones [{KEEP_RUNS}; "
                   "batch: the config's 'keep_runs'].")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar, log lines or summary on stdout or stderr (errors still go to stderr).")
@click.pass_context
def command(ctx, workbook, out, scenarios, engine, scheduler, config, physics, mode, with_effects, cache_dir,
            no_cache, log_file, replace, keep_runs, quiet):
    """Simulate every vehicle type of WORKBOOK over each scenario's cycle mix and write
    report.xlsx, summary.html, results.csv, results.parquet, class_summary.csv, fiscal_summary.csv and
    manifest.json."""

    settings = ctx.meta.get(CONFIG_KEY)   # what the defaults (ctx.default_map) do not carry
    if config is not None and workbook is not None:
        raise click.UsageError("give either WORKBOOK or --config, not both")
    if config is None and workbook is None:
        raise click.UsageError("give a fleet WORKBOOK (or --config batch.toml)")
    if isinstance(settings, Exception):
        raise settings
    # a misspelt effect fails here, before any fleet is read
    if with_effects is not None:
        effects = parse_with(with_effects)
    else:
        effects = list(settings.effects or ()) if settings else []
    inputs = settings.inputs if settings else [workbook]
    batch_mode = config is not None
    out = out or Path(f"run-{Path(workbook).stem}")
    engine = engine or "local"
    if engine not in ENGINES:
        raise unknown_name_error("engine", engine, ENGINES, hint=f"Fix 'engine' in {config}.")
    if scheduler and engine != "dask":
        raise click.UsageError("--scheduler needs --engine dask")
    if no_cache:
        cache = None
    else:
        cache = cache_dir or default_cache_dir()
    if log_file is None and batch_mode:
        log_file = Path(out) / "fleetrun-run.log"
    if log_file is not None:
        refuse_replacing_inputs(log_file, [*inputs, config], "--log")
    plan = batch.RunPlan(inputs=list(inputs), out=Path(out), per_input_dirs=batch_mode,
                         scenarios=list(scenarios), engine=engine, scheduler=scheduler,
                         physics=physics or "thesis", mode=mode or "auto", effects=effects,
                         cache_dir=cache, log=log_file, chunk_size=settings.chunk_size if settings else None)
    plan.replace = replace
    plan.keep_runs = KEEP_RUNS if keep_runs is None else keep_runs
    # What a caller injects through click's context object (tests: a stand-in simulation, a
    # fixture error distribution); the command line itself never sets it.
    injected = ctx.obj or {}
    plan.simulate = injected.get("simulate")
    plan.error_model = injected.get("error_model", plan.error_model)
    handlers = batch.setup_logging(plan.log, quiet)
    try:
        code, errors, written = batch.run_plan(plan, quiet=quiet)
    except KeyboardInterrupt as stop:   # Ctrl-C or SIGTERM: said here with the log that records it
        click.echo(f"Error: {interruption(stop)}; {interrupted_outputs(stop, 'the output folder being written')}"
                   + (f" (logged in {plan.log})" if plan.log else ""), err=True)
        ctx.exit(1)
    finally:
        batch.teardown_logging(handlers)
    if not quiet:
        for item in written:
            warnings = len(item.result.warnings)
            note = f"; {warnings} warning(s), listed in summary.html and manifest.json" if warnings else ""
            files = OUTPUT_FILES + tuple(n for n in REGISTRATION_FILES if (item.out / n).exists())
            click.echo(f"Wrote {item.out}/: {', '.join(files)}{note}")
    if code == batch.EXIT_OK:
        return
    if len(errors) == 1 and len(plan.inputs) == 1:
        message = errors[0]
    else:
        failed = len(errors)
        message = (f"{failed} of {len(plan.inputs)} fleet workbooks failed"
                   + (f" (see {plan.log})" if plan.log else "") + ":\n" + "\n".join(errors))
    click.echo(f"Error: {message}", err=True)
    ctx.exit(code)
