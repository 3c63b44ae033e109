"""Engine and powertrain technology classes as physics (the Vehicles column ``technology``).

Each class is a named model function; constants in ``models/technology.toml`` (docs/simulation.md
"Technology"):

- ``start_stop``: engine off at standstill once warm (:func:`engine_off_at_stop`);
- ``mild_hybrid_48v``, ``p2_hybrid``: regenerative braking to a small battery, the recovered
  energy returned as assist, engine off while coasting (:func:`recovered_braking_energy_J`,
  :func:`assist_share`, :func:`engine_off_coasting`); both also stop the engine at standstill;
- ``atkinson``, ``miller``: late intake-valve closing and a higher expansion ratio
  (:func:`atkinson_pumping_share`, :func:`expansion_ratio_gain`);
- ``cylinder_deactivation``: half the cylinders off at light load (:func:`deactivated_pumping_share`);
- ``turbo``: boosted engine unthrottled above the naturally aspirated bmep (:func:`boosted_pumping_share`).

The pumping functions give the throttle-pumping share that replaces (1 - L) in the fuel
equation (fleetrun/simulation/engine.py): PMEP = p_th x share.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from fleetrun.errors import unknown_name_error
from fleetrun.resources import model_file
from fleetrun.simulation import bounds

TECHNOLOGIES = ("start_stop", "mild_hybrid_48v", "p2_hybrid", "atkinson", "miller", "cylinder_deactivation", "turbo")
HYBRIDS = ("mild_hybrid_48v", "p2_hybrid")
NONE = "none"


def parse_technology(text) -> tuple[bool, ...]:
    """A ``technology`` cell (comma list, blank or ``none``) -> one flag per TECHNOLOGIES name.

    Parameters
    ----------
    text : str, float (NaN: blank) or None, the cell

    Returns
    -------
    tuple of bool, one per :data:`TECHNOLOGIES` name.

    >>> parse_technology("start_stop, Turbo")
    (True, False, False, False, False, False, True)
    """
    if text is None or (isinstance(text, float) and np.isnan(text)):
        return (False,) * len(TECHNOLOGIES)
    names = {t.strip().lower().replace("-", "_").replace(" ", "_") for t in str(text).split(",")} - {"", NONE}
    for name in names:
        if name not in TECHNOLOGIES:
            raise unknown_name_error("technology", name, TECHNOLOGIES + (NONE,),
                                     hint="Write a comma list of these names, or leave the cell blank")
    return tuple(t in names for t in TECHNOLOGIES)


@dataclass(frozen=True)
class TechnologyConstants:
    inhibit_after_cold_start_s: float
    round_trip_efficiency: float
    motor_power_48v_W: float
    motor_power_p2_W: float
    max_assist_share: float
    pumping_retained: float
    compression_ratio_base: float
    compression_ratio_atkinson: float
    compression_ratio_miller: float
    gamma: float
    deac_max_load: float
    deac_min_rpm: float
    deac_max_rpm: float
    na_bmep_kPa: float
    stop_fuel_power_W: float


@lru_cache(maxsize=1)
def technology_constants() -> TechnologyConstants:
    """models/technology.toml as :class:`TechnologyConstants`.

    Returns
    -------
    TechnologyConstants (units in its field names; sources in models/technology.toml).
    """
    m = model_file("technology.toml")
    h, a, d = m["hybrid"], m["atkinson"], m["cylinder_deactivation"]
    return TechnologyConstants(
        m["start_stop"]["inhibit_after_cold_start_s"], h["round_trip_efficiency"],
        1e3 * h["motor_power_kW"]["mild_hybrid_48v"], 1e3 * h["motor_power_kW"]["p2_hybrid"], h["max_assist_share"],
        a["pumping_retained"], a["compression_ratio_base"], a["compression_ratio"]["atkinson"],
        a["compression_ratio"]["miller"], a["gamma"], d["max_load"], d["min_rpm"],
        d["max_rpm"], m["turbo"]["na_bmep_kPa"], m["fitted"]["stop_fuel_power_W"])


def otto_efficiency(compression_ratio, gamma):
    """Ideal Otto-cycle efficiency 1 - r^(1 - gamma) (Heywood 1988, Eq. 5.31).

    Parameters
    ----------
    compression_ratio : float or array, r [-]
    gamma : float, ratio of specific heats [-]

    Returns
    -------
    efficiency [-].

    >>> round(float(otto_efficiency(10.0, 1.3)), 4)
    0.4988
    """
    return 1.0 - np.asarray(compression_ratio, float) ** (1.0 - gamma)


def expansion_ratio_gain(compression_ratio, compression_ratio_base, gamma):
    """Brake-work multiplier of the Willans line for a higher expansion ratio: eta_otto(base) /
    eta_otto(r) (< 1: less fuel per unit of brake work).

    Parameters
    ----------
    compression_ratio : float or array, r [-] (the Atkinson/Miller engine's)
    compression_ratio_base : float, r of the base engine [-]
    gamma : float, ratio of specific heats [-]

    Returns
    -------
    multiplier [-] of the brake-work terms.

    >>> round(float(expansion_ratio_gain(13.0, 10.0, 1.3)), 4)
    0.9293
    """
    return otto_efficiency(compression_ratio_base, gamma) / otto_efficiency(compression_ratio, gamma)


def boosted_pumping_share(torque_Nm, displacement_L, na_bmep_kPa, positive_torque_Nm=None):
    """Throttle-pumping share of a boosted engine: 1 - bmep / bmep_NA, 0 above (unthrottled).

    bmep = 4 pi T / V_d (Heywood 1988, Eq. 2.19) [kPa with V_d in L].

    Parameters
    ----------
    torque_Nm : float or array, brake torque [N m]
    displacement_L : float or array, V_d [L]
    na_bmep_kPa : float, the bmep a naturally aspirated engine reaches at wide-open throttle [kPa]
    positive_torque_Nm : array or None, max(T, 0) [N m] if the caller has it (not changed)

    Returns
    -------
    share [-] in [0, 1], the broadcast shape.

    >>> boosted_pumping_share([0.0, 100.0, 300.0], 2.0, 1000.0).round(4).tolist()
    [1.0, 0.3717, 0.0]
    """
    positive = np.maximum(torque_Nm, 0.0) if positive_torque_Nm is None else positive_torque_Nm
    bmep_kPa = np.multiply(positive, 4.0 * np.pi)
    displacement_L = np.asarray(displacement_L, float)
    if bmep_kPa.shape == np.broadcast(bmep_kPa, displacement_L).shape:   # in place: no second array
        bmep_kPa /= displacement_L
    else:
        bmep_kPa = np.divide(bmep_kPa, displacement_L)
    if not bmep_kPa.ndim:
        return np.clip(1.0 - bmep_kPa / na_bmep_kPa, 0.0, 1.0)
    bmep_kPa /= na_bmep_kPa      # the same arithmetic, in place
    return np.clip(np.subtract(1.0, bmep_kPa, out=bmep_kPa), 0.0, 1.0, out=bmep_kPa)


def atkinson_pumping_share(share, pumping_retained, out=None):
    """Late intake-valve closing: the pumping share kept (``pumping_retained`` of it).

    Parameters
    ----------
    share : float or array, the throttled engine's pumping share [-]
    pumping_retained : float, the part late intake-valve closing keeps [-]
    out : array or None, where to write the result (may be ``share``)

    Returns
    -------
    share [-].
    """
    return np.multiply(share, pumping_retained, out=out)


def deactivated_pumping_share(share, load, speed_rpm, moving, max_load, min_rpm, max_rpm, out=None):
    """Half the cylinders at twice the load: pumping of load 2L on half the displacement,
    0.5 max(1 - 2L, 0) in place of (1 - L) inside the window (load < ``max_load``, engine
    speed within [min_rpm, max_rpm], moving); ``share`` outside it.

    Parameters
    ----------
    share : array, the pumping share without deactivation [-]
    load : array, load fraction L [-]
    speed_rpm : array, engine speed [rpm]
    moving : bool array, the vehicle moves
    max_load : float, [-]
    min_rpm, max_rpm : float, the speed window [rpm]
    out : array or None, ``share`` itself to update it in place (the window's steps only)

    Returns
    -------
    share [-], the broadcast shape.
    """
    window = moving & (load < max_load) & (speed_rpm >= min_rpm) & (speed_rpm <= max_rpm)
    deactivated = _half_spare_load(load)
    if out is not None:
        np.copyto(out, deactivated, where=window)
        return out
    return np.where(window, deactivated, share)


def _half_spare_load(load):
    """0.5 max(1 - 2L, 0) for the load fraction ``load`` [-]; an array's in one array written in place."""
    if not np.ndim(load):
        return 0.5 * bounds.maximum(1.0 - 2.0 * load, 0.0)
    half = np.multiply(load, 2.0)
    np.subtract(1.0, half, out=half)
    bounds.maximum(half, 0.0, out=half)
    half *= 0.5
    return half


def engine_off_at_stop(moving, time_since_start_s, inhibit_s):
    """Steps with the engine off under start-stop: at standstill once ``inhibit_s`` have passed
    since the (cold) start.

    Parameters
    ----------
    moving : bool array, the vehicle moves
    time_since_start_s : array, [s]
    inhibit_s : float, no stop this soon after the start [s]

    Returns
    -------
    bool array, True where the engine is off.
    """
    return ~moving & (time_since_start_s >= inhibit_s)


def engine_off_coasting(moving, drive):
    """Hybrids: the engine is off (or decoupled and unfuelled) while moving without drive demand.

    Parameters
    ----------
    moving : bool array, the vehicle moves
    drive : bool array, the wheels ask for positive power

    Returns
    -------
    bool array, True where the engine is off.
    """
    return moving & ~drive


def recovered_braking_energy_J(wheel_power_W, dt_s, motor_power_W, round_trip_efficiency):
    """Energy [J] per vehicle a hybrid returns from braking: sum of min(-P_wheel, P_motor) dt
    over braking steps, times the round-trip efficiency (machine, inverter, battery, both ways).

    Parameters
    ----------
    wheel_power_W : array (V, N), power at the wheels [W] (negative while braking)
    dt_s : array (N,), step durations [s]
    motor_power_W : array (V,), the e-machine's power [W]
    round_trip_efficiency : float, [-]

    Returns
    -------
    energy [J], array (V,).

    >>> recovered_braking_energy_J([[-20000.0, 5000.0, -5000.0]], np.ones(3), np.array([10000.0]), 0.8).tolist()
    [12000.0]
    """
    braking = np.clip(-np.asarray(wheel_power_W, float), 0.0, np.asarray(motor_power_W, float)[:, None])
    return round_trip_efficiency * (braking * dt_s).sum(axis=1)


def assist_share(recovered_J, positive_engine_work_J, max_share):
    """Share of the engine's positive work the e-machine supplies from recovered energy
    (charge sustaining over the cycle), at most ``max_share``.

    Parameters
    ----------
    recovered_J : float or array (V,), recovered energy [J]
    positive_engine_work_J : float or array (V,), the engine's positive work over the cycle [J]
    max_share : float, [-]

    Returns
    -------
    share [-] in [0, max_share].

    >>> float(assist_share(1e6, 1e7, 0.2)), float(assist_share(5e6, 1e7, 0.2))
    (0.1, 0.2)
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(positive_engine_work_J > 0, recovered_J / positive_engine_work_J, 0.0)
    return np.clip(share, 0.0, max_share)
