"""Differential-level diagnosis: the thesis model driven by the measured input torque and speed.

Baseline: ``T_out = G * eta(T_in / Kim, n_in) * T_in`` while the pinion turns (thesis chain,
``fleetrun.differential.efficiency``), ``G * T_in`` at standstill (statics: no power, no loss).

Sensor zero: torque sensors drift. Where the recording stands still with no torque (a rig,
neutral) the median reading of each torque sensor at standstill is its offset. Where torque
is held at standstill (creep against the brakes), statics still give ``T_out = G * T_in``
whatever the efficiency, so the median of ``measured - G * T_in`` at standstill is the output
sensor's offset relative to the input's. Offsets are removed before anything is fitted. A constant offset while driving would otherwise look
exactly like ``bearing_preload``. Without standstill samples the offset cannot be told from a
preload, and a ``bearing_preload`` finding is reported ``ambiguous`` instead.

Each candidate's column is its effect on the measured target per unit of its linear
parameter: ``-G * m * dT_in``, with ``m = d(eta T)/dT`` the marginal efficiency of the thesis
chain at the operating point (an extra pinion loss passes through the gears like torque).
"""
from __future__ import annotations

import numpy as np

from fleetrun.diagnose.engine import IntegralSpec, Problem
from fleetrun.diagnose.recording import Recording, Sidecar
from fleetrun.diagnose.select import Candidate
from fleetrun.differential import configuration_lubricant, efficiency, kim_torque_scale_Nm
from fleetrun.effects import effects_for_level, overall_ratio
from fleetrun.effects.differential import oil_temperature_C
from fleetrun.units import RAD_S_PER_RPM

#: Pinion speed [rpm] below which the rig/vehicle counts as standing still.
STANDSTILL_RPM = 5.0
#: Standstill samples needed to zero the torque sensors (and at least this share of samples).
MIN_STANDSTILL = 20


def sidecar_kim_torque_scale_Nm(meta: Sidecar) -> float:
    """The Kim torque scale (:func:`fleetrun.differential.kim_torque_scale_Nm`) of a sidecar."""
    return float(kim_torque_scale_Nm(float(meta.peak_engine_torque_Nm), float(meta.torque_converter_ratio),
                                     float(meta.max_transmission_gear_ratio)))


def acceleration(w_rad_s: np.ndarray, dt_s: float) -> np.ndarray:
    """dw/dt by a Savitzky-Golay derivative over ~1 s (speed sensors are noisy at 10 Hz)."""
    from scipy.signal import savgol_filter  # scipy: slow to import, only this routine needs it

    win = max(5, int(round(0.3 / dt_s)) | 1)
    if win >= len(w_rad_s):
        return np.gradient(w_rad_s, dt_s)
    return savgol_filter(w_rad_s, win, 2, deriv=1, delta=dt_s)


def fit_oil_time_constant(time_s, oil_temp_C, ambient_temp_C) -> float:
    """Time constant [s] of the first-order warm-up that best follows a measured sump trace.

    ``fleetrun.effects.differential.oil_temperature_C`` (thesis Sec. 3.1.2 rise), least squares in tau.
    """
    from scipy.optimize import minimize_scalar  # scipy: slow to import, only this routine needs it

    def sse(log_tau):
        e = oil_temp_C - oil_temperature_C(time_s, ambient_temp_C, float(np.exp(log_tau)))
        return float(e @ e)

    res = minimize_scalar(sse, bounds=(np.log(30.0), np.log(7200.0)), method="bounded")
    return float(np.exp(res.x))


def thesis_output_torque(meta: Sidecar, t_in_Nm, n_rpm, physics="thesis"):
    """Model output torque and marginal efficiency for measured input torque and speed."""
    kim = sidecar_kim_torque_scale_Nm(meta)
    cfg = meta.configuration
    kw = {"physics": physics}
    if meta.low_gear_ratio:
        kw["low_gear_ratio"] = float(meta.low_gear_ratio)
        kw["axle_gear"] = str(meta.axle_gear)
    g = overall_ratio(meta.gear_ratio, meta.low_gear_ratio, meta.axle_gear)
    t_pos = np.maximum(t_in_Nm, 0.0)

    def f(t):
        return np.asarray(efficiency(cfg, t / kim, np.abs(n_rpm), float(meta.gear_ratio), **kw),
                          dtype=float) * t

    delta = max(0.005 * kim, 1.0)
    f0 = f(t_pos)
    marginal = (f0 - f(np.maximum(t_pos - delta, 0.0))) / delta
    moving = np.abs(n_rpm) >= STANDSTILL_RPM
    y = np.where(moving, g * f0, g * t_in_Nm)
    # negative input torque while moving (driven backwards) is outside the thesis model:
    # passed through without loss
    y = np.where(moving & (t_in_Nm < 0), g * t_in_Nm, y)
    m = np.where(moving & (t_in_Nm > 0), np.clip(marginal, 0.0, 1.2), 0.0)
    return y, m, g


def _zero_sensors(t, t_in, y, g, still, notes, extra_ambiguity):
    """Torque sensor offsets from standstill (input, output) and how well the zero is known.

    Returns the input and output offsets and the offset floor of ``bearing_preload``.
    """
    offset = offset_in = 0.0
    enough = still.sum() >= max(MIN_STANDSTILL, 0.01 * len(t))
    if not enough:
        notes.append("no standstill in the recording: torque sensor offsets cannot be separated "
                     "from a constant drag")
        extra_ambiguity["bearing_preload"] = ("no standstill samples: a constant torque-sensor "
                                              "offset would look the same")
        return offset_in, offset, {}
    t_still = float(np.median(t_in[still]))
    driving = t_in[~still]
    typical = float(np.median(np.abs(driving))) if driving.size else 0.0
    if abs(t_still) < 0.05 * max(typical, 1e-9):
        # no torque at rest (rig, neutral): each sensor reads its own offset
        offset_in = t_still
        offset = float(np.median(y[still]))
        notes.append(f"torque sensors zeroed at standstill ({int(still.sum())} samples): "
                     f"input offset {offset_in:.3g} N m, output offset {offset:.3g} N m removed")
    else:
        # torque held at rest (creep against the brakes): statics y = G T_in, so only the
        # output sensor's offset relative to G x input is known
        offset = float(np.median(y[still] - g * t_in[still]))
        notes.append(f"torque held at standstill ({t_still:.3g} N m): output zeroed against "
                     f"G x input, offset {offset:.3g} N m removed")
    # how well the zero is known: standstill noise is autocorrelated, so the effective
    # number of samples is n (1 - rho) / (1 + rho); 1.25 for the median's efficiency
    z = ((y - offset) - g * (t_in - offset_in))[still]
    z = z - np.median(z)
    rho = 0.0
    if z.size > 3 and np.std(z[:-1]) > 0 and np.std(z[1:]) > 0:
        rho = float(np.clip(np.corrcoef(z[:-1], z[1:])[0, 1], 0.0, 0.999))
    n_eff = max(z.size * (1 - rho) / (1 + rho), 1.0)
    se = 1.25 * float(np.std(z)) / np.sqrt(n_eff)
    notes.append(f"sensor zero known to {se:.3g} N m (1 sigma, {n_eff:.0f} effective standstill "
                 "samples): a constant drag below 3 sigma cannot be told from a zeroing error")
    # a constant-while-driving effect must stand out from the zeroing error (3 sigma)
    return offset_in, offset, {"bearing_preload": 3.0 * se}


def _channels(df, meta, rec, t0, t_in, n_rpm, g, lubricant) -> dict:
    """The effects' channels (fleetrun.effects.differential) from the recording."""
    w = n_rpm * RAD_S_PER_RPM
    ch = {"time_s": t0, "input_torque_Nm": t_in, "input_speed_rad_s": w,
          "input_accel_rad_s2": acceleration(w, rec.dt_s), "gear_ratio": g, "lubricant": lubricant}
    if "wheel_speed_left_rpm" in df and "wheel_speed_right_rpm" in df:
        ch["wheel_speed_difference_rad_s"] = np.abs(df["wheel_speed_left_rpm"].to_numpy()
                                                    - df["wheel_speed_right_rpm"].to_numpy()) * RAD_S_PER_RPM
    if "ambient_temp_C" in df:
        ch["ambient_temp_C"] = df["ambient_temp_C"].to_numpy()
    elif meta.ambient_temp_C is not None:
        ch["ambient_temp_C"] = np.full(len(t0), float(meta.ambient_temp_C))
    if "oil_temp_C" in df:
        ch["oil_temp_C"] = df["oil_temp_C"].to_numpy()
    return ch


def _candidate(effect, channels, scale, t0) -> Candidate:
    """An effect as a selection candidate: its column(s) on the target per unit of its
    linear parameter, one per value of its shape parameter."""
    lin = effect.parameter(effect.linear)
    if not effect.shape:
        return Candidate(effect.id, [scale * effect.basis(channels)], [{}], lin.lower, lin.upper)
    p = effect.shape[0]
    grid = [{p.name: v} for v in p.grid]
    bounds = (p.lower, p.upper)
    if p.name == "tau_s" and "oil_temp_C" in channels:
        # the sump thermometer replaces the first-order warm-up in the loss; tau_s is
        # then what the thermometer shows, fitted to its trace
        tau = fit_oil_time_constant(t0, channels["oil_temp_C"], channels["ambient_temp_C"])
        return Candidate(effect.id, [scale * effect.basis(channels, tau_s=tau)], [{p.name: tau}],
                         lin.lower, lin.upper)
    if p.name == "tau_s":
        # a warm-up slower than half the recording is hard to tell from a constant
        # drag (a preload, a bearing drag): time constants up to half its length only
        tau_max = max(0.5 * t0[-1], p.grid[0])
        grid = [sh for sh in grid if sh["tau_s"] <= tau_max]
        bounds = (p.lower, min(p.upper, tau_max))
    cols = [scale * effect.basis(channels, **sh) for sh in grid]
    return Candidate(effect.id, cols, grid, lin.lower, lin.upper,
                     column_for=lambda sh: scale * effect.basis(channels, **sh), shape_bounds=bounds)


def _driver_channels(df, ch, n_rpm, t_in, t0) -> dict:
    drivers = {"speed": n_rpm, "torque": t_in, "acceleration": ch["input_accel_rad_s2"],
               "time_since_start": t0}
    if "wheel_speed_difference_rad_s" in ch:
        drivers["wheel_speed_difference"] = ch["wheel_speed_difference_rad_s"]
    if "oil_temp_C" in ch:
        drivers["temperature"] = ch["oil_temp_C"]
    elif "ambient_temp_C" in ch:
        drivers["temperature"] = ch["ambient_temp_C"]
    if "vehicle_speed_kph" in df:
        drivers["vehicle_speed"] = df["vehicle_speed_kph"].to_numpy()
    return drivers


def build_problem(rec: Recording, physics: str = "thesis") -> Problem:
    df, meta = rec.data, rec.meta
    t = df["time_s"].to_numpy()
    t0 = t - t[0]
    n_rpm = df["diff_input_speed_rpm"].to_numpy()
    notes = list(rec.notes)
    g = overall_ratio(meta.gear_ratio, meta.low_gear_ratio, meta.axle_gear)
    still = np.abs(n_rpm) < STANDSTILL_RPM
    if "wheel_speed_left_rpm" in df:
        still &= (np.abs(df["wheel_speed_left_rpm"].to_numpy()) < STANDSTILL_RPM / g) & \
                 (np.abs(df["wheel_speed_right_rpm"].to_numpy()) < STANDSTILL_RPM / g)
    extra_ambiguity = {}
    offset_in, offset, offset_floor = _zero_sensors(
        t, df["diff_input_torque_Nm"].to_numpy(), df["diff_output_torque_Nm"].to_numpy(), g,
        still, notes, extra_ambiguity)
    y = df["diff_output_torque_Nm"].to_numpy() - offset
    t_in = df["diff_input_torque_Nm"].to_numpy() - offset_in
    y_model, marginal, g = thesis_output_torque(meta, t_in, n_rpm, physics)
    lubricant = meta.lubricant or configuration_lubricant(meta.configuration)
    ch = _channels(df, meta, rec, t0, t_in, n_rpm, g, lubricant)
    moving = np.abs(n_rpm) >= STANDSTILL_RPM
    scale = -g * marginal * moving
    candidates, untestable, surrogates, confound = [], {}, {}, {}
    for effect in effects_for_level("differential"):
        missing = effect.missing_channels(ch)
        if not missing:
            candidates.append(_candidate(effect, ch, scale, t0))
            continue
        untestable[effect.id] = missing
        if effect.id == "oil_warmup":
            # the thesis's own assumption (Sec. 3.1.2): 20 C ambient
            surrogates[effect.id] = _candidate(effect, {**ch, "ambient_temp_C": np.full(len(t), 20.0)},
                                               scale, t0)
        # cornering: without wheel speeds an instrumented vehicle (it has a speed channel)
        # may have turned; a rig cannot
        confound[effect.id] = "vehicle_speed_kph" in df
    if "wheel_speed_difference_rad_s" not in ch:
        notes.append("no wheel speeds: wheels assumed equal (cornering cannot be tested)")
    info = {"model": f"thesis differential chain, {meta.configuration}, physics={physics}",
            "offset": round(offset, 6), "input_offset_Nm": round(offset_in, 6),
            "standstill_samples": int(still.sum()),
            "kim_torque_scale_Nm": sidecar_kim_torque_scale_Nm(meta), "overall_ratio": g, "lubricant": lubricant}
    integral = IntegralSpec(moving=moving, unit="kJ", weight=ch["input_speed_rad_s"] / g / 1000.0,
                            speed_mps=df["vehicle_speed_kph"].to_numpy() / 3.6 if "vehicle_speed_kph" in df else None)
    return Problem("differential", "diff_output_torque_Nm", t, y, y_model, candidates, untestable,
                   surrogates, confound, _driver_channels(df, ch, n_rpm, t_in, t0), info, notes,
                   extra_ambiguity, units="N m", offset_floor=offset_floor, integral=integral)
