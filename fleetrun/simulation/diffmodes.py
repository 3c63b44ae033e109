"""The differential inside the drive-cycle simulation: the thesis' three running modes (Ch. 6).

The thesis model is forward: efficiency at a given *input* torque and speed. A backward
simulation knows the *output* (wheel) torque, so every mode inverts it: find T_in with

    eta(T_in / kim, n_in, G) * T_in * G_tot = T_out          (G_tot = G, or G x low range)

(thesis Sec. 7.2 does the same by iteration). The input-referred loss is then
L = T_in - T_out / G_tot.

- ``direct`` (Sec. 6.1): the model is called at every step inside a bracketed
  root search (scipy.optimize.elementwise.find_root), to 1e-10 of the Kim scale.
- ``map2d`` (Sec. 6.2): per vehicle, the model is evaluated once on an input-torque x speed
  grid at the vehicle's own gear ratio(s); each speed column is inverted (input torque as a
  function of output torque) and the steps interpolate bilinearly in that inverse map.
- ``map3d`` (Sec. 6.3): the same inverse maps on a gear-ratio grid, per configuration,
  lubricant temperature and physics, built once and cached on disk; a vehicle's map is the
  linear interpolation in gear ratio.

The output-torque axis of the inverse maps is uniform in sqrt(T_out / (kim G_tot)): road-load
torques are a few percent of the Kim scale, so the grid is densest there. The model is always
given the vehicle's Kim scale (``kim_torque_scale_Nm``); the thesis baseline ignores it, so
its maps serve every vehicle, while maps of baselines in absolute torque (vecto-generic) are
built per Kim scale (:func:`map_torque_scale_Nm`).

The maps and the direct inversion are the thesis chain only: ``--with`` effects act on top of
them, per step (fleetrun/simulation/effects.py).

Overrun and coast (T_out < 0), outside the thesis model (drive torque only): the differential
passes the negative torque with the loss magnitude it has in drive at |T_out|, so
T_in = T_out / G_tot + L(|T_out|) for either sign (continuous at 0, where L is the
no-load loss). At standstill (n_in = 0) nothing turns and there is no loss.
"""
from __future__ import annotations

import hashlib
import json
import os
import zipfile
from pathlib import Path

import numpy as np

from fleetrun import __version__
from fleetrun.differential import efficiency
from fleetrun.errors import FleetrunError
from fleetrun.fileio import atomic_file
from fleetrun.physics.lubricant import THESIS_OPERATING_TEMP_C, operating_temperature_C
from fleetrun.simulation import bounds

MODES = ("direct", "map2d", "map3d")
ZERO_OUTPUT = 1e-8  # output torque fraction that stands for "zero" in the direct inversion

# Grid of the maps: input torque fraction for the forward evaluation, sqrt-spaced to 1.2 of
# the Kim scale; output torque fraction for the inverse map, sqrt-spaced to 1.1.
TF_FORWARD = np.linspace(0.0, np.sqrt(1.2), 161) ** 2
U_MAX = np.sqrt(1.1)
N_U = 161   # 0.07 % worst cycle-fuel difference to direct on the example fleet (97: 0.22 %)
N_SPEED = 81
SPEED_MAX_RPM = {"LD": 10000.0, "HD": 5000.0}
GEAR_GRID = {"LD": np.round(np.arange(2.0, 6.0001, 0.1), 6), "HD": np.round(np.arange(2.5, 8.0001, 0.125), 6)}


def lubricant_temp_C(ambient_temp_C) -> float:
    """Operating lubricant temperature (physics.lubricant.operating_temperature_C, thesis Sec.
    3.1.2 and 7.1.1); None: the thesis code's fixed 70 C.

    Parameters
    ----------
    ambient_temp_C : float or None, ambient temperature [C]

    Returns
    -------
    float, lubricant temperature [C] (ambient + 50 K; 70 C for None).
    """
    return THESIS_OPERATING_TEMP_C if ambient_temp_C is None else float(operating_temperature_C(ambient_temp_C))


def duty_of(configuration: str) -> str:
    """The duty (``LD`` or ``HD``) of a configuration id, from its prefix.

    Parameters
    ----------
    configuration : str, a canonical configuration id (``LD_RWD``, ``HD_DUAL``, ...)

    Returns
    -------
    str, ``HD`` for ids starting with ``HD``, else ``LD``.
    """
    return "HD" if configuration.startswith("HD") else "LD"


def speed_grid(configuration: str) -> np.ndarray:
    """The maps' differential input speed grid of the configuration's duty.

    Parameters
    ----------
    configuration : str, a canonical configuration id

    Returns
    -------
    speeds [rpm], N_SPEED points from 0 to ``SPEED_MAX_RPM`` of the duty.
    """
    return np.linspace(0.0, SPEED_MAX_RPM[duty_of(configuration)], N_SPEED)


# --------------------------------------------------------------------------- the model
# Baselines whose efficiency depends on the torque *fraction* only: the thesis maps the
# fraction onto its reference differential and ignores the vehicle's Kim scale (thesis Sec.
# 5.2.1.A), so one map serves every vehicle. Any other baseline (vecto-generic works in
# absolute torque) gets maps per Kim scale.
SCALE_FREE_PHYSICS = ("thesis",)


def map_torque_scale_Nm(physics, kim_torque_scale_Nm):
    """The Kim scale a map depends on: None for scale-free physics, else the vehicle's.

    Parameters
    ----------
    physics : str, the baseline name (``thesis``, ``vecto-generic``, ...)
    kim_torque_scale_Nm : float, the vehicle's Kim scale [N m]

    Returns
    -------
    float or None, the Kim scale [N m], or None for scale-free physics.
    """
    if str(physics).strip().lower() in SCALE_FREE_PHYSICS:
        return None
    return float(kim_torque_scale_Nm)


def eta_forward(configuration, torque_fraction, speed_rpm, gear_ratio, low_gear_ratio, axle_low,
                physics, ambient_temp_C=None, kim_torque_scale_Nm=None):
    """The differential model (``fleetrun.differential.efficiency``) for one configuration.

    ``gear_ratio``/``low_gear_ratio`` may be arrays (the model groups by distinct pairs);
    ``axle_low`` is a bool (one range); ``kim_torque_scale_Nm`` is the vehicle's Kim scale, which
    baselines in absolute torque (vecto-generic) need.

    Parameters
    ----------
    configuration : str, a canonical configuration id
    torque_fraction : float or array, input torque / Kim scale [-]
    speed_rpm : float or array, differential input speed [rpm]
    gear_ratio : float or array, final-drive ratio [-]
    low_gear_ratio : float or array or None, two-speed axle low ratio [-]
    axle_low : bool, the low range is engaged
    physics : str, the baseline name
    ambient_temp_C : float or None, ambient temperature [C] (None: the baseline's own oil temperature)
    kim_torque_scale_Nm : float or None, the vehicle's Kim scale [N m]

    Returns
    -------
    efficiency [-], an array of the broadcast shape.
    """
    # thesis Sec. 3.1.2: the lubricant runs 50 K above ambient (20 C ambient -> the 70 C that
    # physics="thesis" assumes); None leaves the baseline its own temperature
    oil = None if ambient_temp_C is None else lubricant_temp_C(ambient_temp_C)
    return np.asarray(efficiency(configuration, torque_fraction, speed_rpm, gear_ratio,
                                 low_gear_ratio=low_gear_ratio, axle_gear="low" if axle_low else "high",
                                 physics=physics, oil_temp_C=oil, kim_torque_scale_Nm=kim_torque_scale_Nm), float)


# --------------------------------------------------------------------------- direct inversion
def invert_direct(configuration, out_frac, speed_rpm, gear_ratio, low_gear_ratio, axle_low, physics,
                  ambient_temp_C=None, kim_torque_scale_Nm=None, tol=1e-10, max_iter=60):
    """Input torque fraction whose output fraction eta*T_in equals ``out_frac`` (>= 0).

    ``out_frac`` = T_out / (kim G_tot) and the result T_in / kim, so eta = out / in.
    f(x) = eta(x) x - out is bracketed by [out, hi]: eta <= 1 makes f(out) <= 0; hi grows
    geometrically until f(hi) >= 0; scipy.optimize.elementwise.find_root finds each root.

    Parameters
    ----------
    configuration : str, a canonical configuration id
    out_frac : float or array, output torque fraction T_out / (kim G_tot) [-]
    speed_rpm : float or array, differential input speed [rpm]
    gear_ratio : float or array, final-drive ratio [-]
    low_gear_ratio : float or array or None, two-speed axle low ratio [-]
    axle_low : bool, the low range is engaged
    physics : str, the baseline name
    ambient_temp_C : float or None, ambient temperature [C]
    kim_torque_scale_Nm : float or None, the vehicle's Kim scale [N m]
    tol : float, tolerance on the torque fraction and on the output mismatch [-]
    max_iter : int, iterations of the root search

    Returns
    -------
    input torque fraction T_in / kim [-], a flat array of ``out_frac``'s size.
    """
    # zero output is met by any input up to the no-load loss; aim just above 0 so the
    # answer is that loss (continuous with small outputs, and what the maps give at 0)
    out = np.maximum(np.asarray(out_frac, float).ravel(), ZERO_OUTPUT)
    n = np.broadcast_to(np.asarray(speed_rpm, float), out.shape).ravel()
    G = np.broadcast_to(np.asarray(gear_ratio, float), out.shape).ravel()
    low = None if low_gear_ratio is None else np.broadcast_to(np.asarray(low_gear_ratio, float), out.shape).ravel()

    def f(x, idx):
        eta = eta_forward(configuration, x, n[idx], G[idx], None if low is None else low[idx], axle_low,
                          physics, ambient_temp_C, kim_torque_scale_Nm)
        return eta * x - out[idx]

    all_idx = np.arange(out.size)
    lo = out.copy()
    f_lo = f(lo, all_idx)
    hi = out / 0.9 + 2e-3
    f_hi = f(hi, all_idx)
    for _ in range(60):
        grow = f_hi < 0
        if not grow.any():
            break
        idx = np.flatnonzero(grow)
        lo[idx], f_lo[idx] = hi[idx], f_hi[idx]
        hi[idx] = hi[idx] * 2.0 + 1e-2
        f_hi[idx] = f(hi[idx], idx)
    else:
        raise FleetrunError("the differential model delivers no output torque at any input torque here",
                            hint="Check the gear ratio and speed range of the vehicle")
    # the root inside each bracket: scipy's elementwise bracketing solver (Chandrupatla), to
    # ``tol`` in the torque fraction and in the output mismatch; imported here (direct mode only)
    from scipy.optimize.elementwise import find_root

    def g(x, idx):
        return f(x, idx.astype(np.intp))

    # find_root wants a strict sign change. An end that already meets the output is the
    # answer; where the model gives eta > 1 at ``out`` (f(lo) > 0: no sign change in the
    # bracket) the answer is ``lo``, as the earlier false-position iteration converged to
    x = np.where(f_lo >= -tol, lo, hi)
    todo = np.flatnonzero((f_lo < -tol) & (f_hi > tol))
    if todo.size:
        found = find_root(g, (lo[todo], hi[todo]), args=(todo.astype(float),), maxiter=max_iter,
                          tolerances={"xatol": tol, "xrtol": 0.0, "fatol": tol, "frtol": 0.0})
        x[todo] = found.x
    return x


# --------------------------------------------------------------------------- maps
def inverse_map(configuration, gear_ratio, low_gear_ratio, axle_low, physics, ambient_temp_C=None,
                kim_torque_scale_Nm=None):
    """Inverse map T_in/kim on the (u = sqrt(T_out/(kim G_tot)), speed) grid, shape (N_U, N_SPEED).

    Parameters
    ----------
    configuration : str, a canonical configuration id
    gear_ratio : float, final-drive ratio [-]
    low_gear_ratio : float or None, two-speed axle low ratio [-]
    axle_low : bool, the low range is engaged
    physics : str, the baseline name
    ambient_temp_C : float or None, ambient temperature [C]
    kim_torque_scale_Nm : float or None, the vehicle's Kim scale [N m]

    Returns
    -------
    input torque fraction T_in / kim [-], shape (N_U, N_SPEED).
    """
    n_grid = speed_grid(configuration)
    eta = eta_forward(configuration, TF_FORWARD[:, None], n_grid[None, :], gear_ratio, low_gear_ratio,
                      axle_low, physics, ambient_temp_C, kim_torque_scale_Nm)
    eta = np.broadcast_to(eta, (TF_FORWARD.size, n_grid.size))
    out = np.maximum.accumulate(np.nan_to_num(eta) * TF_FORWARD[:, None], axis=0)
    targets = np.linspace(0.0, U_MAX, N_U) ** 2
    inv = np.empty((N_U, n_grid.size))
    for j in range(n_grid.size):
        col = out[:, j]
        zero = np.flatnonzero(col <= 0.0)
        start = zero[-1] if zero.size else 0
        xp, fp = col[start:], TF_FORWARD[start:]
        keep = np.concatenate([[True], np.diff(xp) > 1e-15])
        xp, fp = xp[keep], fp[keep]
        if xp.size < 2:
            # no output at any torque in this column (the thesis code gives 0 for the HD
            # two-speed box at exactly 0 rpm): filled from the nearest column below
            inv[:, j] = np.nan
            continue
        vals = np.interp(targets, xp, fp)
        beyond = targets > xp[-1]  # linear extrapolation with the last slope
        slope = (fp[-1] - fp[-2]) / (xp[-1] - xp[-2])
        vals[beyond] = fp[-1] + slope * (targets[beyond] - xp[-1])
        inv[:, j] = vals
    bad = np.isnan(inv[0])
    if bad.all():
        raise FleetrunError(f"the differential model of {configuration} gives no output at any speed",
                            hint="Check the gear ratio")
    good = np.flatnonzero(~bad)
    for j in np.flatnonzero(bad):
        inv[:, j] = inv[:, good[np.argmin(np.abs(good - j))]]
    return inv


_LOADED: dict = {}  # maps already read in this process, by (file, key digest)


#: The one environment variable naming the map cache (``fleetrun simulate`` and ``fleetrun run``).
CACHE_ENV = "FLEETRUN_CACHE_DIR"


def default_cache_dir() -> Path:
    """Where cached efficiency maps live between runs: $FLEETRUN_CACHE_DIR, else
    $XDG_CACHE_HOME/fleetrun, else ~/.cache/fleetrun.

    Returns
    -------
    Path, the map cache directory.
    """
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV])
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "fleetrun"


def map3d(configuration, low_gear_ratio, physics, ambient_temp_C=20.0, cache_dir=None, kim_torque_scale_Nm=None):
    """Gear-ratio grid and inverse maps (2 ranges x gears x N_U x N_SPEED), cached on disk.

    Key: configuration, physics, lubricant temperature, low range ratio, grid, fleetrun
    version, and the Kim scale for physics that is not scale-free (``map_torque_scale_Nm``).
    Written atomically (temp file + os.replace) so concurrent runs never see half a file.

    Parameters
    ----------
    configuration : str, a canonical configuration id
    low_gear_ratio : float or None, two-speed axle low ratio [-]
    physics : str, the baseline name
    ambient_temp_C : float or None, ambient temperature [C]
    cache_dir : str or Path or None, the cache directory (None: :func:`default_cache_dir`)
    kim_torque_scale_Nm : float or None, the Kim scale [N m] (:func:`map_torque_scale_Nm`)

    Returns
    -------
    (gear ratios [-] of ``GEAR_GRID``, input torque fractions [-] of shape (2, gears, N_U, N_SPEED)).
    """
    gears = GEAR_GRID[duty_of(configuration)]
    directory = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    quick = (configuration, low_gear_ratio, physics, lubricant_temp_C(ambient_temp_C), kim_torque_scale_Nm, str(directory))
    if quick in _LOADED:  # already read (or built) in this process: skip hashing the key
        return gears, _LOADED[quick]
    key = {"configuration": configuration, "physics": physics, "lubricant_temp_C": lubricant_temp_C(ambient_temp_C),
           "low_gear_ratio": low_gear_ratio, "gears": gears.tolist(), "tf": [float(TF_FORWARD[-1]), TF_FORWARD.size],
           "u": [U_MAX, N_U], "speed": [float(speed_grid(configuration)[-1]), N_SPEED], "version": __version__,
           "format": 2}
    if kim_torque_scale_Nm is not None:  # only then: the keys (and cache files) of thesis maps stay as they were
        key["kim_torque_scale_Nm"] = kim_torque_scale_Nm
    digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:20]
    path = directory / f"map3d-{configuration}-{digest}.npz"
    if (path, digest) in _LOADED:
        return gears, _LOADED[(path, digest)]
    if path.is_file():
        try:
            with np.load(path) as data:
                maps = data["maps"].astype(float)
            _LOADED[(path, digest)] = _LOADED[quick] = maps
            return gears, maps
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
            pass  # an unreadable or damaged cache file (truncated, not a zip, no maps) is rebuilt
    ranges = (False, True) if low_gear_ratio is not None else (False,)
    maps = np.empty((2, gears.size, N_U, N_SPEED))
    for r, axle_low in enumerate(ranges):
        for i, g in enumerate(gears):
            maps[r, i] = inverse_map(configuration, float(g), low_gear_ratio, axle_low, physics, ambient_temp_C,
                                     kim_torque_scale_Nm)
    if len(ranges) == 1:
        maps[1] = maps[0]
    try:
        with atomic_file(path) as tmp, open(tmp, "wb") as fh:
            # float32 on disk: 1e-7 relative, far below the 0.2 % the modes must agree to
            np.savez(fh, maps=maps.astype(np.float32), key=json.dumps(key))
    except (OSError, FleetrunError):
        pass  # an unwritable cache only costs the rebuild next time
    maps = maps.astype(np.float32).astype(float)  # the same values as a later read of the file
    _LOADED[(path, digest)] = _LOADED[quick] = maps
    return gears, maps


def outside_map3d_grid(configuration: str, gear_ratio: float) -> bool:
    """Whether ``gear_ratio`` lies beyond the cached map3d gear-ratio grid of the configuration's
    duty (``GEAR_GRID``); map3d then uses maps built at the vehicle's own ratio (as map2d).

    Parameters
    ----------
    configuration : str, a canonical configuration id
    gear_ratio : float, final-drive ratio [-]

    Returns
    -------
    bool, the ratio lies outside the grid.
    """
    gears = GEAR_GRID[duty_of(configuration)]
    return not gears[0] <= float(gear_ratio) <= gears[-1]


def own_ratio_maps(configuration, gear_ratio, low_gear_ratio, physics, ambient_temp_C=None, kim_torque_scale_Nm=None):
    """Inverse maps (2, N_U, N_SPEED) of both axle ranges at the vehicle's own gear ratio (map2d).

    Parameters
    ----------
    configuration : str, a canonical configuration id
    gear_ratio : float, final-drive ratio [-]
    low_gear_ratio : float or None, two-speed axle low ratio [-] (None: both ranges the same)
    physics : str, the baseline name
    ambient_temp_C : float or None, ambient temperature [C]
    kim_torque_scale_Nm : float or None, the Kim scale [N m] (:func:`map_torque_scale_Nm`)

    Returns
    -------
    input torque fractions [-], shape (2, N_U, N_SPEED) (high range, low range).
    """
    high = inverse_map(configuration, gear_ratio, low_gear_ratio, False, physics, ambient_temp_C, kim_torque_scale_Nm)
    if low_gear_ratio is None:
        return np.stack([high, high])
    low = inverse_map(configuration, gear_ratio, low_gear_ratio, True, physics, ambient_temp_C, kim_torque_scale_Nm)
    return np.stack([high, low])


def vehicle_maps(configurations, gear_ratios, low_ratios, mode, physics, ambient_temp_C=None, cache_dir=None,
                 kim_scales_Nm=None):
    """Inverse maps per distinct differential: (maps (M, 2, N_U, N_SPEED), map index per vehicle (V,),
    top of the speed grid per map (M,)).

    ``low_ratios`` holds NaN for single-speed axles. map2d evaluates the model at each distinct
    (configuration, G, low[, Kim scale]); map3d interpolates the cached gear-ratio maps linearly
    in G, and builds a vehicle's own maps as map2d does when G lies beyond the grid
    (:func:`outside_map3d_grid`; the run notes those vehicles in its warnings). ``kim_scales_Nm`` (V,): the vehicles' Kim scales, part of the key only for physics
    that is not scale-free (:func:`map_torque_scale_Nm`).

    Parameters
    ----------
    configurations : sequence of str, canonical configuration id of each vehicle (V,)
    gear_ratios : array, final-drive ratio of each vehicle [-], (V,)
    low_ratios : array, two-speed axle low ratio [-], NaN for single-speed axles, (V,)
    mode : str, ``map2d`` or ``map3d``
    physics : str, the baseline name
    ambient_temp_C : float or None, ambient temperature [C]
    cache_dir : str or Path or None, the map3d cache directory
    kim_scales_Nm : array or None, the vehicles' Kim scales [N m], (V,)

    Returns
    -------
    (maps of input torque fractions [-] (M, 2, N_U, N_SPEED), map index per vehicle (V,),
    top of each map's speed grid [rpm] (M,)).
    """
    V = len(configurations)
    lows = [None if low != low else low for low in np.asarray(low_ratios, float).tolist()]   # NaN: single speed
    scales = ([None] * V if kim_scales_Nm is None or map_torque_scale_Nm(physics, 1.0) is None else
              [map_torque_scale_Nm(physics, k) for k in np.asarray(kim_scales_Nm, float).tolist()])
    keys: dict = {}
    index = np.array([keys.setdefault(key, len(keys)) for key in
                      zip(configurations, np.asarray(gear_ratios, float).tolist(), lows, scales)], np.intp).reshape(V)
    maps = np.empty((len(keys), 2, N_U, N_SPEED))
    n_max = np.empty(len(keys))
    grids = {}
    for (cfg, G, lowv, scale), m in keys.items():
        n_max[m] = speed_grid(cfg)[-1]
        if mode == "map2d" or outside_map3d_grid(cfg, G):
            # map2d, or a ratio beyond the cached grid: the maps at the vehicle's own ratio
            maps[m] = own_ratio_maps(cfg, G, lowv, physics, ambient_temp_C, scale)
            continue
        if (cfg, lowv, scale) not in grids:
            grids[(cfg, lowv, scale)] = map3d(cfg, lowv, physics, ambient_temp_C, cache_dir, scale)
        gears, grid_maps = grids[(cfg, lowv, scale)]
        i = min(int(np.searchsorted(gears, G, side="right")) - 1, gears.size - 2)
        w = (G - gears[i]) / (gears[i + 1] - gears[i])
        maps[m] = (1.0 - w) * grid_maps[:, i] + w * grid_maps[:, i + 1]
    return maps, index, n_max


def interp_maps(maps, n_max, map_id, axle_low, out_frac, speed_rpm, per_step=False):
    """Bilinear lookup T_in/kim = maps[map_id, range](sqrt(out_frac), speed) (arrays of one shape;
    ``map_id`` and ``axle_low``, the range, may broadcast against them).

    ``n_max`` is the top of each map's speed grid, per map (or per step with ``per_step``).
    Speed is clamped to the grid; the output-torque axis extrapolates linearly past 1.1.

    Parameters
    ----------
    maps : array, inverse maps [-], (M, 2, N_U, N_SPEED) (:func:`vehicle_maps`)
    n_max : array, top of the speed grid [rpm], per map (M,) or, with ``per_step``, per step
    map_id : int or array, map index of each step
    axle_low : bool or array, the low range is engaged
    out_frac : float or array, output torque fraction T_out / (kim G_tot) [-]
    speed_rpm : float or array, differential input speed [rpm]
    per_step : bool, ``n_max`` is already given per step

    Returns
    -------
    input torque fraction T_in / kim [-], the shape of ``out_frac``.
    """
    du = U_MAX / (N_U - 1)
    # in place where possible (the same arithmetic, fewer temporaries); the cell indices are
    # kept as floats (whole numbers: trunc is the integer part the cast to int gives, so the
    # weights are the same) and cast to int once, for the gather
    u = np.asarray(bounds.maximum(out_frac, 0.0), float)
    np.sqrt(u, out=u)
    u /= du
    i = np.trunc(u)
    bounds.minimum(i, N_U - 2.0, out=i)
    wu = u - i
    top = n_max if per_step else n_max[map_id]
    s = np.asarray(speed_rpm * ((N_SPEED - 1) / top), float)
    bounds.minimum(s, N_SPEED - 1.0, out=s)
    j = np.trunc(s)
    bounds.minimum(j, N_SPEED - 2.0, out=j)
    ws = s - j
    flat = maps.reshape(-1)
    # flat index ((map_id * 2 + range) * N_U + i) * N_SPEED + j (whole numbers: exact in any order)
    i *= N_SPEED
    i += j
    if np.ndim(axle_low) and np.size(axle_low) > np.size(map_id):   # a range per step: added where low
        i += map_id * float(2 * N_U * N_SPEED)
        np.add(i, float(N_U * N_SPEED), out=i, where=np.asarray(axle_low, bool))
    else:
        i += (map_id * 2 + np.asarray(axle_low, np.intp)) * float(N_U * N_SPEED)
    base = i.astype(np.intp)
    m00 = flat.take(base)
    base += 1
    m01 = flat.take(base)
    base += N_SPEED - 1
    m10 = flat.take(base)
    base += 1
    m11 = flat.take(base)
    m01 -= m00
    m01 *= ws
    m01 += m00          # a = m00 + ws (m01 - m00)
    m11 -= m10
    m11 *= ws
    m11 += m10          # b = m10 + ws (m11 - m10)
    m11 -= m01
    m11 *= wu
    m11 += m01          # a + wu (b - a)
    return m11
