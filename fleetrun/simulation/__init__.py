"""Drive-cycle simulation: from a speed trace to differential load, drivetrain efficiency and fuel.

``simulate(vehicles, cycle)`` runs many vehicles over one cycle together (arrays over
vehicles x steps). See docs/simulation.md for the model and its choices.
"""
from __future__ import annotations

import functools
import os
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from fleetrun.cycles import composite_per_mile, load_cycle
from fleetrun.errors import InputError, unknown_name_error
from fleetrun.simulation import bounds, coastdown_driveline, diffmodes, measured
from fleetrun.simulation.core import (FOLLOW_TOL_MPS, REDRIVE_SPEED_GRID, DifferentialSolver,
                                      above_full_load_at_start, backward,
                                      backward_drivetrain, has_technology, row_buffers,
                                      standstill_fuel_rate_g_per_s, step_sums, idle_fuel_at_ambient_g_per_s, with_climate_load,
                                      forward_redrive, idle_fuel_rate_g_per_s, max_tractive_force_table,
                                      power_speed_table)
from fleetrun.simulation.effects import (CycleEffects, cycle_effects, describe_effects, step_time_since_start_s,
                                         vehicle_extra_fuel_g_per_s)
from fleetrun.simulation.params import vehicle_arrays
from fleetrun.simulation.records import (BLOCK_ARRAYS, PHASE_FIELDS, SUM_FIELDS, TRACE_COLUMNS, BlockSums,
                                         FleetCycleResult, PhaseResult, StepResults, Trace)
from fleetrun.simulation.thermal import (ThermalConstants, cold_start_extra_fuel, start_temperature_C,
                                         thermal_constants)
from fleetrun.units import LITERS_PER_GALLON, METERS_PER_MILE, RAD_S_PER_RPM

__all__ = ["simulate", "FleetCycleResult", "PhaseResult", "Trace", "TRACE_COLUMNS", "SUM_FIELDS", "PHASE_FIELDS",
           "MODES", "DEFAULT_MODE"]

MODES = diffmodes.MODES
# "auto" = the fastest mode whose cycle fuel stays within 0.2 % of direct for every example
# vehicle (tests/test_simulation_modes.py checks it): the cached 3-D map.
DEFAULT_MODE = "map3d"
REDRIVE_MARGINS = (0.9, 0.8, 0.7, 0.6, 0.5)
# vehicles x steps per block: ~64 UDDS vehicles. Each (block x steps) array (~0.7 MB) stays
# in the CPU's L2/L3 cache and below the size where malloc returns freed memory to the system
# (twice as large blocks spend a third of their time in page faults); smaller blocks pay
# numpy's per-call cost more often (docs/benchmarks-simulation.md: the sweep of block sizes)
BLOCK_STEPS = 88000


def _load(cycle):
    if isinstance(cycle, (str, os.PathLike)):
        cycle = load_cycle(cycle)
    return cycle


@dataclass(frozen=True, eq=False)
class ThermalPlan:
    """What the cold-start pass of a composed cycle needs (:func:`_thermal_plan`)."""

    phases: tuple                 # the cycle's phases (fleetrun.cycles)
    composite: str                # the composite rule's name (fleetrun.cycles.composite_per_mile)
    step_phase: np.ndarray        # phase index per step, -1 in an engine-off soak
    step_soak_s: np.ndarray       # engine-off time per step [s]
    ambient_temp_C: float
    constants: ThermalConstants
    start_temp_C: float


def _thermal_plan(cycle, t, ambient_temp_C, thermal=None):
    """What the cold-start pass needs for a composed cycle (None for a plain cycle, which is
    driven with a warm engine): step phases, engine-off soak time per step, start temperature."""
    phases = tuple(getattr(cycle, "phases", ()) or ())
    if not phases:
        return None
    step_phase = cycle.step_phase()
    dt_all = np.concatenate([[0.0], np.diff(t)])
    return ThermalPlan(phases=phases, composite=str(getattr(cycle, "composite", "")), step_phase=step_phase,
                       step_soak_s=np.where(step_phase < 0, dt_all, 0.0), ambient_temp_C=float(ambient_temp_C),
                       constants=thermal or thermal_constants(),
                       start_temp_C=start_temperature_C(phases[0].soak_before_s, ambient_temp_C, thermal))


def _cycle_arrays(cycle, ambient_temp_C=None, thermal=None):
    """Name, time, speed and grade of ``cycle`` (checked), and with ``ambient_temp_C`` also its
    cold-start plan (:func:`_thermal_plan`)."""
    cycle = _load(cycle)
    try:
        t = np.asarray(cycle.time_s, float)
        v = np.asarray(cycle.speed_mps, float)
        grade = getattr(cycle, "grade_pct", None)
    except (AttributeError, TypeError, ValueError):
        raise InputError("the cycle must have time_s and speed_mps arrays") from None
    name = str(getattr(cycle, "name", "cycle"))
    grade = np.zeros_like(t) if grade is None else np.asarray(grade, float)
    if t.ndim != 1 or t.size < 2 or v.shape != t.shape or grade.shape != t.shape:
        raise InputError(f"cycle '{name}': time_s, speed_mps and grade_pct must be equal-length columns of at least 2 rows")
    if not (np.isfinite(t).all() and np.isfinite(v).all() and np.isfinite(grade).all()):
        raise InputError(f"cycle '{name}': time, speed and grade must be finite numbers")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        raise InputError(f"cycle '{name}': time_s is not strictly increasing (row {bad[0] + 3}: "
                         f"{t[bad[0]]} then {t[bad[0] + 1]})", column="time_s", value=t[bad[0] + 1],
                         hint="Sort the rows by time and remove duplicates")
    neg = np.flatnonzero(v < 0)
    if neg.size:
        raise InputError(f"cycle '{name}': negative speed {v[neg[0]]} at time {t[neg[0]]} s",
                         column="speed", value=v[neg[0]], hint="Speeds must be >= 0")
    if ambient_temp_C is None:
        return name, t, v, grade
    return name, t, v, grade, _thermal_plan(cycle, t, ambient_temp_C, thermal)


def simulate(vehicles: Sequence, cycle, *, mode: str = "auto", ambient_temp_C: float = 20.0,
             physics: str = "thesis", effects=(), trace: bool = False, cache_dir=None,
             thermal: ThermalConstants | None = None, calibrate: bool = True,
             coastdown_driveline_removed: str | None = None) -> FleetCycleResult:
    """Simulate ``vehicles`` (VehicleSpec rows) over ``cycle`` (a DriveCycle, or a shipped
    cycle name / CSV path for ``fleetrun.cycles.load_cycle``) together.

    Parameters
    ----------
    vehicles : sequence of :class:`fleetrun.vehicle.VehicleSpec`, simulated together (arrays over
        vehicles x steps)
    cycle : a :class:`fleetrun.cycles.DriveCycle` (time [s], speed [m/s], grade [%]), a shipped
        cycle name or a CSV path
    mode : ``direct``, ``map2d``, ``map3d`` (thesis Ch. 6) or ``auto`` (= map3d, DEFAULT_MODE)
    ambient_temp_C : float, ambient temperature [C]: the lubricant's (ambient + 50 K, thesis
        Sec. 3.1.2), a composed cycle's (FTP's) cold start and the effects' cold start
    physics : str, the differential baseline (``thesis``, ``vecto-generic``)
    effects : physics the thesis left out (a ``--with`` string, or what
        ``fleetrun.effects.parse_with`` returns), per step on top of any mode
    trace : bool, also return the per-step trace (:class:`fleetrun.simulation.records.Trace`)
    cache_dir : folder of the map3d cache (None: ``diffmodes.default_cache_dir``)
    thermal : the cold-start constants (None: ``models/thermal.toml``)
    calibrate : bool, apply the vehicles' measured figures (``measured_ftp_mpg``,
        ``label_combined_mpg``; docs/simulation.md)
    coastdown_driveline_removed : str or None, driveline spin loss taken out of the road load (a variant
        of simulation/coastdown_driveline.py; None: models/road_load.toml, ``none``)

    Returns
    -------
    :class:`fleetrun.simulation.records.FleetCycleResult`: per-vehicle miles, fuel [g, gal], mpg,
    energies [J], shortfall; per phase for a composed cycle. See docs/simulation.md.

    >>> from fleetrun.testing.vehicles import CAMRY
    >>> r = simulate([CAMRY], "UDDS")
    >>> round(float(r.miles[0]), 2), 20 < float(r.mpg[0]) < 45
    (7.45, True)
    """
    vehicles = list(vehicles)
    if mode == "auto":
        mode = DEFAULT_MODE
    if mode not in MODES:
        raise unknown_name_error("mode", str(mode), MODES + ("auto",))
    effects = cycle_effects(effects)
    name, t, v_target, grade, plan = _cycle_arrays(cycle, ambient_temp_C, thermal)
    va, solver = _arrays_and_solver(vehicles, mode, physics, ambient_temp_C, cache_dir, coastdown_driveline_removed)
    V = va.n
    # Vehicles go through in blocks: each block's vehicles x steps arrays stay in the CPU
    # cache, which is several times faster than one pass over the whole fleet.
    block = _block_rows(t.size)

    def run(rows, speed, redriven_if_behind=False, va_rows=None):
        return _run_rows(va, solver, t, v_target, grade, trace, effects, plan, block, rows, speed, redriven_if_behind,
                         va_rows)
    # first every vehicle drives the trace itself, then those that cannot follow it
    sums = (_redrive_until_feasible(run(np.arange(V), None, bool(REDRIVE_MARGINS)), va, t, v_target, grade, run,
                                    _stuck_at_start(va, solver, t, v_target, grade, effects)) if V else None)
    empty = np.zeros(0)
    totals = {key: (getattr(sums, key) if V else empty) for key in SUM_FIELDS}
    phases, composite = {}, ""
    if plan is not None and V:
        phases, composite, composite_totals = phase_results(plan, sums, va.density)
        totals.update(composite_totals)
    result = FleetCycleResult(
        vehicle_ids=[getattr(x, "vehicle_id", str(i)) for i, x in enumerate(vehicles)], cycle=name, mode=mode,
        **totals, duration_s=float(t[-1] - t[0]), effects=describe_effects(effects),
        trace=sums.trace if trace and V else None, phases=phases, composite=composite,
    )
    if not (calibrate and V):
        return result
    return _calibrate_on_measured(result, vehicles, name, ambient_temp_C, mode, physics, cache_dir)


def _run_rows(va, solver, t, v_target, grade, trace, effects, plan, block, rows, speed, redriven_if_behind,
              va_rows=None):
    """The vehicles ``rows`` of ``va`` at ``speed`` (their rows; None: on the trace) in blocks of
    ``block`` (:func:`_run_block`); on the trace the hardest steps of every block are checked
    in one pass first (:func:`_surely_behind_by_block`). ``va_rows``: ``va.subset(rows)`` if
    the caller has it (the blocks' arrays are then views of its arrays)."""
    V = va.n
    surely = (_surely_behind_by_block(va, solver, t, v_target, grade, effects, block)
              if speed is None and redriven_if_behind and not trace and rows.size == V else None)
    parts, kept = [], []
    for first in range(0, rows.size, block):
        sub = rows[first:first + block]
        precheck = True if surely is None else surely[first:first + block]
        keep = None if surely is None or plan is not None else np.flatnonzero(~precheck)
        if keep is not None and 2 <= keep.size < sub.size:   # run with the other blocks' (below)
            parts.append(_behind_only(sub.size, 1))
            kept.append((len(parts) - 1, sub[keep], keep, sub.size))
            continue
        if sub.size == V:
            va_sub, solver_sub = va, solver
        else:
            va_sub = va.subset(sub) if va_rows is None else va_rows.subset(slice(first, first + sub.size))
            solver_sub = solver.subset(sub, va_sub)
        parts.append(_run_block(va_sub, solver_sub, t, None if speed is None else speed[first:first + block],
                                v_target, grade, trace, effects, plan, redriven_if_behind, precheck))
    if kept:
        _run_kept_together(parts, kept, va, solver, t, v_target, grade, effects)
    return _concatenate(parts)


def _run_kept_together(parts, kept, va, solver, t, v_target, grade, effects):
    """The vehicles on the trace that are not surely behind, of the blocks where others are
    (:func:`_without_rows_behind`; a plain cycle), in one pass: ``kept`` lists (index in
    ``parts``, their rows in ``va``, their rows in the block, the block's size), at least two
    of each block (a part of one vehicle sums its steps in another order), written into the
    blocks' sums ``parts`` (NaN for the others). The same figures as one pass per block:
    element-wise arithmetic, per-vehicle sums, the distance rule of blocks of more than one
    vehicle (:func:`_distance_m`)."""
    rows = np.concatenate([k[1] for k in kept])
    va_keep = va.subset(rows)
    together = _run_block(va_keep, solver.subset(rows, va_keep), t, None, v_target, grade, False, effects, None,
                          True, precheck=False, distance_rows=min(k[3] for k in kept))
    first = 0
    for index, own, local, _ in kept:
        for key in BLOCK_ARRAYS:
            getattr(parts[index], key)[local] = getattr(together, key)[first:first + own.size]
        first += own.size


def _arrays_and_solver(vehicles, mode, physics, ambient_temp_C, cache_dir, coastdown_removed):
    """The vehicles' arrays (power table and idle fuel filled once for the whole call, shared by
    the blocks; the coastdown's driveline part removed as chosen) and the differential solver."""
    va = vehicle_arrays(vehicles)
    if va.n:
        va.power_table, _ = power_speed_table(va), idle_fuel_rate_g_per_s(va)
    solver = DifferentialSolver(va, mode, physics, ambient_temp_C, cache_dir)
    variant = coastdown_removed or coastdown_driveline.default_variant()
    return coastdown_driveline.remove_driveline_spin(va, solver, variant), solver


_NOMINAL_MPG: dict = {}   # (physics key, cycle, mode, physics) -> simulated mpg at 25 C, per process


def _nominal_mpg(vehicles, cycle, mode, physics, cache_dir) -> np.ndarray:
    """Simulated mpg of ``vehicles`` on ``cycle`` at EPA's nominal 25 C, uncalibrated (remembered)."""
    keys = [(v.physics_key(), cycle, mode, physics) for v in vehicles]
    todo = [i for i, key in enumerate(keys) if key not in _NOMINAL_MPG]
    if todo:
        mpg = simulate([vehicles[i] for i in todo], cycle, mode=mode, physics=physics, cache_dir=cache_dir,
                       ambient_temp_C=measured.NOMINAL_AMBIENT_C, calibrate=False).mpg
        _NOMINAL_MPG.update({keys[i]: m for i, m in zip(todo, mpg)})
    return np.array([_NOMINAL_MPG[key] for key in keys], float)


def _calibrate_on_measured(result: FleetCycleResult, vehicles, cycle_name, ambient_temp_C, mode, physics,
                           cache_dir) -> FleetCycleResult:
    """``result`` with the fuel of vehicles with a measured FTP or label figure scaled
    (simulation/measured.py)."""
    figures = measured.measured_figures(vehicles)
    ftp = figures["measured_ftp_mpg"]
    rows = np.flatnonzero(measured.calibrated(figures))
    if rows.size == 0:
        return result
    sub = [vehicles[i] for i in rows]
    sim_ftp = _nominal_mpg(sub, "FTP", mode, physics, cache_dir)
    sim_hwfet = (_nominal_mpg(sub, "HWFET", mode, physics, cache_dir) if np.isnan(ftp[rows]).any()
                 else np.full(rows.size, np.nan))
    factors = measured.cycle_factors({name: x[rows] for name, x in figures.items()}, sim_ftp, sim_hwfet,
                                     [v.model_year for v in sub], [v.label_group for v in sub])
    at_nominal = abs(ambient_temp_C - measured.NOMINAL_AMBIENT_C) < 1e-9
    factor = np.ones(len(vehicles))
    factor[rows] = measured.factor_on(factors, cycle_name, at_nominal)
    return measured.scale_result(result, factor)


def _stuck_at_start(va, solver, t, v_target, grade, effects):
    """``stuck(rows, margin, table, va_rows=None)`` for :func:`_redrive_until_feasible`: which of
    the vehicles ``rows`` (ascending; ``va_rows``: their ``va.subset``) are above full load in
    their re-drive's first two steps (core.above_full_load_at_start). The first call answers
    for its margin and every later one but the last (REDRIVE_MARGINS) in one pass, the vehicles
    stacked once per margin (each row's steps are its own: the same numbers as one call per
    margin); a later round's vehicles are among the first call's, else they are computed anew."""
    known = {}

    def stuck(rows, margin, table, va_rows=None):
        if margin in known:
            first, answer = known[margin]
            at = np.minimum(np.searchsorted(first, rows), first.size - 1)
            if first.size and np.array_equal(first[at], rows):
                return answer[at]
        margins = [m for m in REDRIVE_MARGINS[:-1] if m <= margin] or [margin]
        va_rows = va.subset(rows) if va_rows is None else va_rows
        k, R = len(margins), rows.size
        va_k = va_rows if k == 1 else va_rows.subset(np.tile(np.arange(R), k))
        answers = above_full_load_at_start(va_k, t, v_target, grade, solver.subset(np.tile(rows, k), va_k),
                                           np.repeat(margins, R)[:, None], np.tile(table, (k, 1)), effects)
        known.update((m, (rows, a)) for m, a in zip(margins, answers.reshape(k, R)))
        return known[margin][1]
    return stuck


def _redrive_until_feasible(sums: BlockSums, va, t, v_target, grade, run, stuck=None) -> BlockSums:
    """Vehicles that cannot follow the trace are re-driven (all together) at full effort, with
    a smaller margin on the estimated maximum effort each round, until the backward pass finds
    every step feasible; ``run(rows, speed, redriven_if_behind)`` simulates the vehicles
    ``rows`` at ``speed`` (``redriven_if_behind``: a block whose vehicles all fall behind
    need not be summed, they are driven again: :func:`_run_block`). ``stuck(rows, margin,
    table)``: which of ``rows`` are above full load in the re-drive's first two steps
    (:func:`core.above_full_load_at_start`); before the last round those stay behind
    without being re-driven or summed (their sums would be replaced by the next round's)."""
    force_tables = None
    for margin in REDRIVE_MARGINS:
        behind = np.flatnonzero(sums.behind)
        if behind.size == 0:
            break
        va_behind = va.subset(behind)
        if force_tables is None:  # the drivetrain's maximum effort, once per simulate
            force_tables = np.zeros((va.n, REDRIVE_SPEED_GRID.size))
            force_tables[behind] = max_tractive_force_table(va_behind, 1.0)
        last = margin == REDRIVE_MARGINS[-1]
        if stuck is not None and not last:
            kept = _without_stuck(behind, stuck(behind, margin, force_tables[behind], va_behind), _block_rows(t.size))
            if kept.size == 0:
                continue
            if kept.size < behind.size:
                behind, va_behind = kept, va.subset(kept)
        achieved = forward_redrive(va_behind, t, v_target, grade, margin, force_tables[behind])
        sums = _redriven(sums, run(behind, achieved, not last, va_behind), behind)
    return sums


def _block_rows(steps: int) -> int:
    """Vehicles per block of a cycle of ``steps`` time stamps (BLOCK_STEPS)."""
    return max(1, BLOCK_STEPS // steps)


def _alone(n: int, block: int) -> np.ndarray:
    """Which of ``n`` vehicles run in blocks of ``block`` are alone in theirs (n,)."""
    alone = np.zeros(n, bool)
    if block == 1:
        alone[:] = True
    elif n % block == 1:
        alone[-1] = True
    return alone


def _without_stuck(rows, stuck, block: int):
    """``rows`` without the ``stuck`` ones, unless that would put a vehicle alone in its block
    that was not, or the other way round: a block of one vehicle sums its steps in another
    order than a larger one (numpy's pairwise sum of a contiguous row against the column
    order of the steps gathered for several), so its figures would move in the last bit."""
    keep = rows[~stuck]
    if keep.size and stuck.any() and not np.array_equal(_alone(rows.size, block)[~stuck], _alone(keep.size, block)):
        return rows
    return keep


def _concatenate(parts: list[BlockSums]) -> BlockSums:
    """The blocks' sums (and traces) as one record over all their vehicles."""
    arrays = {key: np.concatenate([getattr(p, key) for p in parts]) for key in BLOCK_ARRAYS}
    trace = None
    if parts[0].trace is not None:
        trace = Trace(**{key: np.concatenate([getattr(p.trace, key) for p in parts]) for key in TRACE_COLUMNS})
    return BlockSums(**arrays, trace=trace)


def _redriven(sums: BlockSums, again: BlockSums, behind) -> BlockSums:
    """``sums`` with the re-driven vehicles' rows ``behind`` replaced by ``again``."""
    for key in BLOCK_ARRAYS:
        getattr(sums, key)[behind] = getattr(again, key)
    if sums.trace is None:
        return sums
    columns = {}
    for key in TRACE_COLUMNS:
        column = np.array(getattr(sums.trace, key))   # a writable copy (some columns are broadcast views)
        column[behind] = getattr(again.trace, key)
        columns[key] = column
    return replace(sums, trace=Trace(**columns))


def _row_buffered(run_block):
    """``run_block`` with numpy's ufunc buffer sized to the block's rows (core.row_buffers:
    the same results, faster); the rows are about the steps where the trace moves."""
    @functools.wraps(run_block)
    def run(va, solver, t, speed, v_target, *args, **kwargs):
        with row_buffers(np.count_nonzero(v_target)):
            return run_block(va, solver, t, speed, v_target, *args, **kwargs)
    return run


@_row_buffered
def _run_block(va, solver, t, speed, v_target, grade, trace, effects: CycleEffects = CycleEffects(),
               plan: ThermalPlan | None = None, redriven_if_behind: bool = False, precheck: bool = True,
               distance_rows: int | None = None) -> BlockSums:
    """Simulate one block of vehicles at the speeds ``speed`` (V, N), or None: the trace
    ``v_target`` itself (then the steps' motion is computed once, (1, N), for all vehicles).
    Per-vehicle sums (and the trace if asked for); ``behind`` marks vehicles with steps above
    full load. ``plan``: a composed cycle's cold-start plan (:func:`_thermal_plan`), None for
    a plain cycle. ``redriven_if_behind``: vehicles behind will be driven again, so their fuel
    need not be computed (the sums are NaN, :func:`_behind_only`): not when every vehicle of
    the block is behind, and on the trace not for those above full load in one of its hardest
    steps (:func:`_surely_behind`; ``precheck``). ``distance_rows``: the block's size when
    this is part of it (:func:`_distance_m`)."""
    V, N = va.n, t.size
    on_trace = speed is None
    speed = v_target[None, :] if on_trace else np.asarray(speed)
    # Without a trace, steps where the trace stands still (and so every vehicle, which is
    # never ahead of it) are not simulated: they burn idle fuel, added below.
    target_avg = 0.5 * (v_target + np.concatenate([v_target[:1], v_target[:-1]]))
    if redriven_if_behind and on_trace and precheck is not False and not trace:
        surely = (precheck if isinstance(precheck, np.ndarray)
                  else _surely_behind(va, solver, t, v_target, grade, effects, target_avg))
        if surely.any() and (surely.all() or plan is None):
            return _without_rows_behind(va, solver, t, v_target, grade, effects, plan, surely)
    columns = None if trace else np.flatnonzero(target_avg > 0)
    drivetrain = backward_drivetrain(va, t, speed, grade, solver, columns, effects, losses=trace)
    if redriven_if_behind and not trace and drivetrain.k.at_rest(drivetrain.infeasible, False).any(axis=1).all():
        return _behind_only(V, 1 if plan is None else len(plan.phases))
    out = backward(va, t, speed, grade, solver, columns, effects, losses=trace, drivetrain=drivetrain)
    dt = out.dt
    dt_all = np.concatenate([[0.0], np.diff(t)])
    k = drivetrain.k
    distance_m = _distance_m(out.v_avg * dt, V, on_trace, distance_rows or V, k)
    target_m = float((target_avg * dt_all).sum())
    not_followed, shortfall_time_s, shortfall_max_speed_mps = _shortfall(v_target, None if on_trace else speed,
                                                                         dt_all, columns, out.infeasible)
    if plan is None:
        fuel_g = (out.fuel_rate_g_per_s * dt).sum(axis=1)
        if columns is not None:
            standstill_s = dt_all.sum() - dt_all[columns].sum()
            if has_technology(va):   # start-stop: engine off at the warm stops
                still = _still(N, columns)
                rate = standstill_fuel_rate_g_per_s(va, step_time_since_start_s(t)[still])[0]
                fuel_g = fuel_g + (with_climate_load(va, solver.ambient, rate) * dt_all[still]).sum(axis=1)
            else:
                fuel_g = fuel_g + idle_fuel_at_ambient_g_per_s(va, solver.ambient) * standstill_s
            if effects.vehicle:  # the skipped steps idle: the vehicle-level effects' fuel at rest
                fuel_g = fuel_g + (_still_effects_fuel(va, t, columns, effects) * dt_all[_still(N, columns)]).sum(axis=1)
        phase_fuel_g, phase_miles = fuel_g[:, None], (distance_m / METERS_PER_MILE)[:, None]
        cold = temp = None
    else:
        fuel_g, phase_fuel_g, phase_miles, cold, temp = _phased_fuel(va, t, columns, out, effects, plan)
    fuel_gal = fuel_g / 1000.0 / va.density / LITERS_PER_GALLON
    miles = distance_m / METERS_PER_MILE
    driving = out.moving & (out.wheel_torque_Nm > 0)
    driving_dt = np.where(driving, dt, 0.0)
    e = lambda p: (p * driving_dt).sum(axis=1)  # noqa: E731
    wheel = e(out.wheel_power_W)
    with np.errstate(divide="ignore", invalid="ignore"):
        mpg = np.where(fuel_gal > 0, miles / fuel_gal, np.nan)
    return BlockSums(
        miles=miles, fuel_g=fuel_g, fuel_gal=fuel_gal, mpg=mpg,
        diff_input_energy_J=e(out.diff_input_torque_Nm * out.diff_input_speed_rpm * RAD_S_PER_RPM),
        diff_output_energy_J=wheel, drivetrain_input_energy_J=e(out.engine_power_W), wheel_energy_J=wheel,
        engine_energy_J=(bounds.maximum(out.engine_power_W, 0.0) * dt).sum(axis=1),
        shortfall_time_s=shortfall_time_s, shortfall_distance_m=target_m - distance_m,
        shortfall_max_speed_mps=shortfall_max_speed_mps,
        shortfall_steps=out.infeasible.sum(axis=1), behind=out.infeasible.any(axis=1),
        phase_fuel_g=phase_fuel_g, phase_miles=phase_miles,
        trace=_trace(t, speed, v_target, grade, out, not_followed, plan, cold, temp) if trace else None,
    )


# on the trace, the steps whose inertial power per kg is at least this share of the cycle's
# largest are checked first: vehicles above full load in one of them are behind
HARD_STEP_SHARE = 0.5


def _surely_behind(va, solver, t, v_target, grade, effects, target_avg) -> np.ndarray:
    """The vehicles (V,) above full load in one of the trace's hardest steps (the backward
    pass up to full load on those steps alone, :func:`core.backward_drivetrain`: every step is
    independent given the speed, so these are the very steps of the whole pass). Checked only
    where rated power is below twice the inertial power of the cycle's hardest step (a
    light-duty car on a light-duty cycle is not)."""
    short, hard = _hard_steps(va, t, v_target, target_avg)
    if not short.any():
        return np.zeros(va.n, bool)
    d = backward_drivetrain(va, t, v_target[None, :], grade, solver, hard, effects, losses=False)
    return d.k.at_rest(d.infeasible, False).any(axis=1)


def _hard_steps(va, t, v_target, target_avg):
    """The vehicles (V,) :func:`_surely_behind` checks (none if the trace never speeds up) and
    the trace's hardest steps."""
    accel = np.concatenate([[0.0], np.diff(v_target) / np.diff(t)])
    power = accel * target_avg                       # [W/kg]
    peak = power.max()
    short = va.P_rated_kW * 1e3 < 2.0 * va.mass_kg * (1.0 + va.rot_frac) * peak
    if peak <= 0:
        short[:] = False
    return short, np.flatnonzero(power >= HARD_STEP_SHARE * peak)


def _surely_behind_by_block(va, solver, t, v_target, grade, effects, block) -> np.ndarray:
    """:func:`_surely_behind` of each block of ``block`` vehicles (V,), in one backward pass
    over the blocks that have a vehicle to check, all of their vehicles (as each block would
    check them; the same values: every vehicle and step is independent given the speed)."""
    target_avg = 0.5 * (v_target + np.concatenate([v_target[:1], v_target[:-1]]))
    short, hard = _hard_steps(va, t, v_target, target_avg)
    surely = np.zeros(va.n, bool)
    starts = np.arange(0, va.n, block)
    checked = np.repeat(np.logical_or.reduceat(short, starts), np.diff(np.append(starts, va.n)))
    rows = np.flatnonzero(checked)
    if rows.size:
        va_rows = va if rows.size == va.n else va.subset(rows)
        solver_rows = solver if rows.size == va.n else solver.subset(rows, va_rows)
        d = backward_drivetrain(va_rows, t, v_target[None, :], grade, solver_rows, hard, effects, losses=False)
        surely[rows] = d.k.at_rest(d.infeasible, False).any(axis=1)
    return surely


def _without_rows_behind(va, solver, t, v_target, grade, effects, plan, surely) -> BlockSums:
    """A block on the trace whose vehicles ``surely`` are behind (re-driven next): NaN sums for
    those, the others simulated as a part of the block (same figures: element-wise arithmetic,
    the block's size for :func:`_distance_m`). A composed cycle only when all are behind (its
    cold-start pass takes the steps where any engine of the block is cold)."""
    sums = _behind_only(va.n, 1 if plan is None else len(plan.phases))
    keep = np.flatnonzero(~surely)
    if keep.size:
        va_keep = va.subset(keep)
        part = _run_block(va_keep, solver.subset(keep, va_keep), t, None, v_target, grade, False, effects, plan,
                          True, precheck=False, distance_rows=va.n)
        for key in BLOCK_ARRAYS:
            getattr(sums, key)[keep] = getattr(part, key)
    return sums


def _behind_only(V, phases) -> BlockSums:
    """The sums of a block whose vehicles all fall behind and will be driven again: NaN
    (replaced by the re-drive's), ``behind`` set, integers 0."""
    nan = lambda *shape: np.full(shape, np.nan)  # noqa: E731
    sums = {key: nan(V) for key in SUM_FIELDS}
    sums["shortfall_steps"] = np.zeros(V, np.intp)
    return BlockSums(**sums, behind=np.ones(V, bool), phase_fuel_g=nan(V, phases), phase_miles=nan(V, phases),
                     trace=None)


def _trace(t, speed, v_target, grade, out: StepResults, not_followed, plan, cold, temp) -> Trace:
    """The block's trace (V, N) from its backward pass (with losses)."""
    V, N = out.wheel_torque_Nm.shape
    full = lambda a: np.broadcast_to(a, (V, N))  # noqa: E731
    return Trace(
        time_s=full(t), vehicle_speed_mps=full(speed), wheel_torque_Nm=out.wheel_torque_Nm,
        diff_input_torque_Nm=out.diff_input_torque_Nm, diff_input_speed_rpm=out.diff_input_speed_rpm,
        diff_efficiency=out.diff_efficiency, gear=out.gear.astype(np.intp), engine_speed_rpm=out.engine_speed_rpm,
        engine_torque_Nm=out.engine_torque_Nm, fuel_rate_g_per_s=out.fuel_rate_g_per_s,
        target_speed_mps=full(v_target), grade_pct=full(grade), tractive_force_N=out.force,
        wheel_speed_rpm=out.wheel_speed_rpm, axle_range=np.where(out.axle_low, "low", "high"),
        transmission_input_torque_Nm=out.transmission_input_torque_Nm,
        transmission_input_speed_rpm=out.transmission_input_speed_rpm,
        converter_unlocked=out.converter_unlocked, engine_max_torque_Nm=out.engine_max_torque_Nm,
        wheel_power_W=out.wheel_power_W, diff_loss_W=out.diff_loss_W, transmission_loss_W=out.transmission_loss_W,
        converter_loss_W=out.converter_loss_W, engine_power_W=out.engine_power_W, not_followed=not_followed,
        **_thermal_trace(V, N, plan, cold, temp),
    )


def _distance_m(step_m, V, on_trace, block_rows=None, k=None):
    """Distance [m] (V,) driven by a block's vehicles, from the distance of each step (V, N),
    or (1, N) when they drive the trace (``on_trace``). V > 1 vehicles on the trace: summed
    step after step, the order in which numpy summed the (V, N) array that held the shared
    trace's steps before they were computed once (kept so that no figure changes); else
    numpy's pairwise row sum, or the pass's rule (core.step_sums) for the Kinematics ``k``.
    ``block_rows``: the size of the block these V vehicles are a part of (the rule follows the
    block)."""
    if on_trace and (block_rows or V) > 1:
        return np.broadcast_to(np.add.accumulate(step_m, axis=1)[:, -1], (V,))
    return step_m.sum(axis=1) if k is None else step_sums(step_m, k)


def _shortfall(v_target, speed, dt_all, columns, infeasible):
    """Where a block's vehicles do not follow the trace (V, N): more than FOLLOW_TOL_MPS below
    it, or above full load in the ``columns`` steps ``infeasible`` covers (all steps if None);
    the time [s] they do not and their largest speed deficit [m/s] (V,). ``speed`` None: the
    vehicles drive the trace itself (no deficit)."""
    V = infeasible.shape[0]
    if speed is None and not infeasible.any():  # on the trace and never above full load
        return np.zeros((V, v_target.size), bool), np.zeros(V), np.zeros(V)
    if speed is None:   # on the trace: no deficit (x - x is +0.0), only the steps above full load
        deficit, not_followed = None, np.zeros((V, v_target.size), bool)
    else:
        deficit = v_target[None, :] - np.broadcast_to(speed, (V, v_target.size))
        not_followed = deficit > FOLLOW_TOL_MPS
    if columns is None:
        not_followed |= infeasible
    else:   # only the steps where some vehicle is above full load (x | False is x)
        some = infeasible.any(axis=0)
        if some.any():
            not_followed[:, columns[some]] |= infeasible[:, some]
    largest = np.zeros(V) if deficit is None else np.maximum(deficit.max(axis=1), 0.0)
    return not_followed, (not_followed * dt_all).sum(axis=1), largest


def _still(N, columns):
    """The steps the block skipped (the whole block stands still there), ascending."""
    skipped = np.ones(N, bool)
    skipped[columns] = False
    return np.flatnonzero(skipped)


def _still_effects_fuel(va, t, columns, effects):
    """Fuel rate (V, len(still)) of the vehicle-level effects at rest in the skipped steps."""
    still = _still(t.size, columns)
    zeros = np.zeros((va.n, still.size))
    return vehicle_extra_fuel_g_per_s(effects, va, step_time_since_start_s(t)[still], zeros, zeros, 1.0)


def _every_step(va, t, columns, out, effects, plan):
    """The warm engine's fuel rate and speed (V, N) in every step: the skipped steps idle (with
    the vehicle-level effects' fuel at rest), engine-off soak steps burn nothing and stand still.
    Sets the soak steps of ``out`` (a traced pass computes them as idle) to engine off."""
    N = t.size
    off = plan.step_phase < 0
    if columns is None:
        out.fuel_rate_g_per_s[:, off] = 0.0
        out.engine_speed_rpm[:, off] = 0.0
        return out.fuel_rate_g_per_s.copy(), out.engine_speed_rpm.copy()
    rate = np.repeat(idle_fuel_at_ambient_g_per_s(va, plan.ambient_temp_C)[:, None], N, axis=1)
    rpm = np.repeat(va.n_idle[:, None], N, axis=1)
    if has_technology(va):   # start-stop: engine off at the warm stops
        still = _still(N, columns)
        at_stop, off_still = standstill_fuel_rate_g_per_s(va, step_time_since_start_s(t)[still])
        rate[:, still] = with_climate_load(va, plan.ambient_temp_C, at_stop)
        rpm[:, still] = np.where(off_still, 0.0, rpm[:, still])
    if effects.vehicle:
        rate[:, _still(N, columns)] += _still_effects_fuel(va, t, columns, effects)
    rate[:, columns] = out.fuel_rate_g_per_s
    rpm[:, columns] = out.engine_speed_rpm
    rate[:, off] = 0.0
    rpm[:, off] = 0.0
    return rate, rpm


def _phased_fuel(va, t, columns, out, effects, plan):
    """A composed cycle's fuel: every step, engine-off soaks, the cold-start pass
    (thermal.py), sums per phase. Returns total fuel [g] (V,), fuel [g] and miles per phase
    (V, phases), the cold-start fuel rate and the engine temperature (V, N); a traced pass's
    ``out`` fuel rate gets the cold-start fuel."""
    V, N = va.n, t.size
    dt_all = np.concatenate([[0.0], np.diff(t)])
    rate, rpm = _every_step(va, t, columns, out, effects, plan)
    cold, temp = cold_start_extra_fuel(va, rate, rpm, dt_all, plan.step_soak_s, plan.start_temp_C,
                                       plan.ambient_temp_C, plan.constants)
    rate += cold
    if columns is None:  # the traced pass's fuel rate, in place
        np.add(out.fuel_rate_g_per_s, cold, out=out.fuel_rate_g_per_s)
    step_m = np.zeros((V, N))
    step_m[:, np.arange(N) if columns is None else columns] = out.v_avg * out.dt
    step_fuel = rate * dt_all
    return (step_fuel.sum(axis=1), _sum_by_phase(step_fuel, plan), _sum_by_phase(step_m, plan) / METERS_PER_MILE,
            cold, temp)


def _sum_by_phase(per_step, plan):
    """Sums (V, phases) of a per-step quantity (V, N) over each phase's steps."""
    index = plan.step_phase
    return np.stack([per_step[:, index == k].sum(axis=1) for k in range(len(plan.phases))], axis=1)


def _thermal_trace(V, N, plan, cold, temp):
    """The trace's phase, engine temperature and cold-start fuel columns (a plain cycle: no
    phase name, a warm engine, no extra fuel)."""
    if plan is None:
        return {"phase": np.full((V, N), ""), "engine_temp_C": np.full((V, N), thermal_constants().thermostat_temp_C),
                "cold_start_fuel_g_per_s": np.zeros((V, N))}
    names = np.array([p.name for p in plan.phases] + [""])   # index -1: the soak, no phase
    return {"phase": np.broadcast_to(names[plan.step_phase], (V, N)), "engine_temp_C": temp,
            "cold_start_fuel_g_per_s": cold}


def phase_results(plan: ThermalPlan, sums: BlockSums, density_kg_per_L):
    """A composed cycle's results per phase (miles, fuel_g, fuel_gal, mpg), the composite's
    name and its miles, fuel_g, fuel_gal and mpg: the cycle's miles driven, and fuel at the
    composite rate per mile (:func:`fleetrun.cycles.composite_per_mile`, for the FTP EPA's bag
    weighting, 40 CFR 86.144), so that ``mpg = miles / fuel_gal`` is the composite mpg and
    fuel per mile is what a budget multiplies by miles.

    Parameters
    ----------
    plan : ThermalPlan, the composed cycle's phases and composite
    sums : BlockSums, per-vehicle sums of fuel [g] and miles per phase
    density_kg_per_L : float or array, fuel density per vehicle [kg/L]

    Returns
    -------
    (dict of PhaseResult by phase name (miles, fuel [g], fuel [gal], mpg), the composite's name,
    dict of the cycle's miles, fuel_g [g], fuel_gal [gal] and mpg per vehicle).
    """
    to_gal = 1.0 / (1000.0 * np.asarray(density_kg_per_L, float) * LITERS_PER_GALLON)
    fuel, miles, phases = {}, {}, {}
    for k, phase in enumerate(plan.phases):
        fuel[phase.name], miles[phase.name] = sums.phase_fuel_g[:, k], sums.phase_miles[:, k]
        with np.errstate(divide="ignore", invalid="ignore"):
            mpg = np.where(fuel[phase.name] > 0, miles[phase.name] / (fuel[phase.name] * to_gal), np.nan)
        phases[phase.name] = PhaseResult(miles=miles[phase.name], fuel_g=fuel[phase.name],
                                         fuel_gal=fuel[phase.name] * to_gal, mpg=mpg)
    with np.errstate(divide="ignore", invalid="ignore"):
        grams_per_mile = composite_per_mile(plan.composite, fuel, miles)
        total_miles = sum(miles.values()) if miles else sums.miles
        fuel_g = grams_per_mile * total_miles
        fuel_gal = fuel_g * to_gal
        mpg = np.where(fuel_gal > 0, total_miles / fuel_gal, np.nan)
    return phases, plan.composite, dict(miles=total_miles, fuel_g=fuel_g, fuel_gal=fuel_gal, mpg=mpg)
