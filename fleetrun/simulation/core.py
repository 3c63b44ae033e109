"""Backward drive-cycle simulation over many vehicles at once (thesis Ch. 1-3, 6, 7).

Per step, from the wheels back to the fuel (arrays are vehicles x steps):

1. kinematics (``kinematics``): step i covers [t_{i-1}, t_i]; mean speed, acceleration, mean grade;
2. road load + inertia + grade (``wheel_demand``) -> tractive force -> wheel torque and speed (tyre radius);
3. gear (``gear_choice``; shift schedule, incl. the two-speed axle range) -> differential input speed;
4. differential (``differential``): invert the thesis model for the input torque (direct / map2d / map3d);
5. gearbox (``gearbox``; constant mesh efficiency), torque converter or clutch
   (``converter_or_clutch``) -> engine speed, torque;
6. engine (``engine``): full load, motoring, fuel (engine.py), idle fuel at standstill, fuel cut-off
   on overrun.

A vehicle whose engine cannot deliver the demanded torque is re-driven forward at its
maximum tractive effort (it follows the trace as closely as it can, re-joining it when the
trace slows down); the backward pass is then repeated on the achieved speed and the
shortfall is reported. Every step is independent given the speed, so the whole fleet x cycle
is a handful of array operations (no per-step Python loop unless a vehicle falls behind).
"""
from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from fleetrun.simulation import bounds, climate, diffmodes
from fleetrun.simulation.effects import (CycleEffects, differential_extra_torque_Nm, step_time_since_start_s,
                                         vehicle_extra_fuel_g_per_s)
from fleetrun.simulation.engine import (fuel_coefficients, fuel_power_terms_W, fuel_rate_g_per_s,
                                        full_load_torque_Nm, load_fraction, mean_piston_speed_m_s, motoring_torque_Nm)
from fleetrun.simulation.params import VehicleArrays
from fleetrun.simulation.records import StepResults, Trace
from fleetrun.simulation.road_load import coastdown_force_N, grade_force_factors, tractive_force_N
from fleetrun.simulation import technology as tech
from fleetrun.simulation.transmission import (choose_gear, converter_speed_ratio, converter_unlocked, cvt_ratio,
                                              input_torque_Nm, spin_loss_Nm, torque_ratio)
from fleetrun.units import RPM_PER_RAD_S

FOLLOW_TOL_MPS = 0.1                 # achieved speed below trace by more than this = not followed
DRIVETRAIN_GUESS = 0.88              # engine -> wheel efficiency used only to pick the gear
N_POWER_TABLE = 65
ACCEL_SHIFT_MPS2 = 0.1               # steps accelerating faster than this use shift_speed_accel_rpm
NUMPY_BUFFER_DEFAULT = 8192          # numpy's own ufunc buffer size (elements)


@contextmanager
def row_buffers(steps: int):
    """numpy's ufunc buffer set to about one row of ``steps`` elements for the arrays of a
    block (vehicles x steps), restored afterwards.

    With numpy's default buffer (8,192 elements) an operation between a (V, N) array and a
    per-vehicle (V, 1) or per-step (1, N) one is copied through the buffer several rows at a
    time, and runs at about half the speed of the same operation on two (V, N) arrays
    (numpy 2.4: 30 us instead of 16 us for 64 x 1,120 elements, a (V, 1) x (1, N) outer
    product 35 us instead of 11 us). With a buffer of at most one row, numpy runs the rows
    in place. Each element is computed the same way either way, so the results are the same
    bit for bit; reductions over same-type arrays are not buffered (docs/benchmarks-simulation.md).

    Parameters
    ----------
    steps : int, the length of the rows (steps per vehicle) the block's arrays have

    Returns
    -------
    a context manager (nothing is yielded).
    """
    size = min(NUMPY_BUFFER_DEFAULT, max(16, int(steps) // 16 * 16))   # numpy wants a multiple of 16
    old = np.setbufsize(size)
    try:
        yield
    finally:
        np.setbufsize(old)


def power_speed_table(va: VehicleArrays) -> np.ndarray:
    """Engine speed at which full-load power reaches p x P_rated, p on a uniform 0..1 grid (V, 65).

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters (engine speeds in [rpm], torque in [N m], power in [kW])

    Returns
    -------
    engine speed [rpm], shape (V, N_POWER_TABLE).
    """
    # rows depend on the engine only: compute each distinct engine once (fleets repeat types)
    engines = np.column_stack([va.n_idle, va.n_rated, va.T_peak, va.P_rated_kW, va.n_peak_torque, va.idle_T_frac])
    if va.n > 1 and np.isfinite(engines).all():
        _, first, inverse = np.unique(engines, axis=0, return_index=True, return_inverse=True)
        if first.size < va.n:
            return power_speed_table(va.subset(first))[inverse.reshape(-1)]
    x = np.linspace(0.0, 1.0, 257)[None, :]
    col = lambda a: a[:, None]  # noqa: E731
    n = col(va.n_idle) + x * col(va.n_rated - va.n_idle)
    T = full_load_torque_Nm(n, col(va.T_peak), col(va.P_rated_kW), col(va.n_rated), col(va.n_idle),
                            col(va.n_peak_torque), col(va.idle_T_frac))
    p = np.maximum.accumulate(T * n / RPM_PER_RAD_S / col(va.P_rated_kW * 1e3), axis=1)
    p_grid = np.linspace(0.0, 1.0, N_POWER_TABLE)
    # p is non-decreasing per row: count of grid points below each target = its index. Counted
    # as: each point lies below the targets from the first one above it on (a cumulative count)
    width = p_grid.size + 1
    first_above = np.searchsorted(p_grid, p.reshape(-1), side="right").reshape(p.shape)
    counts = np.bincount((first_above + np.arange(va.n)[:, None] * width).reshape(-1), minlength=va.n * width)
    idx = np.clip(np.cumsum(counts.reshape(va.n, width), axis=1)[:, :p_grid.size], 1, x.size - 1)
    rows = np.arange(va.n)[:, None]
    p0, p1 = p[rows, idx - 1], p[rows, idx]
    n0, n1 = n[rows, idx - 1], n[rows, idx]
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.clip(np.where(p1 > p0, (p_grid[None, :] - p0) / (p1 - p0), 1.0), 0.0, 1.0)
    return n0 + w * (n1 - n0)


def _lookup_rows(table, rows, frac):
    """Row-wise linear lookup on a uniform 0..1 grid: table[rows](frac); ``frac`` (a float
    array) is overwritten. The cell index is kept as a float (whole numbers, exact) until the
    gather: trunc(x) is the integer part int(x) gives for x >= 0, so the weight x - i is the same."""
    m = table.shape[1] - 1
    x = np.clip(frac, 0.0, 1.0, out=frac)
    x *= m
    i = np.trunc(x)
    bounds.minimum(i, m - 1.0, out=i)
    w = x - i
    flat = table.reshape(-1)
    i += rows * (m + 1.0)
    base = i.astype(np.intp)
    lo = flat.take(base)
    base += 1
    hi = flat.take(base)
    hi -= lo
    hi *= w
    hi += lo            # lo + w (hi - lo)
    return hi


class DifferentialSolver:
    """Input torque of the differential's thesis chain (the baseline, without effects) for given
    output torque and input speed, any mode."""

    def __init__(self, va: VehicleArrays, mode, physics, ambient_temp_C, cache_dir):
        self.va, self.mode, self.physics = va, mode, physics
        self.ambient = ambient_temp_C
        self.low = np.where(va.low_ratio > 1.0, va.low_ratio, np.nan)
        if mode != "direct":
            self.maps, self.map_id, self.n_max = diffmodes.vehicle_maps(
                va.configuration, va.final_drive, self.low, mode, physics, ambient_temp_C, cache_dir, va.kim_torque_scale_Nm)

    def subset(self, rows, va_subset: VehicleArrays | None = None) -> "DifferentialSolver":
        """The solver for the vehicles ``rows``; ``va_subset``: ``self.va.subset(rows)`` if the
        caller has it already."""
        other = object.__new__(DifferentialSolver)
        other.__dict__.update(self.__dict__)
        other.va = self.va.subset(rows) if va_subset is None else va_subset
        other.low = self.low[rows]
        if self.mode != "direct":
            other.map_id = self.map_id[rows]
        return other

    def input_fraction_2d(self, out_frac, speed_rpm, axle_low, active):
        """T_in / kim (V, N) for the (V, N) arrays; only ``active`` steps are meaningful.

        The maps are looked up for every step (cheaper than gathering the active ones); the
        direct model is called for the active steps only.
        """
        V, N = out_frac.shape
        if self.mode != "direct":
            # per vehicle (V, 1), broadcast against the steps inside the lookup
            map_id = self.map_id[:, None]
            n_max = self.n_max[self.map_id][:, None]
            ranges = axle_low if self.va.combo_axle_low.any() else 0   # no two-speed axle: the high range
            return diffmodes.interp_maps(self.maps, n_max, map_id, ranges, out_frac, speed_rpm, per_step=True)
        result = np.zeros((V, N))
        idx = np.flatnonzero(active)
        rows = np.broadcast_to(np.arange(V)[:, None], (V, N)).reshape(-1)[idx]
        result.reshape(-1)[idx] = self.input_fraction(out_frac.reshape(-1)[idx], speed_rpm.reshape(-1)[idx], rows,
                                                      axle_low.reshape(-1)[idx])
        return result

    def input_fraction(self, out_frac, speed_rpm, vehicle, axle_low):
        """T_in / kim for T_out / (kim G_tot) = ``out_frac`` >= 0 (flat arrays)."""
        if self.mode != "direct":
            return diffmodes.interp_maps(self.maps, self.n_max, self.map_id[vehicle], axle_low.astype(np.intp),
                                         out_frac, speed_rpm)
        result = np.empty(out_frac.shape)
        cfgs = np.array(self.va.configuration)
        # one model call per configuration, axle range and (for physics in absolute torque) Kim
        # scale: the model itself takes scalar scales but arrays of gear ratios
        scales = np.array([diffmodes.map_torque_scale_Nm(self.physics, k) for k in self.va.kim_torque_scale_Nm], dtype=object)
        for cfg in np.unique(cfgs[vehicle]) if vehicle.size else ():
            for scale in dict.fromkeys(scales[vehicle][cfgs[vehicle] == cfg]):
                for low_range in (False, True):
                    sel = np.flatnonzero((cfgs[vehicle] == cfg) & (scales[vehicle] == scale) & (axle_low == low_range))
                    if sel.size == 0:
                        continue
                    vv = vehicle[sel]
                    low = self.low[vv]
                    result[sel] = diffmodes.invert_direct(
                        cfg, out_frac[sel], speed_rpm[sel], self.va.final_drive[vv],
                        None if np.isnan(low).all() else low, low_range, self.physics, self.ambient, scale)
        return result


def engine_fuel_rate_g_per_s(va: VehicleArrays, torque_Nm, speed_rpm, max_torque_Nm, fueled, inertial_power_W=0.0,
                             col=lambda a: a, moving=True, piston_speed_m_s=None):
    """The fuel equation (engine.py) with each vehicle's constants and technology classes;
    ``col`` shapes the (V,) parameters against ``torque_Nm`` (e.g. ``a[:, None]`` for vehicles
    x steps arrays).

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    torque_Nm : float or array, engine brake torque [N m]
    speed_rpm : float or array, engine speed [rpm]
    max_torque_Nm : float or array, full-load torque at ``speed_rpm`` [N m]
    fueled : bool or array, False where fuel is cut off
    inertial_power_W : float or array, the vehicle's inertial power m_eff a v [W] (transient term)
    col : callable, shapes a (V,) parameter against ``torque_Nm``
    moving : bool or array, the vehicle moves (cylinder deactivation)
    piston_speed_m_s : array or None, the mean piston speed at ``speed_rpm`` [m/s] if the caller has it

    Returns
    -------
    fuel rate [g/s], the shape of ``torque_Nm``.
    """
    positive = bounds.maximum(torque_Nm, 0.0)   # max(T, 0), once for every term that takes it
    pumping, gain, load = _technology_fuel_inputs(va, torque_Nm, speed_rpm, max_torque_Nm, moving, col, positive)
    terms = fuel_power_terms_W(torque_Nm, speed_rpm, max_torque_Nm, col(va.displacement_L), col(va.stroke_m),
                               col(va.T_peak), col(va.throttled), inertial_power_W, pumping, gain, load, positive,
                               piston_speed_m_s)
    return fuel_rate_g_per_s(terms, fuel_coefficients(*(col(c) for c in va.fuel_constants.T)), fueled, col(va.lhv))


def has_technology(va: VehicleArrays) -> bool:
    """Whether any vehicle of ``va`` has a technology class (simulation/technology.py).

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters

    Returns
    -------
    bool.
    """
    return va.technology is not None and bool(va.technology.any())


def _flag(va: VehicleArrays, name: str) -> np.ndarray:
    return va.technology[:, tech.TECHNOLOGIES.index(name)]


# _rows_with's answers for the technology arrays of the last blocks, by id, each with the array
# itself (so that the id is not reused while the entry lives)
_ROWS_SEEN: dict = {}


def _rows_with(va: VehicleArrays, *names: str):
    """Indices of the vehicles that have any of the technology classes ``names`` (a full slice
    when all have: no copies); remembered per technology array (a block asks several times)."""
    key = (id(va.technology), names)
    seen = _ROWS_SEEN.get(key)
    if seen is not None and seen[0] is va.technology:
        return seen[1]
    rows = np.flatnonzero(np.logical_or.reduce([_flag(va, name) for name in names]))
    rows = slice(None) if rows.size == va.n else rows
    if len(_ROWS_SEEN) > 64:
        _ROWS_SEEN.clear()
    _ROWS_SEEN[key] = (va.technology, rows)
    return rows


def _any(rows) -> bool:
    return isinstance(rows, slice) or rows.size > 0


def _pick(va: VehicleArrays, a, rows):
    """``a`` for the vehicles ``rows`` when it has one row per vehicle, else ``a`` (a shared row or scalar)."""
    a = np.asarray(a)
    return a[rows] if a.ndim and a.shape[0] == va.n else a


def technology_fuel_inputs(va: VehicleArrays, torque_Nm, speed_rpm, max_torque_Nm, moving=True, col=lambda a: a):
    """The throttle-pumping share and brake-work multiplier of each vehicle's technology
    classes (simulation/technology.py) for :func:`engine.fuel_power_terms_W`; (None, None)
    when no vehicle has any. Each class is evaluated on its own vehicles' rows only.

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    torque_Nm : float or array, engine brake torque [N m]
    speed_rpm : float or array, engine speed [rpm]
    max_torque_Nm : float or array, full-load torque [N m]
    moving : bool or array, the vehicle moves
    col : callable, shapes a (V,) parameter against ``torque_Nm``

    Returns
    -------
    (throttle-pumping share [-], brake-work multiplier [-]) or (None, None).
    """
    return _technology_fuel_inputs(va, torque_Nm, speed_rpm, max_torque_Nm, moving, col)[:2]


def _technology_fuel_inputs(va: VehicleArrays, torque_Nm, speed_rpm, max_torque_Nm, moving=True, col=lambda a: a,
                            positive_torque_Nm=None):
    """:func:`technology_fuel_inputs` and the load fraction it used (engine.load_fraction; None
    without technology classes), for the fuel equation not to compute it again;
    ``positive_torque_Nm``: max(T, 0) if the caller has it. A class on every vehicle updates
    the share in place."""
    if not has_technology(va):
        return None, None, None
    c = tech.technology_constants()
    positive = bounds.maximum(torque_Nm, 0.0) if positive_torque_Nm is None else positive_torque_Nm
    load = load_fraction(torque_Nm, max_torque_Nm, positive)
    rows = _rows_with(va, "turbo")
    if isinstance(rows, slice):   # every vehicle boosted: no (1 - L) to overwrite
        share = tech.boosted_pumping_share(torque_Nm, col(va.displacement_L), c.na_bmep_kPa, positive)
    else:
        share = 1.0 - load
        if rows.size:
            share[rows] = tech.boosted_pumping_share(_pick(va, torque_Nm, rows), col(va.displacement_L[rows]),
                                                     c.na_bmep_kPa, _pick(va, positive, rows))
    rows = _rows_with(va, "atkinson", "miller")
    if isinstance(rows, slice):
        tech.atkinson_pumping_share(share, c.pumping_retained, out=share)
    elif rows.size:
        share[rows] = tech.atkinson_pumping_share(share[rows], c.pumping_retained)
    rows = _rows_with(va, "cylinder_deactivation")
    if _any(rows):
        every = isinstance(rows, slice)
        deactivated = tech.deactivated_pumping_share(share[rows], load[rows], _pick(va, speed_rpm, rows),
                                                     _pick(va, moving, rows), c.deac_max_load, c.deac_min_rpm,
                                                     c.deac_max_rpm, out=share if every else None)
        if not every:
            share[rows] = deactivated
    gain = np.ones(va.n)
    for name, ratio in (("atkinson", c.compression_ratio_atkinson), ("miller", c.compression_ratio_miller)):
        gain = np.where(_flag(va, name), tech.expansion_ratio_gain(ratio, c.compression_ratio_base, c.gamma), gain)
    return share, col(gain), load


def technology_engine_state(va: VehicleArrays, k: "Kinematics", engine_torque, engine_rpm, drive, wheel_power):
    """Hybrids' assist (engine torque after the e-machine's share of the positive work) and the
    steps with the engine off (one mask): start-stop at warm stops, hybrids also while coasting.

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    k : Kinematics, the step motion (:func:`kinematics`)
    engine_torque : array, engine torque [N m], (V, N); the caller's own array, overwritten
        with the assist (:func:`engine` passes its fresh min(T, T_max))
    engine_rpm : array, engine speed [rpm], (V, N)
    drive : bool or array, the driveline pulls, (V, N)
    wheel_power : float or array, tractive power at the wheels [W], (V, N)

    Returns
    -------
    (engine torque after the hybrid assist [N m] (V, N), engine-off mask (V, N)).
    """
    c = tech.technology_constants()
    hybrid = _flag(va, "mild_hybrid_48v") | _flag(va, "p2_hybrid")
    torque = engine_torque
    rows = _rows_with(va, "mild_hybrid_48v", "p2_hybrid")
    if _any(rows):
        motor_W = np.where(_flag(va, "p2_hybrid")[rows], c.motor_power_p2_W, c.motor_power_48v_W)
        dt = _pick(va, k.dt, rows)
        power = _pick(va, np.broadcast_to(wheel_power, engine_torque.shape), rows)
        own = engine_torque[rows]
        if k.sequential and isinstance(rows, slice):   # every vehicle: sums step after step (step_sums)
            power, own = np.asfortranarray(power), np.asfortranarray(own)
        recovered = tech.recovered_braking_energy_J(power, dt, motor_W, c.round_trip_efficiency)
        positive = bounds.maximum(own, 0.0)     # the engine's positive work over the cycle, in place:
        positive *= engine_rpm[rows]
        positive /= RPM_PER_RAD_S
        positive *= dt
        positive = positive.sum(axis=1)
        keep = 1.0 - tech.assist_share(recovered, positive, c.max_assist_share)
        np.multiply(own, keep[:, None], out=own, where=own > 0)   # the assist, in place
        if isinstance(rows, slice):   # every vehicle a hybrid: ``own`` is the torque (a view or copy)
            torque = own
        else:                         # ``own``: a copy of the rows, written back
            engine_torque[rows] = own
    off = tech.engine_off_coasting(k.moving, drive)
    if not (hybrid.all() and off.shape == engine_torque.shape):   # & True changes nothing
        off = _col(hybrid) & off
    if not k.all_moving:   # (at standstill start-stop's stops; none when every step moves)
        off |= _col(_flag(va, "start_stop") | hybrid) & tech.engine_off_at_stop(k.moving, k.since_start,
                                                                                c.inhibit_after_cold_start_s)
    return torque, off


def standstill_fuel_rate_g_per_s(va: VehicleArrays, time_since_start_s):
    """Fuel rate (V, n) at standstill at the times ``time_since_start_s`` (n,) and the
    engine-off mask: idle fuel, or under start-stop (and hybrids) once warm the fitted stop power.

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    time_since_start_s : array, time since the cycle's start [s], (n,)

    Returns
    -------
    (fuel rate [g/s] (V, n), engine-off mask (V, n)).
    """
    c = tech.technology_constants()
    stops = (_flag(va, "start_stop") | _flag(va, "mild_hybrid_48v") | _flag(va, "p2_hybrid"))[:, None]
    off = stops & tech.engine_off_at_stop(np.zeros(np.shape(time_since_start_s), bool), time_since_start_s,
                                          c.inhibit_after_cold_start_s)[None, :]
    rate = np.where(off, c.stop_fuel_power_W / (va.lhv[:, None] * 1e3), idle_fuel_rate_g_per_s(va)[:, None])
    return rate, off


def engine_motoring_torque_Nm(va: VehicleArrays, speed_rpm, col=lambda a: a, throttled=None, piston_speed_m_s=None):
    """Each vehicle's motoring torque (engine.motoring_torque_Nm) at ``speed_rpm``;
    ``throttled=False``: the friction alone (no closed-throttle pumping).

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    speed_rpm : float or array, engine speed [rpm]
    col : callable, shapes a (V,) parameter against ``speed_rpm``
    throttled : bool or array or None, closed-throttle pumping (None: spark-ignition rows)
    piston_speed_m_s : array or None, the mean piston speed at ``speed_rpm`` [m/s] if the caller has it

    Returns
    -------
    motoring torque T_0 [N m] (positive), the shape of ``speed_rpm``.
    """
    c = va.fuel_constants
    return motoring_torque_Nm(speed_rpm, col(va.displacement_L), col(va.stroke_m), col(va.T_peak), col(c[:, 2]),
                              col(c[:, 3]), col(c[:, 4]), col(c[:, 5]),
                              col(va.throttled) if throttled is None else throttled, piston_speed_m_s)


def idle_fuel_rate_g_per_s(va: VehicleArrays) -> np.ndarray:
    """Fuel rate at standstill (V,): ``idle_fuel_g_per_s`` if given, else the fuel equation at
    idle speed and zero load. Computed once per ``va`` (kept in ``va.idle_fuel_rate``, which
    its subsets carry; the vehicles' parameters do not change during a simulation).

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters

    Returns
    -------
    idle fuel rate [g/s], shape (V,).
    """
    if va.idle_fuel_rate is None:
        t_max = full_load_torque_Nm(va.n_idle, va.T_peak, va.P_rated_kW, va.n_rated, va.n_idle, va.n_peak_torque,
                                    va.idle_T_frac)
        idle = engine_fuel_rate_g_per_s(va, np.zeros(va.n), va.n_idle, t_max, True)
        va.idle_fuel_rate = np.where(np.isfinite(va.idle_fuel_g_s), va.idle_fuel_g_s, idle)
    return va.idle_fuel_rate


@dataclass(frozen=True, eq=False)
class Kinematics:
    """Per-step motion of one backward pass: step i covers [t_{i-1}, t_i] (vehicles x steps,
    or 1 x steps when every vehicle drives the same speeds; quantities of time only are 1 x
    steps)."""

    dt: np.ndarray
    grade: np.ndarray            # mean grade of the step [%]
    since_start: np.ndarray      # time since the cycle started (the effects' cold start)
    v_avg: np.ndarray
    accel: np.ndarray
    moving: np.ndarray
    all_moving: bool             # then the standstill cases are skipped (they would be no-ops)
    sequential: bool = False     # per-vehicle sums over the steps add step after step (step_sums)

    def at_rest(self, a, value):
        """``a`` where the vehicle moves, ``value`` at standstill."""
        return a if self.all_moving else np.where(self.moving, a, value)


def step_sums(a, k: Kinematics) -> np.ndarray:
    """Per-vehicle sums (V,) over the steps of a (V, steps) array of the pass ``k``: numpy's
    row sum (pairwise), or, in a pass over several vehicles' own speeds (``k.sequential``),
    added step after step: the order in which numpy summed these arrays when the pass laid
    them out column by column (as gathering the steps' columns of the speeds does), kept so
    that no figure changes (docs/simulation.md, "How it is computed").

    Parameters
    ----------
    a : array (V, steps), a per-step quantity [any unit]
    k : Kinematics, the pass's step motion

    Returns
    -------
    array (V,), the sums [the unit of ``a`` x steps].
    """
    return np.asfortranarray(a).sum(axis=1) if k.sequential else a.sum(axis=1)   # column by column: in order


def kinematics(time_s, speed_mps, grade_pct, columns=None) -> Kinematics:
    """Mean speed, acceleration and mean grade of each step; ``columns``: only these steps.

    Parameters
    ----------
    time_s : array, the cycle's time stamps [s], (N,)
    speed_mps : array, vehicle speed at each time stamp [m/s], (V, N) or (1, N)
    grade_pct : array, road grade at each time stamp [%], (N,)
    columns : array of int or None, the steps to compute (None: all)

    Returns
    -------
    Kinematics, dt [s], mean grade [%], time since start [s], mean speed [m/s], acceleration
    [m/s^2] and the moving mask per step.
    """
    N = speed_mps.shape[1]
    dt = np.concatenate([[0.0], np.diff(time_s)])[None, :]
    inv_dt = np.concatenate([[0.0], 1.0 / np.diff(time_s)])[None, :]  # step 0 has no time
    g_prev = np.concatenate([grade_pct[:1], grade_pct[:-1]])
    grade = (0.5 * (grade_pct + g_prev))[None, :]
    since_start = step_time_since_start_s(time_s)
    # the previous step's index per step (step 0: itself)
    prev_index = np.concatenate([[0], np.arange(N - 1)])
    sequential = False
    if columns is not None:
        # only the steps asked for (the same element-wise arithmetic on fewer columns)
        dt, inv_dt, grade = dt[:, columns], inv_dt[:, columns], grade[:, columns]
        since_start = since_start[columns]
        v_now, v_prev = _step_speeds(speed_mps, columns, prev_index)
        # several vehicles' own speeds: their sums add step after step (step_sums)
        sequential = speed_mps.shape[0] > 1
    else:
        v_now = speed_mps
        v_prev = speed_mps[:, prev_index]
    v_avg = 0.5 * (v_now + v_prev)
    accel = (v_now - v_prev) * inv_dt
    moving = v_avg > 1e-6
    return Kinematics(dt, grade, since_start, v_avg, accel, moving, bool(moving.all()), sequential)


def _step_speeds(speed_mps, columns, prev_index):
    """The speeds at the end and at the start of the steps ``columns`` (ascending), laid out
    row by row (vehicles x steps, as the rest of the pass): views for consecutive steps after
    the first, else the gathered columns."""
    if speed_mps.shape[0] > 1 and columns.size and columns[0] >= 1 and (np.diff(columns) == 1).all():
        return speed_mps[:, columns[0]:columns[-1] + 1], speed_mps[:, columns[0] - 1:columns[-1]]
    if speed_mps.shape[0] > 1:
        return np.take(speed_mps, columns, axis=1), np.take(speed_mps, prev_index[columns], axis=1)
    return speed_mps[:, columns], speed_mps[:, prev_index[columns]]


def trace_kinematics(trace: Trace) -> Kinematics:
    """The step motion (dt, mean speed, acceleration, moving; (V, N)) of a simulated trace,
    as the backward pass computed it: for checks of the per-step physics against the trace.

    Parameters
    ----------
    trace : Trace, a simulated trace (fleetrun.simulation.records)

    Returns
    -------
    Kinematics, as :func:`kinematics` gives it for the trace's achieved speeds.
    """
    return kinematics(trace.time_s[0], np.asarray(trace.vehicle_speed_mps), trace.grade_pct[0])


def _col(a):
    return a[:, None]


def wheel_demand(va: VehicleArrays, k: Kinematics):
    """Road load + inertia + grade (road_load.py) -> tractive force, wheel torque and speed.

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters (mass in [kg], road load A, B, C in SI units
        [N], [N s/m], [N s^2/m^2], tyre radius in [m])
    k : Kinematics, the step motion (:func:`kinematics`)

    Returns
    -------
    (tractive force [N], wheel torque [N m], wheel speed [rad/s], wheel speed [rpm]), each (V, N).
    """
    force = tractive_force_N(k.v_avg, k.accel, k.grade, _col(va.mass_kg), _col(va.rot_frac), _col(va.A_N),
                             _col(va.B_N), _col(va.C_N))
    force = k.at_rest(force, 0.0)  # at standstill the brakes hold the vehicle
    r = _col(va.radius_m)
    wheel_omega = k.v_avg / r
    return force, force * r, wheel_omega, wheel_omega * RPM_PER_RAD_S


def gear_choice(va: VehicleArrays, k: Kinematics, force, wheel_rpm):
    """Gear (and axle range): lowest engine speed with power reserve (transmission.py).

    Returns the transmission ratio, low axle range, gearbox efficiency and gear number per step.

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    k : Kinematics, the step motion (:func:`kinematics`)
    force : array, tractive force [N], (V, N)
    wheel_rpm : array, wheel speed [rpm], (V, N)

    Returns
    -------
    (transmission ratio [-], low axle range (bool), gearbox efficiency [-], gear number (0 at
    standstill)), each (V, N).
    """
    p_need = force * k.v_avg
    bounds.maximum(p_need, 0.0, out=p_need)
    p_need /= DRIVETRAIN_GUESS
    rows = np.arange(va.n)[:, None]
    # speed at which reserve x full-load power reaches the power needed (rated speed beyond)
    if va.power_table is None:
        va.power_table = power_speed_table(va)
    p_need /= _col(va.power_reserve * va.P_rated_kW * 1e3)
    n_req = _lookup_rows(va.power_table, rows, p_need)  # n_power, then clamped in place:
    np.maximum(_col(va.shift_min_rpm), n_req, out=n_req)
    _hold_while_accelerating(va, k, n_req)
    np.minimum(n_req, _col(va.n_rated), out=n_req)
    overall = va.combo_trans_ratio * np.where(va.combo_axle_low, va.low_ratio[:, None], 1.0)
    choice = choose_gear(wheel_rpm * _col(va.final_drive), n_req, _col(va.n_rated), overall, va.n_combos)
    flat_k = rows * overall.shape[1] + choice
    trans_ratio = va.combo_trans_ratio.reshape(-1).take(flat_k)
    axle_low = va.combo_axle_low.reshape(-1).take(flat_k) if va.combo_axle_low.any() else np.zeros(flat_k.shape, bool)
    gear_eff = va.combo_gear_eff.reshape(-1).take(flat_k)
    gear = va.combo_gear.reshape(-1).take(flat_k)
    if va.cvt.any():  # a CVT meets the schedule's engine speed within its ratio range
        cvt = _col(va.cvt)
        ratio = cvt_ratio(wheel_rpm * _col(va.final_drive), n_req, _col(va.cvt_ratio_range[:, 0]),
                          _col(va.cvt_ratio_range[:, 1]))
        trans_ratio = np.where(cvt, ratio, trans_ratio)
        gear = np.where(cvt, np.where(ratio >= _col(va.cvt_ratio_range[:, 0]), 1, 2), gear)
    if not k.all_moving:
        axle_low &= k.moving
        gear = np.where(k.moving, gear, 0)
    return trans_ratio, axle_low, gear_eff, gear


def _hold_while_accelerating(va: VehicleArrays, k: Kinematics, n_req):
    """While accelerating, the schedule holds a gear up to a higher engine speed: n_req (in
    place) = max(shift_accel_rpm, n_req) in the steps accelerating faster than ACCEL_SHIFT_MPS2.
    On the trace (one row of motion for all vehicles) only those steps are touched; the
    others keep n_req, as max(0, n_req) does."""
    hold = k.accel > ACCEL_SHIFT_MPS2
    if hold.shape[0] == 1 and n_req.shape[0] > 1:
        steps = np.flatnonzero(hold[0])
        part = n_req[:, steps]
        n_req[:, steps] = np.maximum(_col(va.shift_accel_rpm), part, out=part)
    else:   # max(0.0, n_req) is n_req: n_req is at least the power table's speed, >= idle >= +0
        np.maximum(_col(va.shift_accel_rpm), n_req, out=n_req, where=hold)


def differential(va: VehicleArrays, k: Kinematics, solver: DifferentialSolver, effects: CycleEffects,
                 wheel_torque, wheel_rpm, axle_low, efficiency: bool = True):
    """The differential backwards: input speed, input torque and step efficiency (None
    without ``efficiency``).

    The thesis chain is inverted by ``solver`` (any mode); the ``--with`` effects add their
    extra pinion torque on the drive-side input at |T_out| (so on overrun the drags still take
    energy from the flow and J dw/dt keeps its sign).

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    k : Kinematics, the step motion (:func:`kinematics`)
    solver : DifferentialSolver, the thesis chain's inversion in the run's mode
    effects : CycleEffects, the ``--with`` effects (fleetrun/simulation/effects.py)
    wheel_torque : array, total wheel torque [N m], (V, N)
    wheel_rpm : array, wheel speed [rpm], (V, N)
    axle_low : array of bool, the two-speed axle's low range is engaged, (V, N)
    efficiency : bool, also return the step efficiency

    Returns
    -------
    (input speed [rpm], input torque [N m], step efficiency [-] or None), each (V, N).
    """
    if (va.low_ratio > 1.0).any():
        G_tot = _col(va.final_drive) * np.where(axle_low, _col(va.low_ratio), 1.0)
    else:  # no two-speed axle in this block
        G_tot = _col(va.final_drive)
    diff_rpm = wheel_rpm * G_tot
    kim = _col(va.kim_torque_scale_Nm)
    active = k.moving & (diff_rpm > 0)
    # T_out / (kim G_tot) with its sign: |T| / x is |T / x| and (T / x) kim is
    # copysign(|T / x| kim, T) bit for bit (IEEE rounding is symmetric in the sign)
    signed_frac = wheel_torque / (kim * G_tot)
    out_frac = np.abs(signed_frac)
    diff_loss_Nm = solver.input_fraction_2d(out_frac, diff_rpm, axle_low, active)
    diff_loss_Nm -= out_frac
    bounds.maximum(diff_loss_Nm, 0.0, out=diff_loss_Nm)
    diff_loss_Nm *= kim
    if not active.all():
        diff_loss_Nm[~active] = 0.0  # standstill: nothing turns, no loss
    out_Nm = out_frac * kim  # |T_out| / G_tot: output torque referred to the input
    if effects.differential:
        pinion_accel = k.accel / _col(va.radius_m) * G_tot
        extra_Nm = differential_extra_torque_Nm(effects, va.configuration, out_Nm + diff_loss_Nm, diff_rpm,
                                                pinion_accel, k.since_start, solver.ambient, G_tot, kim)
        diff_loss_Nm = diff_loss_Nm + np.where(active, extra_Nm, 0.0)
    diff_torque = np.multiply(signed_frac, kim, out=signed_frac)   # copysign(out_Nm, wheel_torque)
    diff_torque += diff_loss_Nm
    if not efficiency:
        return diff_rpm, diff_torque, None
    with np.errstate(divide="ignore", invalid="ignore"):
        # with inertia a decelerating pinion gives energy back: the step efficiency may exceed 1
        turning = (active & (out_Nm + diff_loss_Nm > 0)) if effects.differential else diff_loss_Nm > 0
        diff_eff = np.where(turning, out_Nm / (out_Nm + diff_loss_Nm), 0.0)
    return diff_rpm, diff_torque, diff_eff


def gearbox(va: VehicleArrays, k: Kinematics, diff_torque, diff_rpm, trans_ratio, gear_eff):
    """Gearbox input (turbine) torque and speed: mesh efficiency and spin loss (transmission.py).

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters (spin loss a [N m], b [N m per 1000 rpm])
    k : Kinematics, the step motion (:func:`kinematics`)
    diff_torque : array, differential input torque [N m], (V, N)
    diff_rpm : array, differential input speed [rpm], (V, N)
    trans_ratio : array, transmission ratio [-], (V, N)
    gear_eff : array, gearbox mesh efficiency [-], (V, N)

    Returns
    -------
    (gearbox input torque [N m], gearbox input (turbine) speed [rpm]), each (V, N).
    """
    turbine_rpm = diff_rpm * trans_ratio
    spin = spin_loss_Nm(turbine_rpm, _col(va.spin_loss[:, 0]), _col(va.spin_loss[:, 1]))
    trans_torque = k.at_rest(input_torque_Nm(diff_torque, trans_ratio, gear_eff, spin), 0.0)
    return trans_torque, turbine_rpm


def converter_or_clutch(va: VehicleArrays, k: Kinematics, trans_torque, turbine_rpm, gear):
    """Engine speed and torque behind the torque converter (automatic, CVT) or clutch (manual,
    automated manual).

    Returns engine speed, engine torque, the unlocked-converter mask and the drive mask.

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    k : Kinematics, the step motion (:func:`kinematics`)
    trans_torque : array, gearbox input torque [N m], (V, N)
    turbine_rpm : array, gearbox input (turbine) speed [rpm], (V, N)
    gear : array of int, gear number, (V, N)

    Returns
    -------
    (engine speed [rpm], engine torque [N m], unlocked-converter mask, drive mask), each (V, N).
    """
    N = trans_torque.shape[1]
    idle = _col(va.n_idle)
    auto = _col(va.automatic)
    drive = trans_torque > 0
    engine_rpm = turbine_rpm.copy()
    engine_torque = trans_torque.copy()
    if not va.automatic.any():   # no converter in this block (the masks below would be all False)
        unlocked = np.zeros(trans_torque.shape, bool)
    else:
        unlocked = auto & converter_unlocked(gear == 1, turbine_rpm, _col(va.lockup_rpm), _col(va.has_lockup))
        _converter(va, N, unlocked, drive, turbine_rpm, trans_torque, engine_rpm, engine_torque)
    if not va.automatic.all():   # manual gearboxes in this block
        _clutch(va, drive, gear, turbine_rpm, engine_rpm, engine_torque)
    if k.all_moving:
        np.maximum(engine_rpm, idle, out=engine_rpm)
    else:
        engine_rpm = np.where(k.moving, np.maximum(engine_rpm, idle), idle)
        engine_torque = np.where(k.moving, engine_torque, 0.0)
    return engine_rpm, engine_torque, unlocked, drive


def _converter(va: VehicleArrays, N, unlocked, drive, turbine_rpm, trans_torque, engine_rpm, engine_torque):
    """The torque converter (:func:`converter_or_clutch`), in place on ``engine_rpm`` and
    ``engine_torque``: the converter model where it slips, idle unloaded on overrun."""
    idle = _col(va.n_idle)
    slipping = np.flatnonzero(unlocked & drive)  # the converter model only where it slips
    if slipping.size:
        vrow = slipping // N
        nt, Tt = turbine_rpm.reshape(-1).take(slipping), trans_torque.reshape(-1).take(slipping)
        sr = converter_speed_ratio(nt, Tt, va.K_tc[vrow], va.stall_TR[vrow])
        with np.errstate(divide="ignore", invalid="ignore"):
            pump = np.maximum(np.where(sr > 0, nt / sr, va.n_idle[vrow]), va.n_idle[vrow])
        engine_rpm.reshape(-1)[slipping] = pump
        engine_torque.reshape(-1)[slipping] = Tt / torque_ratio(nt / pump, va.stall_TR[vrow])
    coasting = unlocked & ~drive  # unlocked converter on overrun: the engine idles unloaded
    np.copyto(engine_rpm, np.maximum(idle, turbine_rpm), where=coasting)
    np.copyto(engine_torque, 0.0, where=coasting)


def _clutch(va: VehicleArrays, drive, gear, turbine_rpm, engine_rpm, engine_torque):
    """Manual gearboxes (:func:`converter_or_clutch`), in place: the clutch slips at take-off
    (first gear: engine held at launch speed) and is disengaged below idle on overrun; in a
    higher gear it is closed (a heavy diesel cruises below the launch speed, which is no slip)."""
    idle = _col(va.n_idle)
    manual = ~_col(va.automatic)
    launch = _col(va.launch_rpm)
    slip = manual & drive & (gear == 1) & (turbine_rpm < launch)
    np.copyto(engine_rpm, launch, where=slip)
    declutch = manual & ~drive & (turbine_rpm < idle)
    np.copyto(engine_rpm, idle, where=declutch)
    np.copyto(engine_torque, 0.0, where=declutch)


def engine_limits(va: VehicleArrays, engine_rpm, engine_torque):
    """Full-load torque at ``engine_rpm`` (engine.py) and the steps whose demand lies above it
    (infeasible: the vehicle cannot follow the trace there).

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    engine_rpm : array, engine speed [rpm], (V, N)
    engine_torque : array, demanded engine torque [N m], (V, N)

    Returns
    -------
    (full-load torque [N m], infeasible mask), each (V, N).
    """
    t_max = full_load_torque_Nm(engine_rpm, _col(va.T_peak), _col(va.P_rated_kW), _col(va.n_rated), _col(va.n_idle),
                                _col(va.n_peak_torque), _col(va.idle_T_frac))
    return t_max, engine_torque > t_max * (1.0 + 1e-9)


def engine(va: VehicleArrays, k: Kinematics, effects: CycleEffects, engine_rpm, engine_torque, t_max, idling,
           wheel_power, drive=None):
    """Engine torque and fuel (engine.py) below the full-load torque ``t_max``
    (:func:`engine_limits`): motoring (engine braking; the rest is brakes), the fuel equation,
    idle fuel, fuel cut-off, and the vehicle-level effects' extra fuel. ``idling``: unlocked
    converter on overrun; ``drive``: the driveline pulls (technology classes: hybrids' assist
    and engine off, start-stop).

    Returns the engine torque, the fuel rate and the engine-off mask (None without technology
    classes).

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    k : Kinematics, the step motion (:func:`kinematics`)
    effects : CycleEffects, the ``--with`` effects
    engine_rpm : array, engine speed [rpm], (V, N)
    engine_torque : array, demanded engine torque [N m], (V, N)
    t_max : array, full-load torque [N m], (V, N)
    idling : array of bool, unlocked converter on overrun, (V, N)
    wheel_power : float or array, tractive power at the wheels [W], (V, N)
    drive : array of bool or None, the driveline pulls (None: engine torque > 0)

    Returns
    -------
    (engine torque [N m], fuel rate [g/s], engine-off mask or None), arrays (V, N).
    """
    c_m = mean_piston_speed_m_s(engine_rpm, _col(va.stroke_m))   # for the motoring torque and the fuel
    t_offset = engine_motoring_torque_Nm(va, engine_rpm, _col, piston_speed_m_s=c_m)
    engine_torque_fuel = np.minimum(engine_torque, t_max)
    overrun = engine_torque < 0
    # engine braking is limited to the motoring torque (friction and pumping); the brakes take
    # the rest, so the reported engine torque is never below -T_0
    engine_torque = np.maximum(engine_torque, np.negative(t_offset, out=t_offset))
    fueled = ~(overrun & (engine_rpm >= _col(va.fuel_cut_rpm)))
    inertial_W = _col(va.mass_kg * (1.0 + va.rot_frac)) * k.accel
    inertial_W *= k.v_avg
    off = None
    if has_technology(va):
        pulls = engine_torque > 0
        engine_torque_fuel, off = technology_engine_state(
            va, k, engine_torque_fuel, engine_rpm, pulls if drive is None else drive, wheel_power)
        np.copyto(engine_torque, engine_torque_fuel, where=pulls)   # engine_torque: np.maximum's own array
    fuel = engine_fuel_rate_g_per_s(va, engine_torque_fuel, engine_rpm, t_max, fueled, inertial_W, _col, k.moving, c_m)
    idle_fuel = _col(va.idle_fuel_g_s)
    if np.isfinite(idle_fuel).any():
        np.copyto(fuel, idle_fuel, where=idling & np.isfinite(idle_fuel))
    if not k.all_moving:
        fuel = np.where(k.moving, fuel, _col(idle_fuel_rate_g_per_s(va)))
    if off is not None:   # engine off: no fuel; start-stop's stops cost the fitted average power
        stop_W = tech.technology_constants().stop_fuel_power_W
        if k.all_moving:
            np.copyto(fuel, 0.0, where=off)
        else:
            fuel = np.where(off, np.where(k.moving, 0.0, stop_W / (_col(va.lhv) * 1e3)), fuel)
    if effects.vehicle:
        # extra fuel only while the engine burns fuel (idle counts; fuel cut-off does not)
        burning = ~k.moving | fueled
        fuel = np.maximum(fuel + vehicle_extra_fuel_g_per_s(effects, va, k.since_start,
                                                            np.broadcast_to(k.v_avg, fuel.shape), wheel_power,
                                                            burning), 0.0)
    return engine_torque, fuel, off


def with_climate_load(va: VehicleArrays, ambient_temp_C, fuel):
    """``fuel`` plus the A/C or cold-weather accessory load at the ambient temperature
    (fleetrun/simulation/climate.py) while the engine burns fuel; electric rows keep theirs.

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    ambient_temp_C : float, ambient temperature [C]
    fuel : array, fuel rate [g/s], (V, N)

    Returns
    -------
    fuel rate with the climate accessory load [g/s], (V, N).
    """
    power = climate.accessory_power_W(float(ambient_temp_C))
    if power == 0.0:
        return fuel
    from fleetrun.simulation.params import willans_slope

    return fuel + climate.extra_fuel_g_per_s(power, willans_slope(va), va.lhv, fuel > 0)


def idle_fuel_at_ambient_g_per_s(va: VehicleArrays, ambient_temp_C) -> np.ndarray:
    """Idle fuel (V,) [g/s] with the climate accessory load at ``ambient_temp_C``: the rate of
    the standstill steps a run without a trace does not simulate one by one.

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    ambient_temp_C : float, ambient temperature [C]

    Returns
    -------
    idle fuel rate [g/s], shape (V,).
    """
    idle = idle_fuel_rate_g_per_s(va)
    power = climate.accessory_power_W(float(ambient_temp_C))
    if power == 0.0:
        return idle
    from fleetrun.simulation.params import willans_slope

    return idle + climate.per_vehicle_fuel_g_per_s(power, willans_slope(va), va.lhv)


def _shaft_power_W(torque_Nm, speed_rpm):
    power = torque_Nm * speed_rpm
    power /= RPM_PER_RAD_S
    return power


@dataclass(frozen=True, eq=False)
class Drivetrain:
    """The first part of a backward pass (:func:`backward_drivetrain`): the step motion and
    the chain from the wheels to the engine's speed, torque and full load."""

    k: Kinematics
    force: np.ndarray
    wheel_torque: np.ndarray
    wheel_rpm: np.ndarray
    wheel_power: np.ndarray
    gear: np.ndarray
    axle_low: np.ndarray
    diff_rpm: np.ndarray
    diff_torque: np.ndarray
    diff_eff: np.ndarray | None
    trans_torque: np.ndarray
    turbine_rpm: np.ndarray
    engine_rpm: np.ndarray
    engine_torque: np.ndarray
    unlocked: np.ndarray
    drive: np.ndarray
    t_max: np.ndarray
    infeasible: np.ndarray       # demand above full load (V, steps)


def backward_drivetrain(va: VehicleArrays, time_s, speed_mps, grade_pct, solver: DifferentialSolver, columns=None,
                        effects: CycleEffects = CycleEffects(), losses: bool = True) -> Drivetrain:
    """The wheels-to-engine part of :func:`backward` (same arguments): enough to tell which
    vehicles cannot follow ``speed_mps`` (``infeasible``) before their fuel is computed.

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    time_s : array, the cycle's time stamps [s], (N,)
    speed_mps : array, vehicle speed [m/s], (V, N) or (1, N)
    grade_pct : array, road grade [%], (N,)
    solver : DifferentialSolver, the thesis chain's inversion in the run's mode
    columns : array of int or None, the steps to compute
    effects : CycleEffects, the ``--with`` effects
    losses : bool, also the differential's step efficiency

    Returns
    -------
    Drivetrain, the step motion and the wheel-to-engine chain (speeds [rpm], torques [N m],
    force [N], power [W]).
    """
    k = kinematics(time_s, speed_mps, grade_pct, columns)
    force, wheel_torque, wheel_omega, wheel_rpm = wheel_demand(va, k)
    wheel_power = wheel_torque * wheel_omega
    trans_ratio, axle_low, gear_eff, gear = gear_choice(va, k, force, wheel_rpm)
    diff_rpm, diff_torque, diff_eff = differential(va, k, solver, effects, wheel_torque, wheel_rpm, axle_low, losses)
    trans_torque, turbine_rpm = gearbox(va, k, diff_torque, diff_rpm, trans_ratio, gear_eff)
    engine_rpm, engine_torque, unlocked, drive = converter_or_clutch(va, k, trans_torque, turbine_rpm, gear)
    t_max, infeasible = engine_limits(va, engine_rpm, engine_torque)
    return Drivetrain(k, force, wheel_torque, wheel_rpm, wheel_power, gear, axle_low, diff_rpm, diff_torque, diff_eff,
                      trans_torque, turbine_rpm, engine_rpm, engine_torque, unlocked, drive, t_max, infeasible)


def backward(va: VehicleArrays, time_s, speed_mps, grade_pct, solver: DifferentialSolver, columns=None,
             effects: CycleEffects = CycleEffects(), losses: bool = True, drivetrain: Drivetrain | None = None
             ) -> StepResults:
    """One backward pass, from the wheels back to the fuel. ``speed_mps`` is (V, N) (each
    vehicle's achieved speed), or (1, N) when every vehicle drives the same speeds (then the
    motion of the steps, ``dt`` to ``moving``, is (1, N) too).

    ``columns``: compute only these steps (the caller skips steps where the whole block
    stands still); the results then have shape (V, len(columns)). ``effects``: the ``--with``
    physics (fleetrun/simulation/effects.py), on top of the thesis chain and the fuel line.
    ``losses``: also the differential's step efficiency and the power lost in the
    differential, gearbox and converter (the trace's). ``drivetrain``: the pass's
    :func:`backward_drivetrain` if the caller has it already (same arguments).

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    time_s : array, the cycle's time stamps [s], (N,)
    speed_mps : array, vehicle speed [m/s], (V, N) or (1, N)
    grade_pct : array, road grade [%], (N,)
    solver : DifferentialSolver, the thesis chain's inversion in the run's mode
    columns : array of int or None, the steps to compute
    effects : CycleEffects, the ``--with`` effects
    losses : bool, also efficiency and power losses [W]
    drivetrain : Drivetrain or None, the pass's :func:`backward_drivetrain`

    Returns
    -------
    StepResults, the per-step quantities (fleetrun.simulation.records; units in the field names).
    """
    d = drivetrain or backward_drivetrain(va, time_s, speed_mps, grade_pct, solver, columns, effects, losses)
    k, wheel_power = d.k, d.wheel_power
    engine_torque, fuel, off = engine(va, k, effects, d.engine_rpm, d.engine_torque, d.t_max, d.unlocked & ~d.drive,
                                      wheel_power, d.drive)
    engine_rpm = d.engine_rpm
    if off is not None:   # technology classes: the engine stands still while off (trace speed 0)
        engine_rpm = np.where(off, 0.0, engine_rpm)
        np.copyto(engine_torque, 0.0, where=off)   # engine()'s own array
    fuel = with_climate_load(va, solver.ambient, fuel)
    engine_power = _shaft_power_W(engine_torque, engine_rpm)
    losses_W = {}
    if losses:
        diff_in_power = _shaft_power_W(d.diff_torque, d.diff_rpm)
        turbine_power = _shaft_power_W(d.trans_torque, d.turbine_rpm)
        losses_W = dict(diff_loss_W=diff_in_power - wheel_power, transmission_loss_W=turbine_power - diff_in_power,
                        converter_loss_W=engine_power - turbine_power)
    V, N = d.wheel_torque.shape
    return StepResults(
        dt=k.dt, v_avg=k.v_avg, accel=k.accel, grade=np.broadcast_to(k.grade, (V, N)), force=d.force,
        moving=k.moving, wheel_torque_Nm=d.wheel_torque, wheel_speed_rpm=d.wheel_rpm, gear=d.gear,
        axle_low=d.axle_low, diff_input_torque_Nm=d.diff_torque, diff_input_speed_rpm=d.diff_rpm,
        diff_efficiency=d.diff_eff, transmission_input_torque_Nm=d.trans_torque,
        transmission_input_speed_rpm=d.turbine_rpm, converter_unlocked=k.at_rest(d.unlocked, False),
        engine_speed_rpm=engine_rpm, engine_torque_Nm=engine_torque, engine_max_torque_Nm=d.t_max,
        infeasible=k.at_rest(d.infeasible, False), fuel_rate_g_per_s=fuel, wheel_power_W=wheel_power,
        engine_power_W=engine_power, **losses_W,
    )


REDRIVE_SPEED_GRID = np.linspace(0.0, 70.0, 281)  # m/s, 0.25 m/s steps, beyond any cycle


def converter_stall_point(va: VehicleArrays):
    """Engine speed and torque at converter stall (V,): where (n/K)^2 meets full load.

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters (capacity factor K_tc [rpm / sqrt(N m)])

    Returns
    -------
    (engine speed [rpm], engine torque [N m]) at stall, each (V,).
    """
    x = np.linspace(0.0, 1.0, 401)[None, :]
    n = va.n_idle[:, None] + x * (va.n_rated - va.n_idle)[:, None]
    T = full_load_torque_Nm(n, va.T_peak[:, None], va.P_rated_kW[:, None], va.n_rated[:, None],
                            va.n_idle[:, None], va.n_peak_torque[:, None], va.idle_T_frac[:, None])
    gap = (n / va.K_tc[:, None]) ** 2 - T          # rises through 0 at the stall point
    i = np.argmax(gap >= 0, axis=1)
    i = np.where((gap >= 0).any(axis=1), i, x.size - 1)
    rows = np.arange(va.n)
    return n[rows, i], np.minimum((n[rows, i] / va.K_tc) ** 2, T[rows, i])


def _drivetrain_rows(va: VehicleArrays) -> np.ndarray:
    """What :func:`max_tractive_force_table` reads of each vehicle, one row per vehicle (the
    table does not depend on mass or road load)."""
    return np.column_stack([va.combo_trans_ratio, va.combo_axle_low, va.combo_gear_eff, va.combo_gear,
                            va.low_ratio, va.radius_m, va.final_drive, va.automatic, va.n_idle, va.launch_rpm,
                            va.T_peak, va.P_rated_kW, va.n_rated, va.n_peak_torque, va.idle_T_frac, va.K_tc,
                            va.stall_TR])


# each distinct drivetrain's unscaled force table (margin 1), by the bytes of its
# _drivetrain_rows row: kept for the process (a fleet run simulates the same vehicles on
# several cycles and scenarios); emptied when it holds FORCE_TABLE_CACHE_ROWS (2.2 kB each)
_FORCE_TABLE_ROWS: dict[bytes, np.ndarray] = {}
FORCE_TABLE_CACHE_ROWS = 4096


def max_tractive_force_table(va: VehicleArrays, margin=0.97):
    """Largest wheel force [N] the drivetrain can deliver, (V, len(REDRIVE_SPEED_GRID)).

    Over every gear: full-load torque at the engine speed the gear implies (clutch: at least
    the launch speed; automatics in first gear: the converter slips up to its stall point and
    multiplies the stall torque by its torque ratio), times gearbox ratio and efficiency,
    final drive and 0.95 for the axle; x ``margin``. Computed once per distinct drivetrain
    (vehicles that differ only in mass or road load share a row) and kept for the process, as
    power_speed_table does per engine: element-wise arithmetic, so the values are the same bit
    for bit.

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    margin : float, share of the full effort the driver uses [-]

    Returns
    -------
    wheel force [N], shape (V, len(REDRIVE_SPEED_GRID)) (speeds [m/s] of the grid).
    """
    names = [row.tobytes() for row in _drivetrain_rows(va)]
    if not names:
        return np.zeros((0, REDRIVE_SPEED_GRID.size))
    found, first = {}, {}
    for i, name in enumerate(names):
        if name not in found:
            row = _FORCE_TABLE_ROWS.get(name)
            if row is None:
                first.setdefault(name, i)
            else:
                found[name] = row
    if first:
        rows = _unscaled_force_table(va.subset(np.fromiter(first.values(), np.intp, len(first))))
        found.update(zip(first, rows))
        if len(_FORCE_TABLE_ROWS) + len(first) > FORCE_TABLE_CACHE_ROWS:
            _FORCE_TABLE_ROWS.clear()
        _FORCE_TABLE_ROWS.update(zip(first, rows))
    return margin * np.stack([found[name] for name in names])   # this call's rows (another thread may clear the cache)


def _unscaled_force_table(va: VehicleArrays):
    """:func:`max_tractive_force_table` at margin 1, computed for every row of ``va``."""
    v = REDRIVE_SPEED_GRID[None, :, None]
    col = lambda a: a[:, None, None]  # noqa: E731
    overall = (va.combo_trans_ratio * np.where(va.combo_axle_low, va.low_ratio[:, None], 1.0))[:, None, :]
    n_e = v / col(va.radius_m) * RPM_PER_RAD_S * overall * col(va.final_drive)
    n_stall, T_stall = converter_stall_point(va)
    first = (va.combo_gear == 1)[:, None, :]
    auto = col(va.automatic)
    T_lock = full_load_torque_Nm(np.maximum(n_e, col(np.where(va.automatic, va.n_idle, va.launch_rpm))),
                                 col(va.T_peak), col(va.P_rated_kW), col(va.n_rated), col(va.n_idle),
                                 col(va.n_peak_torque), col(va.idle_T_frac))
    T_conv = col(T_stall) * torque_ratio(n_e / col(n_stall), col(va.stall_TR))
    T = np.where(auto & first, np.maximum(np.where(n_e < col(n_stall), T_conv, 0.0), T_lock), T_lock)
    F = T * overall * col(va.final_drive) * va.combo_gear_eff[:, None, :] * 0.95 / col(va.radius_m)
    F = np.where((va.combo_trans_ratio > 0)[:, None, :], F, 0.0)
    return F.max(axis=2)


# vehicles x steps per chunk of the re-drive's all-steps trial: its ~40 temporaries of
# ~170 kB stay in the L2 cache (4x as many per chunk took twice as long, UDDS, 200 trucks)
REDRIVE_CHUNK_STEPS = 22000


@dataclass(frozen=True, eq=False)
class _EffortModel:
    """What one full-effort step needs of each vehicle (:func:`forward_redrive`), (V,) arrays
    and the sine of each step's grade (N - 1,); ``rows``: the same for some vehicles."""

    flat: np.ndarray              # the force tables x margin, one row of ``width`` per vehicle
    flat_next: np.ndarray         # flat[i + 1] at i (one index for both ends of an interval)
    base: np.ndarray              # each vehicle's first index in ``flat``
    per: np.ndarray               # (4, V): coastdown A, B, C and 1 / m_eff (one gather for a part)
    weight: np.ndarray            # m g [N] (V,): the grade force is weight x sine (road_load.py)
    sine: np.ndarray              # sin(atan(grade / 100)) of each step's mean grade (N - 1,)

    @staticmethod
    def of(flat, base, A, B, C, inv_m, weight, sine) -> "_EffortModel":
        return _EffortModel(flat, np.append(flat[1:], 0.0), base, np.stack([A, B, C, inv_m]), weight, sine)

    def part(self, rows) -> "_EffortModel":
        """The vehicles ``rows``."""
        return _EffortModel(self.flat, self.flat_next, self.base[rows], self.per[:, rows], self.weight[rows],
                            self.sine)

    def grade_force(self, steps):
        """The grade force [N] of these vehicles in ``steps`` (an index, or an array against
        ``weight``'s shape); 0.0 where every such step is level (x - 0.0 is x, bit for bit)."""
        sine = self.sine[steps]
        if not (np.any(sine) or np.signbit(sine).any()):
            return 0.0
        return self.weight * sine


def _full_effort_step(m: _EffortModel, grade_force, vp, cap, dt, dv: float, top: float):
    """Speed at the end of one or more steps from ``vp`` at their start, at full effort.

    v(i) = min(cap(i), v(i-1) + a dt), clipped at 0; a = (F(v) - coastdown(v) - grade force) / m_eff,
    F interpolated on the force table at the step's mean speed (one predictor-corrector pass,
    as the backward pass evaluates the step at its mean speed; ``grade_force`` of these
    vehicles and steps). Element-wise for any shapes that broadcast: (rows,) per-vehicle values
    in one step, or (rows, 1) against (1, steps).
    """
    A, B, C, inv_m = m.per

    def accel(v):
        x = np.minimum(v / dv, top)
        j = x.astype(np.intp)
        w = x - j
        index = m.base + j
        force = m.flat.take(index) * (1.0 - w) + m.flat_next.take(index) * w
        v = np.maximum(v, 1e-3)
        return (force - coastdown_force_N(v, A, B, C) - grade_force) * inv_m

    guess = np.maximum(np.minimum(cap, vp + accel(vp) * dt), 0.0)
    return np.maximum(np.minimum(cap, vp + accel(0.5 * (vp + guess)) * dt), 0.0)


def _least_acceleration(m: _EffortModel, cap, dv: float) -> np.ndarray:
    """A lower bound (V,) [m/s^2] of every full-effort acceleration :func:`_full_effort_step`
    computes at speeds up to the trace's top speed on the cycle's grades, rounding included
    (-inf where it would not be positive): the least force of the table's intervals up to
    that speed less a bound of the coastdown there (|A| + |B| v + |C| v^2) and the largest
    grade force, less 1e-9 of the largest force, coastdown and grade force (rounding is
    ~1e-16 of them), over the effective mass, less 1e-9 of itself."""
    V = m.base.size
    v_top = max(float(cap.max()), 1e-3)
    width = m.flat.size // max(V, 1)
    table = m.flat.reshape(V, width)[:, :min(int(v_top / dv) + 2, width)]
    A, B, C, _ = np.abs(m.per)
    coast = A + v_top * (B + C * v_top)
    grade = m.weight * float(m.sine.max()) if m.sine.size else np.zeros(V)
    slack = 1e-9 * (table.max(axis=1) + coast + np.abs(grade))
    least = (table.min(axis=1) - coast - grade - slack) * m.per[3] * (1.0 - 1e-9)
    return np.where(least > 0, least, -np.inf)


def _trial_speeds(m: _EffortModel, cap, dt, dv, top, out):
    """Each step's full-effort speed from the trace's speed at its start, into ``out``
    (V, N - 1): a vehicle that followed the trace to step i - 1 reaches this speed at step i.
    Without arithmetic: steps that end at rest are 0 (min(0, x) clipped at 0 is 0 for any
    finite x); steps the vehicle surely follows are the trace's speed: v(i-1) + a dt >=
    trace(i) at the step's start and at every mean speed up to trace(i) with a at least
    :func:`_least_acceleration` (those the trace does not speed up, for a vehicle whose bound
    is positive; on the others where v(i-1) + bound dt >= trace(i), the same float operations).
    The steps without arithmetic are copied as whole rows of a template."""
    V = m.base.size
    moving = cap[1:] > 0
    rising = np.flatnonzero(moving & (cap[1:] > cap[:-1]))
    level = np.flatnonzero(moving & ~(cap[1:] > cap[:-1]))
    least = _least_acceleration(m, cap, dv)
    template = np.zeros(cap.size - 1)          # at rest 0, the trace where the trace does not speed up
    template[level] = cap[1:][level]
    # the steps the trace speeds up: vehicles in the order of their bound, in chunks; a chunk
    # computes the steps its smallest bound does not cover
    order = np.argsort(least, kind="stable")
    chunk = max(1, REDRIVE_CHUNK_STEPS // max(rising.size, 1))
    prev, now, dt_r = cap[rising], cap[rising + 1], dt[rising]
    for first in range(0, V, chunk):
        rows = order[first:first + chunk]
        covered = prev + least[rows[0]] * dt_r >= now
        row = template.copy()
        row[rising[covered]] = now[covered]
        out[rows] = row
        _trial_part(m, rows, rising[~covered], cap, dt, dv, top, out)
    _trial_part(m, np.flatnonzero(~(least > 0)), level, cap, dt, dv, top, out)   # no positive bound
    return out


def _trial_part(m: _EffortModel, rows, steps, cap, dt, dv, top, out):
    """:func:`_trial_speeds` of the vehicles ``rows`` in ``steps`` (indices of dt), into ``out``,
    in chunks of REDRIVE_CHUNK_STEPS vehicle-steps."""
    if rows.size == 0 or steps.size == 0:
        return
    prev, now, dt = cap[steps][None, :], cap[steps + 1], dt[steps]
    chunk = max(1, REDRIVE_CHUNK_STEPS // steps.size)
    for first in range(0, rows.size, chunk):
        r = rows[first:first + chunk, None]
        part = m.part(r)
        out[r, steps] = _full_effort_step(part, part.grade_force(steps[None, :]), prev, now, dt, dv, top)


def forward_redrive(va: VehicleArrays, time_s, target_mps, grade_pct, margin=0.97, table=None):
    """Achieved speed (V, N) of vehicles driven at most at full tractive effort.

    v(i) = min(trace(i), v(i-1) + a_max dt), a_max from the force table at the step's mean
    speed (:func:`_full_effort_step`): the vehicle falls behind on hard accelerations and
    re-joins the trace when it slows down. A vehicle on the trace at step i - 1 reaches the
    same speed at step i as any other on it, so every step is first computed from the trace's
    own speed for all vehicles at once (:func:`_trial_speeds`); only from the steps some
    vehicle cannot follow are they then walked one by one, vectorised over the vehicles. The
    same element-wise arithmetic either way: the speeds are those of a plain step loop, bit
    for bit. ``table``: the unscaled :func:`max_tractive_force_table` if already computed.

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    time_s : array, the cycle's time stamps [s], (N,)
    target_mps : array, the trace's speed [m/s], (N,)
    grade_pct : array, road grade [%], (N,)
    margin : float or array (V, 1), share of the full effort the driver uses [-] (per vehicle)
    table : array or None, :func:`max_tractive_force_table` with margin 1 [N]

    Returns
    -------
    achieved speed [m/s], shape (V, N).
    """
    if table is None:
        table = max_tractive_force_table(va, 1.0)
    dv = float(REDRIVE_SPEED_GRID[1] - REDRIVE_SPEED_GRID[0])
    top = REDRIVE_SPEED_GRID.size - 1 - 1e-9
    t, cap, grade = np.asarray(time_s, float), np.asarray(target_mps, float), np.asarray(grade_pct, float)
    weight, sine = grade_force_factors(va.mass_kg, 0.5 * (grade[1:] + grade[:-1]))
    m = _EffortModel.of(flat=(table * margin).reshape(-1), base=np.arange(va.n) * table.shape[1], A=va.A_N, B=va.B_N,
                        C=va.C_N, inv_m=1.0 / (va.mass_kg * (1.0 + va.rot_frac)), weight=weight, sine=sine)
    dt = np.diff(t)
    speeds = np.empty((va.n, t.size))
    speeds[:, 0] = cap[0]
    _trial_speeds(m, cap, dt, dv, top, speeds[:, 1:])
    _walk_behind(m, speeds, cap, dt, dv, top)
    return speeds


def above_full_load_at_start(va: VehicleArrays, time_s, target_mps, grade_pct, solver: DifferentialSolver,
                             margin, table, effects: CycleEffects = CycleEffects()) -> np.ndarray:
    """The vehicles (V,) whose re-drive at ``margin`` is above full load in the cycle's first
    two steps (step 0 at the trace's first speed, step 1 from there at full effort), where the
    backward pass computes them (the trace moves there): they stay behind in that round
    whatever the rest of the cycle gives. The re-drive and the backward pass of those steps
    alone, on the cycle's first two time stamps: every step is independent given the speed,
    so these are the very numbers of the whole re-drive and pass (:func:`forward_redrive`,
    :func:`backward_drivetrain`).

    Parameters
    ----------
    va : VehicleArrays, the vehicles' parameters
    time_s : array, the cycle's time stamps [s], (N,)
    target_mps : array, the trace's speed [m/s], (N,)
    grade_pct : array, road grade [%], (N,)
    solver : DifferentialSolver, the thesis chain's inversion in the run's mode
    margin : float or array (V, 1), share of the full effort the driver uses [-] (per vehicle)
    table : array, :func:`max_tractive_force_table` with margin 1 [N]
    effects : CycleEffects, the ``--with`` effects

    Returns
    -------
    bool array (V,).
    """
    t, cap, grade = (np.asarray(a, float)[:2] for a in (time_s, target_mps, grade_pct))
    columns = np.flatnonzero(0.5 * (cap + cap[:1]) > 0)      # the pass's steps: the trace moves
    if columns.size == 0:
        return np.zeros(va.n, bool)
    speeds = forward_redrive(va, t, cap, grade, margin, table)
    d = backward_drivetrain(va, t, speeds, grade, solver, columns, effects, losses=False)
    return d.k.at_rest(d.infeasible, False).any(axis=1)


def _walk_behind(m: _EffortModel, speeds, cap, dt, dv, top):
    """Re-compute, step by step, the speeds (in place) from each step some vehicle cannot
    follow until every vehicle is back on the trace; ``speeds`` holds each step's trial speed
    (:func:`_trial_speeds`). Every vehicle is stepped (views, no gathers, no bookkeeping of
    who is behind): one on the trace at the start of a step gets its trial speed again, the
    same arithmetic on the same numbers. The walked steps are written as rows of a
    steps x vehicles buffer (contiguous) and copied into ``speeds`` once per stretch."""
    fail_steps = np.flatnonzero((speeds[:, 1:] != cap[1:]).any(axis=0)) + 1   # someone cannot follow step i
    if fail_steps.size == 0:
        return
    walk = _stepper(m, dv, top, cap, dt)
    rows = np.empty((cap.size, m.base.size))                   # rows[i]: the speeds at step i
    N, k = cap.size, 0
    while k < fail_steps.size:
        first = int(fail_steps[k]) + 1        # speeds up to fail_steps[k] are right for everyone
        rows[first - 1] = speeds[:, first - 1]
        i = walk(first, rows)
        last = min(i, N - 1)
        speeds[:, first:last + 1] = rows[first:last + 1].T
        k = np.searchsorted(fail_steps, i, side="right")


def _plain_numbers(m: _EffortModel, cap, dt) -> bool:
    """Whether every input of the re-drive's step is finite, at most 1e50 in size, and no
    trace speed is -0.0: then no NaN and no -0.0 arises in a step (speeds stay in [+0, cap],
    products stay below 1e250), the two cases where numpy's ``fmax`` / ``fmin`` differ from
    ``maximum`` / ``minimum`` (which propagate NaN and order signed zeros their own way)."""
    # max and min propagate NaN, so the bounds also tell that every number is finite
    parts = (m.flat, m.per, m.weight, m.sine, cap, dt)
    return all(a.size == 0 or (a.max() <= 1e50 and a.min() >= -1e50) for a in parts) and not np.signbit(cap).any()


def _stepper(m: _EffortModel, dv: float, top: float, cap, dt):
    """``walk(i, rows)``: :func:`_full_effort_step` for every vehicle of ``m`` from step ``i``
    on (``rows[i - 1]``: the speeds at its start), each step's speeds into ``rows[i]``, until
    every vehicle is back on the trace (returns that step) or the cycle ends (returns N): the
    same operations on the same numbers in fewer, cheaper calls (docs/simulation.md, "How it
    is computed"). Left out where they cannot change a bit: the clip at the table's end when
    no speed reaches it, a grade force of 0.0 (x - 0.0 is x), a step of 1 s (x * 1.0 is x).
    Bounds are ``np.fmax`` / ``np.fmin`` when :func:`_plain_numbers` (the same values where
    neither operand is NaN nor both are zeros; numpy 2.4's ``maximum`` / ``minimum`` cost
    1.4 us a call against 0.25), a step's two bounds then one call (:func:`_bounds`); the
    acceleration in stacked buffers (:func:`_lanes`): 33 numpy calls a step."""
    V, N = m.base.size, cap.size
    clip = not float(cap.max()) / dv < top
    plain = _plain_numbers(m, cap, dt)
    fmax, fmin = (np.fmax, np.fmin) if plain else (_with_out(np.maximum), _with_out(np.minimum))
    least = np.fmin.reduce if plain else np.minimum.reduce
    bounded = _bounds(plain)
    lane = _lanes(m, dv, top, clip, fmax, fmin)
    zero, half, capb, dtb = (np.full(V, c) for c in (0.0, 0.5, 0.0, 1.0))
    guess = np.empty(V)
    grade = np.empty(V)
    mid = lane.mid
    add, multiply = np.add, np.multiply
    level = ((m.sine == 0) & ~np.signbit(m.sine)).tolist()    # grade force 0.0 (m.grade_force)
    caps, dts = cap.tolist(), dt.tolist()
    accel_at, accel_mid = lane.accel_at, lane.accel_mid

    def walk(i, rows):
        vp, filled = rows[i - 1], None
        while i < N:
            c, step_s, out = caps[i], dts[i - 1], rows[i]
            g = None if level[i - 1] else multiply(m.weight, m.sine[i - 1], out=grade)
            if c != filled:
                capb.fill(c)
                filled = c
            if step_s != 1.0:
                dtb.fill(step_s)
            a = accel_at(vp, g)
            if step_s != 1.0:
                multiply(a, dtb, a)
            add(a, vp, guess)                  # vp + a dt (addition commutes bit for bit)
            bounded(guess, zero, capb, guess)
            add(vp, guess, mid)
            multiply(mid, half, mid)
            a = accel_mid(g)
            if step_s != 1.0:
                multiply(a, dtb, a)
            add(a, vp, out)
            bounded(out, zero, capb, out)
            # all back on the trace (v <= cap): trial speeds hold again; the first and last
            # vehicle read first (a scalar each), the reduction only when both are on it
            if out[0] == c and out[-1] == c and least(out) == c:
                return i
            vp, i = out, i + 1
        return i
    return walk


def _bounds(plain: bool):
    """``bounded(x, zero, cap, out)``: max(min(cap, x), 0) into ``out`` (:func:`_full_effort_step`'s
    bounds). With :func:`_plain_numbers` one call of the ufunc behind ``np.clip`` (numpy's
    ``umath.clip``), min(max(x, 0), cap): the same value for any x when cap >= +0 and neither
    is NaN or -0.0 (a step's speed is never -0.0: the trace has none, and max(., +0) of a
    negative is +0); else, or if a numpy has no such ufunc, ``minimum`` then ``maximum``, as
    written (tests/test_simulation.py: the plain step loop, bit for bit)."""
    clip = getattr(getattr(getattr(np, "_core", getattr(np, "core", None)), "umath", None), "clip", None)
    if plain and isinstance(clip, np.ufunc):
        return clip

    def bounded(x, zero, cap, out):
        np.minimum(cap, x, out=out)
        np.maximum(out, zero, out=out)
    return bounded


def _with_out(ufunc):
    """``ufunc(a, b, out)`` as ``ufunc(a, b, out=out)`` (numpy 2.4 deprecates a positional
    ``out`` for ``maximum`` / ``minimum``; ``fmax`` / ``fmin`` take it positionally)."""
    return lambda a, b, out: ufunc(a, b, out=out)


@dataclass(frozen=True, eq=False)
class _Lanes:
    """:func:`_lanes`: the full-effort acceleration at speeds ``v`` (``accel_at(v, g)``) or at
    the speeds in ``mid`` (``accel_mid(g)``, for the step's mean speed), into one buffer."""

    mid: np.ndarray
    accel_at: object
    accel_mid: object


def _lanes(m: _EffortModel, dv: float, top: float, clip: bool, fmax, fmin) -> _Lanes:
    """:func:`_full_effort_step`'s ``accel`` in few numpy calls: the force table's interpolation
    and the coastdown do not depend on each other, so an operation they both do is one call on
    stacked buffers (vehicles x 3: the cell weights, the speed floor and the step's mean speed;
    the gathered forces, the coastdown's B + C v and the cell index), each element the same
    IEEE operation on the same operands (products and sums commute bit for bit; v / dv is
    v x (1 / dv) exactly when dv is a power of two, as the grid's 0.25 m/s). ``g``: the grade
    force [N] of the vehicles in this step, or None where it is 0.0."""
    V = m.base.size
    A, B, C, inv_m = m.per
    n, p, r, q, f = np.empty(3 * V), np.empty(3 * V), np.empty(3 * V), np.empty(4 * V), np.empty(2 * V)
    q[3 * V:] = A
    by_power_of_two = dv > 0 and math.frexp(dv)[0] == 0.5
    scale = np.concatenate([np.full(V, 1.0 / dv), C])                 # [1 / dv | C]
    add_to = np.concatenate([B, m.base.astype(float)])                 # [B | each vehicle's first cell]
    floor, tops, one, dvs = (np.full(V, c) for c in (1e-3, top, 1.0, dv))
    j, a = np.empty(V, np.intp), np.empty(V)
    n0, n1, n2, n01 = n[:V], n[V:2 * V], n[2 * V:], n[:2 * V]
    p0, p1, p2, p01, p12 = p[:V], p[V:2 * V], p[2 * V:], p[:2 * V], p[V:]
    r0, r2, r12, q3, q01, q23, f0, f1 = r[:V], r[2 * V:], r[V:], q[:3 * V], q[:2 * V], q[2 * V:], f[:V], f[V:]
    take_lo, take_hi = m.flat.take, m.flat_next.take
    divide, trunc, subtract, add, multiply = np.divide, np.trunc, np.subtract, np.add, np.multiply

    def rest(g):
        """From the cell position x (p0) and C v (p1), v floored in n1: the acceleration."""
        if clip:
            fmin(p0, tops, p0)
        trunc(p0, p2)                          # int(x) for x >= 0, as a float
        subtract(p0, p2, n2)                   # w
        subtract(one, n2, n0)                  # 1 - w
        add(p12, add_to, r12)                  # [C v + B | int(x) + first cell]
        j[...] = r2
        take_lo(j, out=r0)
        take_hi(j, out=r2)                     # r: [F(j) | B + C v | F(j + 1)]
        multiply(r, n, q3)                     # [F(j) (1 - w) | (B + C v) v | F(j + 1) w]
        add(q01, q23, f)                       # [force | coastdown (+ A)]
        subtract(f0, f1, a)
        if g is not None:
            subtract(a, g, a)
        multiply(a, inv_m, a)
        return a

    def accel_at(v, g):
        fmax(v, floor, n1)
        divide(v, dvs, p0)
        multiply(C, n1, p1)
        return rest(g)

    def accel_mid(g):
        fmax(n0, floor, n1)
        if by_power_of_two:
            multiply(n01, scale, p01)          # [v / dv | C v]
        else:
            divide(n0, dvs, p0)
            multiply(C, n1, p1)
        return rest(g)
    return _Lanes(n0, accel_at, accel_mid)
