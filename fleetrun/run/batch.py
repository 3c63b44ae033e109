"""Unattended runs: the ``batch.toml`` file, the log, progress reporting and exit codes.

Exit codes (docs/batch.md), for a scheduler to act on:

====  =====================================================================================
0     every fleet's five outputs were written
1     bad input or a domain error; nothing was written for the failing fleet (every fleet,
      for a batch)
2     usage error (command line)
3     partial failure: some fleets of a batch were written, others failed (see the log)
4     internal error (a bug): nothing written for that fleet; the traceback is in the log
====  =====================================================================================
"""
from __future__ import annotations

import glob
import logging
import os
import sys
import time
import tomllib
import traceback
from dataclasses import dataclass, field, replace
from pathlib import Path

import click

from fleetrun.budget.result import RunResult
from fleetrun.effects import parse_with
from fleetrun.errors import FleetrunError, InputError, interrupted_outputs, interruption
from fleetrun.fileio import EARLIER_IMPORTS, why_not_writable, write_error_log
from fleetrun.reports.changes import EARLIER_DIR, KEEP_RUNS, EarlierRun, compare, describe, read_earlier, scenario_totals_dict
from fleetrun.reports.manifest import manifest_dict
from fleetrun.run.engines import make_engine
from fleetrun.output_folder import folder_lock
from fleetrun.run.outputs import refuse_foreign_outputs, refuse_overwriting_inputs, write_run_outputs
from fleetrun.run.runner import CHUNK_SIZE, run_fleet
from fleetrun.workbook.reader import read_fleet
from fleetrun.workbook.xlsx_safety import is_office_lock_file

EXIT_OK, EXIT_INPUT, EXIT_USAGE, EXIT_PARTIAL, EXIT_INTERNAL = 0, 1, 2, 3, 4

CONFIG_KEYS = {"inputs", "scenarios", "out", "engine", "scheduler", "physics", "mode", "with", "cache_dir",
               "log", "chunk_size", "keep_runs"}

log = logging.getLogger("fleetrun.run")


@dataclass
class RunPlan:
    """One invocation of ``fleetrun run``: which fleets, where to, and how."""
    inputs: list[Path]
    out: Path
    per_input_dirs: bool                  # batch: out/<stem>/ per fleet; single: out itself
    scenarios: list[str] = field(default_factory=list)
    engine: str = "local"
    scheduler: str | None = None
    physics: str = "thesis"
    mode: str = "auto"
    effects: list = field(default_factory=list)   # --with: (Effect, params) pairs from parse_with
    cache_dir: Path | None = None
    log: Path | None = None
    chunk_size: int | None = None
    simulate: object = None               # the simulation function (None: fleetrun.simulation.simulate)
    replace: bool = False                 # --replace: do not keep the earlier run in earlier-runs/
    keep_runs: int = KEEP_RUNS            # --keep-runs: earlier runs kept in earlier-runs/, the oldest removed
    error_model: object = "default"       # measured fuel-economy error (run_fleet's error_model)

    def out_dir(self, fleet_path: Path) -> Path:
        if not self.per_input_dirs:
            return self.out
        return self.out / output_names(self.inputs).get(Path(fleet_path), Path(fleet_path).stem)


def output_names(inputs) -> dict[Path, str]:
    """A distinct output folder name per input of a batch: the workbook's name without its
    extension, or, where two inputs share it (``north/fleet.xlsx``, ``south/fleet.xlsx``), that
    name prefixed with as many parent folders as tell them apart (``north-fleet``,
    ``south-fleet``), else with its extension (``fleet-xlsm``), else numbered. Compared without
    case, as file systems on Windows and macOS do."""
    paths = [Path(p) for p in dict.fromkeys(inputs)]
    names = {p: p.stem for p in paths}
    for group in _clashes(names):
        names.update(_tell_apart(group))
    for group in _clashes(names):      # a new name met an existing one: number them
        names.update({p: f"{names[p]}-{i}" for i, p in enumerate(group, start=1)})
    return names


def _tell_apart(group: list[Path]) -> dict[Path, str]:
    parents = {p: Path(os.path.abspath(p)).parent.parts[1:] for p in group}
    for depth in range(1, max(len(v) for v in parents.values()) + 1):
        names = {p: "-".join([*parents[p][-depth:], p.stem]) for p in group}
        if len({n.casefold() for n in names.values()}) == len(group):
            return names
    names = {p: p.name.replace(".", "-") for p in group}
    if len({n.casefold() for n in names.values()}) == len(group):
        return names
    return {p: f"{p.stem}-{i}" for i, p in enumerate(group, start=1)}


def _clashes(names: dict[Path, str]) -> list[list[Path]]:
    seen: dict[str, list[Path]] = {}
    for path, name in names.items():
        seen.setdefault(name.casefold(), []).append(path)
    return [group for group in seen.values() if len(group) > 1]


@dataclass(frozen=True)
class BatchConfig:
    """``batch.toml``'s checked values (docs/batch.md); paths resolved against the file's
    folder. None: the key was not in the file (the command line's option or default holds)."""
    inputs: tuple[Path, ...]
    out: Path
    scenarios: tuple[str, ...] = ()
    cache_dir: Path | None = None
    log: Path | None = None
    engine: str | None = None
    scheduler: str | None = None
    physics: str | None = None
    mode: str | None = None
    effects: tuple | None = None        # 'with': (Effect, params) pairs from parse_with
    chunk_size: int | None = None
    keep_runs: int | None = None


@dataclass(frozen=True)
class FleetWritten:
    """One fleet of a run, written: its workbook, output folder, files and result."""
    fleet: Path
    out: Path
    outputs: dict[str, Path]
    result: RunResult


def _not_a_fleet(path: Path) -> bool:
    """A file a glob of workbooks meets that is no fleet: an Office lock file, a run's own
    report.xlsx (beside the manifest.json that lists it), or a copy fleetrun kept (a workbook an
    import replaced, an earlier run's outputs)."""
    return (is_office_lock_file(path) or (path.name == "report.xlsx" and (path.parent / "manifest.json").is_file())
            or bool({EARLIER_IMPORTS, EARLIER_DIR} & set(path.parts[:-1])))


def read_config(path: Path) -> BatchConfig:
    """``batch.toml`` as checked values; paths resolved against the file's folder."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError("batch config not found", file=path, hint="Check the --config path.") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"is not valid TOML ({exc})", file=path) from None
    if isinstance(data.get("run"), dict):   # a [run] table is accepted too
        data = {**{k: v for k, v in data.items() if k != "run"}, **data["run"]}
    unknown = sorted(set(data) - CONFIG_KEYS)
    if unknown:
        raise InputError(f"unknown key(s) {', '.join(unknown)}; valid: {', '.join(sorted(CONFIG_KEYS))}",
                         file=path)
    base = path.resolve().parent
    inputs = data.get("inputs")
    if isinstance(inputs, str):
        inputs = [inputs]
    if not inputs or not all(isinstance(i, str) for i in inputs):
        raise InputError("'inputs' must list the fleet workbooks (paths or globs)", file=path,
                         hint='e.g. inputs = ["fleets/*.xlsx"]')
    found: list[Path] = []
    for pattern in inputs:
        full = pattern if os.path.isabs(pattern) else str(base / pattern)
        # a glob skips the lock files Excel keeps beside open workbooks (~$fleet.xlsx), and the
        # reports of earlier runs (out beside the fleets): a nightly batch must not fail on them
        matches = sorted(m for m in glob.glob(full) if not _not_a_fleet(Path(m))) \
            if glob.has_magic(full) else [full]
        if not matches:
            raise InputError(f"'inputs' pattern '{pattern}' matches no file", file=path)
        found.extend(Path(m) for m in matches)
    config = {"inputs": tuple(dict.fromkeys(found))}
    scenarios = data.get("scenarios", [])
    if isinstance(scenarios, str):
        scenarios = [scenarios]
    if not isinstance(scenarios, list) or not all(isinstance(s, str) for s in scenarios):
        raise InputError("'scenarios' must be a list of scenario ids", file=path)
    config["scenarios"] = tuple(scenarios)
    for key in ("out", "cache_dir", "log"):
        if key in data:
            if not isinstance(data[key], str):
                raise InputError(f"'{key}' must be a path (a string)", file=path)
            value = Path(data[key]).expanduser()
            config[key] = value if value.is_absolute() else base / value
            if config[key].is_dir() == (key == "log") and config[key].exists():
                raise InputError(f"{config[key]} is {'a folder' if key == 'log' else 'a file'}",
                                 file=path, column=key, hint=f"Give a {'file' if key == 'log' else 'folder'} path")
    config.setdefault("out", base / "results")   # relative to this file, as every path in it
    for key in ("engine", "scheduler", "physics", "mode"):
        if key in data:
            if not isinstance(data[key], str):
                raise InputError(f"'{key}' must be a string", file=path)
            config[key] = data[key]
    if "with" in data:   # the --with effects: "a,b:p=1" or ["a", "b:p=1"]
        value = data["with"]
        if isinstance(value, str):
            value = [value]
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise InputError("'with' must be a string or a list of strings of effects, e.g. "
                             "'bearing_preload:drag_torque_Nm=3,warmup'", file=path)

        try:
            config["effects"] = tuple(pair for item in value for pair in parse_with(item))
        except InputError as exc:
            exc.file = exc.file or path
            raise
    if "chunk_size" in data:
        if type(data["chunk_size"]) is not int or data["chunk_size"] < 1:   # true is no size
            raise InputError("'chunk_size' must be a positive whole number", file=path)
        config["chunk_size"] = data["chunk_size"]
    if "keep_runs" in data:
        if type(data["keep_runs"]) is not int or data["keep_runs"] < 0:
            raise InputError("'keep_runs' must be a whole number, 0 or more (earlier runs kept in "
                             f"earlier-runs/; default {KEEP_RUNS})", file=path)
        config["keep_runs"] = data["keep_runs"]
    return BatchConfig(**config)


class Progress:
    """A progress bar on a terminal (``click.progressbar``: bar, count, time left); plain log
    lines (every 10 %) otherwise."""

    def __init__(self, label: str, stream=None, enabled: bool = True):
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = enabled and hasattr(self.stream, "isatty") and self.stream.isatty()
        self._last_decile = -1
        self._bar = None

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled or total <= 0:
            return
        if self.tty:
            if self._bar is None:
                self._bar = click.progressbar(length=total, label=self.label, file=self.stream, show_pos=True,
                                              item_show_func=lambda _: "simulation tasks")
                self._bar.__enter__()
            self._bar.update(done - self._bar.pos)
            if done >= total:
                self._bar.__exit__(None, None, None)
            return
        fraction = done / total
        decile = int(fraction * 10)
        if decile != self._last_decile:
            self._last_decile = decile
            log.info("%s: %d/%d simulation tasks (%d %%)", self.label, done, total, int(fraction * 100))


def setup_logging(log_file: Path | None, quiet: bool) -> list[logging.Handler]:
    """Log lines to the file (if any) and, unless quiet, to stdout when stderr is not a
    terminal (a terminal gets the progress bar instead). Not stderr: there a failed run leaves
    exactly one message, the ``Error:`` line."""
    handlers: list[logging.Handler] = []
    formatter = logging.Formatter("%(asctime)s %(levelname)s %(message)s", "%Y-%m-%dT%H:%M:%S")
    formatter.converter = time.gmtime
    if log_file is not None:
        handler = _log_handler(Path(log_file))
        handler.setFormatter(formatter)
        handlers.append(handler)
    if not quiet and not sys.stderr.isatty():
        handler = logging.StreamHandler(sys.stdout)
        handler.setFormatter(formatter)
        # Errors are the command's "Error: ..." message on stderr; not repeated here.
        handler.addFilter(lambda record: record.levelno < logging.ERROR)
        handlers.append(handler)
    handlers.append(logging.NullHandler())   # no "last resort" echo of records to stderr
    for handler in handlers:
        log.addHandler(handler)
    log.setLevel(logging.INFO)
    log.propagate = False
    return handlers


def _log_handler(log_file: Path) -> logging.Handler:
    """A handler appending to ``log_file``, or InputError naming it (a folder, no permission,
    disk full): the user's to fix, exit 1."""
    if log_file.is_dir():
        raise InputError(f"{log_file}: --log names a folder", hint="Give a file name for the log (--log)")
    try:
        log_file.parent.mkdir(parents=True, exist_ok=True)
        return logging.FileHandler(log_file, encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{log_file}: cannot write the log ({why_not_writable(log_file, exc)})",
                         hint="Choose a log file in a folder you can write to (--log)") from None


def teardown_logging(handlers) -> None:
    for handler in handlers:
        log.removeHandler(handler)
        handler.close()


def run_one(plan: RunPlan, fleet_path: Path, engine, progress_enabled: bool) -> FleetWritten:
    """Read, simulate and write one fleet; raises on failure (nothing written then)."""

    started = time.perf_counter()
    fleet = read_fleet(fleet_path)
    read_s = time.perf_counter() - started
    out_dir = plan.out_dir(fleet_path)
    refuse_overwriting_inputs(out_dir, [fleet_path, *fleet.input_files()])
    for warning in fleet.warnings:
        log.warning("%s: %s", fleet_path.name, warning)
    log.info("%s: %d vehicle types, %d registration rows, %d scenarios; engine %s", fleet_path.name,
             len(fleet.vehicles), len(fleet.registrations), len(plan.scenarios) or len(fleet.scenarios), plan.engine)
    result = run_fleet(fleet, plan.scenarios, engine=engine, physics=plan.physics, mode=plan.mode,
                       effects=plan.effects, cache_dir=str(plan.cache_dir) if plan.cache_dir else None,
                       progress=Progress(fleet_path.name, enabled=progress_enabled),
                       chunk_size=plan.chunk_size or CHUNK_SIZE, simulate=plan.simulate,
                       error_model=plan.error_model)
    result = replace(result, timings_s={"read": read_s, **result.timings_s})
    written_at = time.perf_counter()
    with folder_lock(out_dir):   # one run at a time compares with and replaces the folder
        refuse_foreign_outputs(out_dir)
        result, earlier = _what_changed(result, out_dir, fleet_path)
        outputs = write_run_outputs(result, out_dir, earlier=None if plan.replace else earlier,
                                    keep_runs=plan.keep_runs)
    if earlier is not None and not plan.replace:
        log.info("%s: the earlier run is kept in %s", fleet_path.name, out_dir / "earlier-runs")
    log.info("%s: wrote %s (read %.1f s, simulate %.1f s, write %.1f s)", fleet_path.name, out_dir,
             read_s, result.timings_s["simulate"], time.perf_counter() - written_at)
    return FleetWritten(fleet=fleet_path, out=out_dir, outputs=outputs, result=result)


def _what_changed(result: RunResult, out_dir: Path, fleet_path: Path) -> tuple[RunResult, EarlierRun | None]:
    """Compare with the run already in ``out_dir`` (inputs' sha256, totals by scenario): the
    result with the comparison on ``changes`` (logged), and the earlier manifest (None: no
    earlier run)."""

    earlier = read_earlier(out_dir)
    if earlier is None:
        return result, None
    now = manifest_dict(result)
    result = replace(result, changes=compare(earlier, now["inputs"], scenario_totals_dict(result.classes),
                                             now["attribution"]))
    for line in describe(result.changes):
        log.info("%s: %s", fleet_path.name, line)
    return result, earlier


def _earlier_outputs_note(out_dir: Path) -> str:
    """After a failed run: a line saying that ``out_dir`` still holds an earlier run (when it
    does), so that nobody takes its outputs for this run's."""
    earlier = read_earlier(out_dir)
    if earlier is None:
        return ""
    return (f"\n{out_dir} still holds the outputs of the earlier run of {earlier.manifest.get('created_utc', '?')}, "
            "not of this run")


def run_plan(plan: RunPlan, *, quiet: bool = False) -> tuple[int, list[str], list[FleetWritten]]:
    """Run every fleet in the plan; return (exit code, error lines, what was written)."""
    errors: list[str] = []
    internal = False
    written: list[FleetWritten] = []
    engine = make_engine(plan.engine, plan.scheduler)   # InputError here: nothing to run
    try:
        for fleet_path in plan.inputs:
            try:
                written.append(run_one(plan, fleet_path, engine, progress_enabled=not quiet))
            except KeyboardInterrupt as stop:   # the log of a cron job says why it ends here
                log.error("%s: %s; %s", fleet_path, interruption(stop),
                          interrupted_outputs(stop, str(plan.out_dir(fleet_path))))
                raise
            except FleetrunError as exc:
                errors.append(str(exc) + _earlier_outputs_note(plan.out_dir(fleet_path)))
                log.error("%s", errors[-1])
            except Exception as exc:  # a bug: keep going with the other fleets, keep the traceback
                internal = True
                trace = traceback.format_exc()
                log.error("%s: internal error\n%s", fleet_path, trace)
                where = plan.log if plan.log else write_error_log(f"{fleet_path}: internal error\n{trace}")
                errors.append(f"{fleet_path}: internal error ({type(exc).__name__}: {exc}); "
                              f"the traceback is in {where}; please report it with that file")
    finally:
        engine.close()
    if not errors:
        return EXIT_OK, [], written
    if written:
        return EXIT_PARTIAL, errors, written
    return (EXIT_INTERNAL if internal else EXIT_INPUT), errors, written
