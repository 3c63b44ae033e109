"""``fleetrun run``: simulate a fleet workbook over its scenarios and write the budget reports.

    fleetrun run FLEET.xlsx [--out DIR] [--scenario ID]... [--engine local|dask] [--scheduler ADDR]
                 [--with EFFECT[,EFFECT...]]
    fleetrun run --config batch.toml

Writes report.xlsx, summary.html, results.csv, class_summary.csv, fiscal_summary.csv and
manifest.json into DIR, all or nothing; an earlier run there is kept in DIR/earlier-runs/
unless --replace. Exit codes: docs/batch.md (0 ok, 1 input error, 2 usage, 3 partial,
4 internal).
"""
from __future__ import annotations

from pathlib import Path

import click

from fleetrun.run.outputs import OUTPUT_FILES

from fleetrun.run.engines import ENGINES


@click.command("run")
@click.argument("workbook", required=False, type=click.Path(path_type=Path))
@click.option("--out", "out", type=click.Path(file_okay=False, path_type=Path),
              help="Output folder [default: ./run-<workbook name>].")
@click.option("--scenario", "scenarios", multiple=True, metavar="ID",
              help="Run only this scenario (repeatable) [default: all].")
@click.option("--engine", type=click.Choice(ENGINES), default=None, help="Where to simulate [local].")
@click.option("--scheduler", metavar="ADDRESS", default=None,
              help="Dask scheduler address (with --engine dask); none: a local cluster.")
@click.option("--config", "config", type=click.Path(dir_okay=False, path_type=Path),
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
@click.option("-q", "--quiet", is_flag=True, help="No progress bar, log lines or summary on stdout or stderr (errors still go to stderr).")
@click.pass_context
def command(ctx, workbook, out, scenarios, engine, scheduler, config, physics, mode, with_effects, cache_dir,
            no_cache, log_file, replace, quiet):
    """Simulate every vehicle type of WORKBOOK over each scenario's cycle mix and write
    report.xlsx, summary.html, results.csv, class_summary.csv, fiscal_summary.csv and manifest.json."""
    from fleetrun.effects import parse_with
    from fleetrun.run import batch

    settings: dict = {}
    if config is not None:
        if workbook is not None:
            raise click.UsageError("give either WORKBOOK or --config, not both")
        settings = batch.read_config(config)
    elif workbook is None:
        raise click.UsageError("give a fleet WORKBOOK (or --config batch.toml)")
    # a misspelt effect fails here, before any fleet is read
    effects = parse_with(with_effects) if with_effects is not None else settings.get("with", [])
    inputs = settings.get("inputs") or [workbook]
    batch_mode = config is not None
    out = out or settings.get("out") or (Path("results") if batch_mode else Path(f"run-{Path(workbook).stem}"))
    engine = engine or settings.get("engine", "local")
    if engine not in ENGINES:
        from fleetrun.errors import unknown_name_error

        raise unknown_name_error("engine", engine, ENGINES, hint=f"Fix 'engine' in {config}.")
    scheduler = scheduler or settings.get("scheduler")
    if scheduler and engine != "dask":
        raise click.UsageError("--scheduler needs --engine dask")
    if no_cache:
        cache = None
    else:
        from fleetrun.simulation.diffmodes import default_cache_dir

        cache = cache_dir or settings.get("cache_dir") or default_cache_dir()
    if log_file is None:
        log_file = settings.get("log") or (Path(out) / "fleetrun-run.log" if batch_mode else None)
    plan = batch.RunPlan(inputs=list(inputs), out=Path(out), per_input_dirs=batch_mode,
                         scenarios=list(scenarios) or settings.get("scenarios", []), engine=engine,
                         scheduler=scheduler, physics=physics or settings.get("physics", "thesis"),
                         mode=mode or settings.get("mode", "auto"), effects=effects, cache_dir=cache,
                         log=log_file, chunk_size=settings.get("chunk_size"))
    plan.replace = replace
    # What a caller injects through click's context object (tests: a stand-in simulation, a
    # fixture error distribution); the command line itself never sets it.
    injected = ctx.obj or {}
    plan.simulate = injected.get("simulate")
    plan.error_model = injected.get("error_model", plan.error_model)
    handlers = batch.setup_logging(plan.log, quiet)
    try:
        code, errors, written = batch.run_plan(plan, quiet=quiet)
    finally:
        batch.teardown_logging(handlers)
    if not quiet:
        for item in written:
            note = (f"; {item['warnings']} warning(s), listed in summary.html and manifest.json"
                    if item["warnings"] else "")
            click.echo(f"Wrote {item['out']}/: {', '.join(OUTPUT_FILES)}{note}")
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
