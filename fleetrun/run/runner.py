"""Simulate a fleet over its scenarios and aggregate fuel, efficiency and fuel-tax revenue.

Every vehicle type is simulated once per distinct (drive cycle, ambient temperature) that the
chosen scenarios use, in chunks of vehicles (the unit of work for both engines). The budget
arithmetic (on-road fuel, mixes, budget years, taxes, calibration, fiscal years, ranges) is
in :mod:`fleetrun.budget.totals` and :mod:`fleetrun.budget.arithmetic` (also docs/report.md).

``diff_efficiency`` = differential output energy / input energy and ``drivetrain_efficiency``
= wheel energy / drivetrain input energy, both summed over the mix's miles (energy-weighted).
"""
from __future__ import annotations

import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from fleetrun.budget import periods
from fleetrun.budget.result import AppliedEffect, CycleInfo, EfficiencyMap, RunResult
from fleetrun.budget.totals import (CLASS_COLUMNS, ENERGY_FIELDS, RESULTS_COLUMNS, aggregate_classes,
                                   aggregate_vehicles, change_decomposition, fiscal_summary)
from fleetrun.budget.uncertainty import read_error_model
from fleetrun.cycles import load_cycle
from fleetrun.differential import efficiency
from fleetrun.effects import as_effect_list, efficiency_with_effects
from fleetrun.errors import DomainError, InputError
from fleetrun.resources import inputs_dir
from fleetrun.run.engines import LocalEngine
from fleetrun.simulation import DEFAULT_MODE
from fleetrun.simulation import simulate as simulate_vehicles
from fleetrun.simulation.diffmodes import GEAR_GRID, outside_map3d_grid
from fleetrun.simulation.electric import simulate_electric
from fleetrun.vehicle import VehicleSpec
from fleetrun.workbook.reader import Fleet, file_sha256
from fleetrun.workbook.schema import DUTY_CLASSES

__all__ = ["run_fleet", "RunResult", "SimulationTask", "simulate_task", "CycleSums", "RESULTS_COLUMNS", "CLASS_COLUMNS"]

CHUNK_SIZE = 128            # vehicles per simulation task: bounds memory, spreads work
MAX_LISTED_WARNINGS = 50    # per kind; the rest are counted
SHORTFALL_TOLERANCE = 1e-6  # shortfall measures below this are rounding noise
RESULT_FIELDS = ("miles", "fuel_gal") + ENERGY_FIELDS
ELECTRIC = "electric"
Condition = tuple[str, float]   # a simulated condition: (drive cycle name, ambient temperature C)


@dataclass(frozen=True)
class SimulationTask:
    """A chunk of vehicles at one temperature over the cycles they drive there.

    Vehicles in a chunk mostly share their differentials (the fleet is sorted by them), and
    one task does every cycle at that temperature, so a worker builds each efficiency map once.
    """
    chunk: int
    vehicles: tuple[VehicleSpec, ...]
    cycles: tuple[tuple[str, tuple[int, ...]], ...]   # (cycle, indices into vehicles) pairs
    ambient_temp_C: float
    physics: str
    mode: str
    cache_dir: str | None
    simulate: Callable | None = None   # None: fleetrun.simulation.simulate
    effects: tuple = ()                # --with: (effect id, params) pairs, plain data for any worker


@lru_cache(maxsize=32)
def _cycle(name: str):
    return load_cycle(name)


@dataclass(frozen=True)
class CycleSums:
    """One task's per-vehicle results over one cycle, what travels back from a worker:
    ``sums`` the RESULT_FIELDS (miles, fuel_gal, the energies), ``shortfalls`` the measures of
    how far the vehicles fell behind the trace (``shortfall_*``, those the simulation reports)."""
    sums: dict[str, np.ndarray]
    shortfalls: dict[str, np.ndarray]


def simulate_task(task: SimulationTask) -> dict[str, CycleSums]:
    """Run one chunk over its cycles: cycle -> per-vehicle sums (only these travel back)."""
    simulate = task.simulate or simulate_vehicles
    kwargs = {"ambient_temp_C": task.ambient_temp_C, "physics": task.physics, "mode": task.mode}
    if task.cache_dir:
        kwargs["cache_dir"] = task.cache_dir
    if task.effects:
        kwargs["effects"] = [(effect, dict(params)) for effect, params in task.effects]
    found = {}
    for cycle, members in task.cycles:
        result = simulate([task.vehicles[k] for k in members], _cycle(cycle), **kwargs)
        sums = {name: np.asarray(getattr(result, name), dtype=float) for name in RESULT_FIELDS}
        shortfalls = {}
        for name in dir(result):
            if name.startswith("shortfall_"):
                value = getattr(result, name)
                if isinstance(value, (np.ndarray, list, tuple)):
                    shortfalls[name] = np.asarray(value, dtype=float)
        found[cycle] = CycleSums(sums=sums, shortfalls=shortfalls)
    return found


def run_fleet(fleet: Fleet, scenario_ids: Sequence[str] = (), *, engine=None, physics: str = "thesis",
              mode: str = "auto", cache_dir: str | None = None,
              progress: Callable[[int, int], None] | None = None,
              chunk_size: int = CHUNK_SIZE, effects=(), simulate: Callable | None = None,
              error_model="default") -> RunResult:
    """Simulate ``fleet`` for the scenarios named (all when none) and aggregate the results.

    ``effects``: physics the thesis left out (``--with``; a string or ``parse_with`` pairs),
    applied in every simulation (each cycle of a mix is driven from a cold start).
    ``simulate``: the simulation function (default ``fleetrun.simulation.simulate``; tests pass
    a stand-in). ``error_model``: the measured fuel-economy error behind the ranges
    (:func:`fleetrun.budget.uncertainty.read_error_model`; ``"default"`` reads models/, None: no ranges).
    """

    started = time.perf_counter()
    effect_pairs = tuple((e.id, tuple(sorted(p.items()))) for e, p in as_effect_list(effects))
    scenarios = [fleet.scenario(s) for s in dict.fromkeys(scenario_ids)] if scenario_ids else list(fleet.scenarios)
    engine = engine or LocalEngine()
    vehicles, years, registrations = registration_vehicles(fleet, scenarios)
    if not vehicles:   # the reader refuses this first (reader._check_something_to_forecast)
        raise InputError("the fleet has no vehicles to forecast (nothing represents its registrations)",
                         file=fleet.path, hint="Give the fleet's counts")
    # Rows that differ only in id, class, count or miles drive the same: simulate each
    # distinct physical vehicle once and hand its per-vehicle results to every such row.
    distinct, owner = distinct_vehicles(vehicles)
    needed = needed_conditions(scenarios)
    conditions = list(needed)
    template = SimulationTask(chunk=0, vehicles=(), cycles=(), ambient_temp_C=0.0, physics=physics, mode=mode,
                              cache_dir=cache_dir, simulate=simulate, effects=effect_pairs)
    tasks, positions = plan_tasks(distinct, needed, template, chunk_size)
    per_condition, shortfalls = collect(engine, tasks, positions, conditions, len(distinct), progress)
    refuse_non_finite(fleet, tasks, positions, per_condition)
    electric_sums(distinct, needed, per_condition)
    simulated = time.perf_counter()
    per_condition = {cond: {name: values[owner] for name, values in arrays.items()}
                     for cond, arrays in per_condition.items()}
    shortfalls = {cond: {name: values[owner] for name, values in arrays.items()}
                  for cond, arrays in shortfalls.items()}

    if registrations:
        shortfall_lines = _library_shortfalls(_shortfall_warnings(vehicles, shortfalls, listed=None))
    else:
        shortfall_lines = _shortfall_warnings(vehicles, shortfalls)
    warnings = list(fleet.warnings) + (registrations.warnings if registrations else []) \
        + _map_grid_notes(fleet, mode) + shortfall_lines
    cycles = _cycle_info({cycle for cycle, _ in conditions})
    if error_model == "default":
        error_model = read_error_model()
    if error_model is None:
        warnings.append("ranges hold the drivers only, no model error: no measured fleet error "
                        "(models/fleet_error.toml) in this installation")
    budget = aggregate_vehicles(vehicles, scenarios, per_condition, error_model, years)
    results, calibration = budget.results, budget.calibration
    warnings += budget.warnings
    classes = aggregate_classes(results)
    fiscal = fiscal_summary(results, scenarios, budget.yearly)
    memo = periods.memo_table(fiscal, budget.ranges)
    maps, map_warnings = efficiency_maps(vehicles, physics, effect_pairs)
    warnings += map_warnings
    finished = time.perf_counter()
    return RunResult(
        fleet=fleet, scenarios=scenarios, results=results, classes=classes, fiscal=fiscal,
        calibration=calibration, error_model=error_model, tornado=budget.tornado, ranges=budget.ranges, period_ranges=budget.period_ranges,
        memo=memo, periods=periods.period_rows(memo, scenarios),
        cycles=cycles, maps=maps, warnings=warnings,
        timings_s={"simulate": simulated - started, "aggregate": finished - simulated},
        distinct_vehicles=len(distinct),
        engine=engine.describe(), physics=physics, mode=mode,
        cycle_inputs={info.path: info.sha256 for info in cycles.values() if info.path},
        effects=[AppliedEffect(e.id, e.level, dict(p)) for e, p in as_effect_list(effect_pairs)],
        registrations=registrations.choices if registrations else None,
        turnover=change_decomposition(fiscal) if registrations else None,
    )


def registration_vehicles(fleet: Fleet, scenarios) -> tuple[list, object, object]:
    """The fleet's rows to simulate: its Vehicles rows, then the cohorts of its Registrations
    (:mod:`fleetrun.registrations`), with their miles by year (None without registrations)."""
    if not fleet.registrations:   # most fleets: the registrations package is not even imported
        return fleet.vehicles, None, None
    from fleetrun.registrations import expand
    from fleetrun.registrations.expand import FleetYears

    expansion = expand(fleet, scenarios)
    if expansion is None:
        return fleet.vehicles, None, None
    return list(fleet.vehicles) + expansion.vehicles, FleetYears(fleet.vehicles, expansion), expansion


def refuse_non_finite(fleet: Fleet, tasks, positions, per_condition) -> None:
    """DomainError naming the Vehicles row of the first simulated vehicle whose cycle sums are
    not finite numbers (or whose miles are not positive): no inf or NaN reaches an output."""
    for index, task in enumerate(tasks):
        for cycle, members in task.cycles:
            arrays = per_condition[(cycle, task.ambient_temp_C)]
            where = positions[index][list(members)]
            for name in RESULT_FIELDS:
                values = arrays[name][where]
                bad = ~np.isfinite(values) | ((values <= 0) if name == "miles" else False)
                if bad.any():
                    vehicle = task.vehicles[members[int(np.flatnonzero(bad)[0])]]
                    row = fleet.vehicle_rows.get(vehicle.vehicle_id)
                    where_text = f"Vehicles!row {row}" if row else "Vehicles"
                    raise DomainError(f"{where_text} vehicle_id {vehicle.vehicle_id!r}: the simulation over "
                                      f"{_cycle_label(cycle)} at {task.ambient_temp_C:g} C gives {name} = "
                                      f"{float(values[bad][0])!r}, not a usable number", file=fleet.path,
                                      hint="Check this vehicle's engine and gearing values (units?); "
                                           "`fleetrun simulate` shows the trace")


def needed_conditions(scenarios) -> dict[Condition, set[str]]:
    """Each distinct (cycle, ambient) the scenarios use, with the duty classes that drive it:
    simulated once, for those vehicles only."""
    needed: dict[Condition, set[str]] = {}
    for s in scenarios:
        for duty in DUTY_CLASSES:
            for cycle in s.mix_for(duty):
                needed.setdefault((cycle, s.ambient_temp_C), set()).add(duty)
    return needed


def plan_tasks(distinct, needed: dict[Condition, set[str]], template: SimulationTask,
               chunk_size: int) -> tuple[list[SimulationTask], list[np.ndarray]]:
    """Chunks of vehicles per temperature, each with the cycles its members drive there, and
    each chunk's positions among ``distinct``. ``template`` carries the shared settings."""
    conditions = list(needed)
    duties = np.array([v.duty_class for v in distinct], dtype=object)
    duties[[v.fuel == ELECTRIC for v in distinct]] = None   # electric_sums drives those
    tasks: list[SimulationTask] = []
    positions: list[np.ndarray] = []
    for ambient in dict.fromkeys(a for _, a in conditions):
        cycles_here = [c for c, a in conditions if a == ambient]
        members = np.flatnonzero(np.isin(duties, sorted(set().union(*(needed[(c, ambient)] for c in cycles_here)))))
        for start in range(0, len(members), chunk_size):
            chunk = members[start:start + chunk_size]
            cycles = []
            for cycle in cycles_here:
                wanted = np.flatnonzero(np.isin(duties[chunk], sorted(needed[(cycle, ambient)])))
                if len(wanted):
                    cycles.append((cycle, tuple(int(k) for k in wanted)))
            positions.append(chunk)
            tasks.append(replace(template, chunk=len(tasks), vehicles=tuple(distinct[j] for j in chunk),
                                 cycles=tuple(cycles), ambient_temp_C=ambient))
    return tasks, positions


def collect(engine, tasks, positions, conditions, n: int,
            progress=None) -> tuple[dict[Condition, dict[str, np.ndarray]], dict[Condition, dict[str, np.ndarray]]]:
    """Run the tasks on ``engine``; per condition (cycle, ambient C) the per-vehicle sums and
    shortfall measures, each a column of values by name."""
    per_condition = {cond: {**{name: np.full(n, np.nan) for name in RESULT_FIELDS}, "kwh": np.zeros(n)}
                     for cond in conditions}
    shortfalls: dict[Condition, dict[str, np.ndarray]] = {cond: {} for cond in conditions}
    if progress:
        progress(0, len(tasks))
    for done, (index, by_cycle) in enumerate(engine.run(simulate_task, tasks), start=1):
        task = tasks[index]
        for cycle, members in task.cycles:
            cond = (cycle, task.ambient_temp_C)
            where = positions[index][list(members)]
            sums = by_cycle[cycle]
            for name in RESULT_FIELDS:
                per_condition[cond][name][where] = sums.sums[name]
            for name, values in sums.shortfalls.items():
                shortfalls[cond].setdefault(name, np.zeros(n))[where] = values
        if progress:
            progress(done, len(tasks))
    return per_condition, shortfalls


def electric_sums(distinct, needed: dict[Condition, set[str]],
                  per_condition: dict[Condition, dict[str, np.ndarray]]) -> None:
    """Fill in the electric vehicles' per-cycle sums from the road-load energy model
    (:func:`fleetrun.simulation.electric.simulate_electric`): kWh from the wall, no fuel, no
    differential energies (the thesis model is not run for them), the battery energy spent on
    traction as drivetrain input. Ambient temperature does not change them (not modelled)."""
    duties = np.array([v.duty_class if v.fuel == ELECTRIC else None for v in distinct], dtype=object)
    for (cycle, ambient), duty_set in needed.items():
        rows = np.flatnonzero(np.isin(duties, sorted(duty_set)))
        if not len(rows):
            continue
        sums = simulate_electric([distinct[i] for i in rows], _cycle(cycle))
        target = per_condition[(cycle, ambient)]
        target["miles"][rows] = sums["miles"]
        target["kwh"][rows] = sums["kwh"]
        target["fuel_gal"][rows] = 0.0
        target["diff_input_energy_J"][rows] = target["diff_output_energy_J"][rows] = 0.0
        target["wheel_energy_J"][rows] = sums["wheel_energy_J"]
        target["drivetrain_input_energy_J"][rows] = sums["drivetrain_input_energy_J"]


def distinct_vehicles(vehicles: Sequence[VehicleSpec]) -> tuple[list[VehicleSpec], np.ndarray]:
    """The physically distinct vehicles (first of each, grouped by differential) and, per
    fleet row, the index of its distinct vehicle."""
    index: dict[tuple, int] = {}
    distinct: list[VehicleSpec] = []
    owner = np.empty(len(vehicles), dtype=np.int64)
    for i, v in enumerate(vehicles):
        key = v.physics_key()
        j = index.get(key)
        if j is None:
            j = index[key] = len(distinct)
            distinct.append(v)
        owner[i] = j
    # Vehicles that share a differential next to each other: a chunk then needs few maps.
    order = sorted(range(len(distinct)), key=lambda j: (distinct[j].configuration, distinct[j].final_drive_ratio,
                                                         distinct[j].low_gear_ratio or 0.0, j))
    rank = np.empty(len(distinct), dtype=np.int64)
    rank[order] = np.arange(len(distinct))
    return [distinct[j] for j in order], rank[owner]


_SHORTFALL_PHRASES = {  # the simulation's shortfall measures, in the order a reader wants them
    "shortfall_time_s": "{:.3g} s behind the trace",
    "shortfall_max_speed_mps": "up to {:.3g} m/s below it",
    "shortfall_distance_m": "{:.3g} m short",
    "shortfall_steps": "{:.3g} steps at full load",
}


def _phrase_order(item):
    name = item[0]
    return (list(_SHORTFALL_PHRASES).index(name) if name in _SHORTFALL_PHRASES else len(_SHORTFALL_PHRASES), name)


def _map_grid_notes(fleet: Fleet, mode: str) -> list[str]:
    """One note listing the vehicles whose final drive ratio lies beyond the cached map3d
    gear-ratio grid: map3d builds their maps at their own ratio (as map2d)."""

    if (DEFAULT_MODE if mode == "auto" else mode) != "map3d":
        return []
    beyond: dict[tuple, bool] = {}    # per configuration and ratio (a fleet repeats them)
    outside = []
    for v in fleet.vehicles:
        key = (v.configuration, v.final_drive_ratio)
        found = beyond.get(key)
        if found is None:
            found = beyond[key] = outside_map3d_grid(*key)
        if found:
            outside.append(v)
    if not outside:
        return []
    shown = ", ".join(f"{v.vehicle_id} (row {fleet.vehicle_rows.get(v.vehicle_id, '?')}: {v.final_drive_ratio:g})"
                      for v in outside[:MAX_LISTED_WARNINGS])
    more = f" and {len(outside) - MAX_LISTED_WARNINGS} more" if len(outside) > MAX_LISTED_WARNINGS else ""
    grids = "; ".join(f"{duty} {g[0]:g}-{g[-1]:g}" for duty, g in GEAR_GRID.items())
    return [f"note: {len(outside)} vehicle type(s) have a final_drive_ratio beyond the map3d gear-ratio grid "
            f"({grids}); their differential maps are built at their own ratio, as in --mode map2d: "
            f"{shown}{more}"]


def _shortfall_phrase(name: str, value: float) -> str:
    template = _SHORTFALL_PHRASES.get(name)
    return template.format(value) if template else f"{name.removeprefix('shortfall_')} {value:.3g}"


def _shortfall_warnings(vehicles, shortfalls, listed: int | None = MAX_LISTED_WARNINGS) -> list[str]:
    """One line per vehicle that could not follow some cycle (the first ``listed``, then a
    count; None: all): which cycles, and the worst value of each shortfall measure the
    simulation reports. The masks are numpy; only the listed vehicles are looked at one by one."""
    behind_by_condition = {}
    for condition, arrays in shortfalls.items():
        if not arrays:
            continue
        names = sorted(arrays)
        stacked = np.nan_to_num(np.vstack([arrays[n] for n in names]))
        if "shortfall_time_s" in arrays:
            # the simulation counts time more than 0.1 m/s below the trace: its own tolerance
            behind = np.nan_to_num(arrays["shortfall_time_s"]) > 0
        else:
            behind = (stacked > SHORTFALL_TOLERANCE).any(axis=0)
        behind_by_condition[condition] = (names, stacked, behind)
    if not behind_by_condition:
        return []
    anyone = np.logical_or.reduce([behind for _, _, behind in behind_by_condition.values()])
    vehicles_behind = np.flatnonzero(anyone)
    shown = vehicles_behind if listed is None else vehicles_behind[:listed]
    lines = [_shortfall_line(vehicles[i], int(i), behind_by_condition) for i in shown]
    if len(vehicles_behind) > len(shown):
        lines.append(f"... and {len(vehicles_behind) - len(shown)} more vehicle types that cannot "
                     "follow some cycle")
    return lines


def _library_shortfalls(lines: list[str]) -> list[str]:
    """Registration cohorts: one line per representing vehicle, not per model year
    (docs/registrations.md), the first MAX_LISTED_WARNINGS, then a count; a shipped library
    vehicle's line says what it means for the forecast."""
    unique = list(dict.fromkeys(re.sub(r":MY\d+(:mi[0-9.e+]+)?", ":MY*", t) for t in lines))
    unique = [t + ("; a shipped library vehicle: its fuel is that of the speed it reaches, nothing to fix in the "
                   "workbook" if ":MY*" in t and ":VEH:" not in t else "")
              for t in unique]
    if len(unique) > MAX_LISTED_WARNINGS:
        unique = unique[:MAX_LISTED_WARNINGS] + [f"... and {len(unique) - MAX_LISTED_WARNINGS} more vehicle types "
                                                 "that cannot follow some cycle"]
    return unique


def _shortfall_line(vehicle, i: int, behind_by_condition: dict) -> str:
    """The warning of vehicle ``i``: the cycles (and temperatures) it falls behind on, the worst
    of each shortfall measure over them."""
    cycles: dict[str, list[str]] = {}
    worst: dict[str, float] = {}
    for (cycle, ambient), (names, stacked, behind) in behind_by_condition.items():
        if not behind[i]:
            continue
        cycles.setdefault(_cycle_label(cycle), []).append(f"{ambient:g} C")
        for k, name in enumerate(names):
            if stacked[k, i] > SHORTFALL_TOLERANCE:
                worst[name] = max(worst.get(name, 0.0), float(stacked[k, i]))
    listed = ", ".join(f"{c} ({', '.join(t)})" for c, t in cycles.items())
    measures = ", ".join(_shortfall_phrase(n, v) for n, v in sorted(worst.items(), key=_phrase_order))
    return f"vehicle {vehicle.vehicle_id} cannot follow {listed}; worst shortfall: {measures}"


def _cycle_label(cycle: str) -> str:
    return Path(cycle).name if cycle.lower().endswith(".csv") else cycle


def _shipped_cycle_file(name: str):
    """The CSV (or a composed cycle's TOML) a shipped cycle is read from (its sha256 goes in
    the manifest)."""
    for suffix in (".csv", ".toml"):
        candidate = Path(inputs_dir()) / "cycles" / f"{name}{suffix}"
        if candidate.is_file():
            return candidate
    return None


def _cycle_info(names) -> dict[str, CycleInfo]:
    info = {}
    for name in sorted(names):
        cycle = _cycle(name)
        duration = float(cycle.time_s[-1] - cycle.time_s[0])
        path = Path(name) if name.lower().endswith(".csv") else _shipped_cycle_file(name)
        info[name] = CycleInfo(cycle.name, float(cycle.miles), duration, None if path is None else str(path),
                               None if path is None else file_sha256(path))
    return info


# --- efficiency maps of the configurations used -------------------------------------------

MAP_TORQUE_FRACTIONS = (0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
MAP_SPEEDS_RPM = (250, 500, 1000, 1500, 2000, 2500, 3000, 3500, 4000)


def efficiency_maps(vehicles: Sequence[VehicleSpec], physics: str, effects=()) -> tuple[list[EfficiencyMap], list[str]]:
    """For each configuration in the fleet: efficiency over torque fraction x speed at the
    fleet's median gear ratio and Kim scale (and median low ratio for two-speed axles, high
    gear), with the steady-state part of the differential-level ``effects``."""

    differential_effects = [(e, p) for e, p in as_effect_list(effects) if e.level == "differential"]
    maps = []
    by_config: dict[str, list[VehicleSpec]] = {}
    for v in vehicles:
        by_config.setdefault(v.configuration, []).append(v)
    tf, rpm = np.meshgrid(np.array(MAP_TORQUE_FRACTIONS), np.array(MAP_SPEEDS_RPM, dtype=float),
                          indexing="ij")
    for config in sorted(by_config):
        group = by_config[config]
        gear = float(np.median([v.final_drive_ratio for v in group]))
        lows = [v.low_gear_ratio for v in group if v.low_gear_ratio]
        low = float(np.median(lows)) if lows else None
        kim = float(np.median([v.kim_torque_scale_Nm for v in group]))
        if differential_effects:
            eta = efficiency_with_effects(config, tf, rpm, gear, differential_effects, kim_torque_scale_Nm=kim,
                                          low_gear_ratio=low, axle_gear="high", physics=physics)
        else:
            eta = efficiency(config, tf, rpm, gear, low_gear_ratio=low, axle_gear="high", physics=physics,
                             kim_torque_scale_Nm=kim)
        eta = np.asarray(eta, dtype=float)
        maps.append(EfficiencyMap(configuration=config, gear_ratio=gear, low_gear_ratio=low, axle_gear="high",
                                  torque_fractions=MAP_TORQUE_FRACTIONS, speeds_rpm=MAP_SPEEDS_RPM,
                                  efficiency=tuple(map(tuple, eta.tolist())), vehicle_types=len(group)))
    return maps, []
