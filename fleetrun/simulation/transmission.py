"""Transmission: shift schedule, gear efficiency, torque converter (thesis Ch. 2, 5.2.1.C).

All functions are backward ("what must the input do so that the output does this") and
vectorised over vehicles x steps.

Shift schedule (documented in docs/simulation.md): a stateless "lowest engine speed that
still has reserve" rule, as in economy schedules of backward simulators (ADVISOR, FASTSim's
auto-shift): in every step choose the highest gear (smallest overall ratio) in which the
engine turns at least

    n_req = min(max(n_shift_min, n_power), n_rated),  n_power = P_demand / (reserve x T_peak)
                                        (the speed at which reserve x peak torque gives
                                        the power demanded),

falling back to first gear. Two-speed (dual) axles act as a range splitter: the schedule
chooses among all transmission-gear x axle-gear products (thesis Sec. 2.2.6.B leaves the
choice to the drive-cycle driver model), so the low axle range is used exactly when the high
range would lug the engine. Being stateless it is vectorisable and needs no hysteresis.

Torque converter (Kotwicki 1982 form, fitted to the usual curves): torque ratio falls
linearly from the stall ratio TR_s at speed ratio SR = 0 to 1 at the coupling point SR_c,
and the pump absorbs T_p = (n_p / K)^2 with a constant capacity factor K sized so that the
engine stalls the converter at ``stall_speed_rpm`` with peak torque.
"""
from __future__ import annotations

import numpy as np

COUPLING_SPEED_RATIO = 0.85   # SR where the torque ratio reaches 1 (typical converters 0.8-0.9)
MAX_SPEED_RATIO = 0.98        # slip that remains in the coupling range when unlocked


def torque_ratio(speed_ratio, stall_torque_ratio):
    """Converter torque ratio TR(SR): linear from TR_s at stall to 1 at the coupling point.

    Parameters
    ----------
    speed_ratio : float or array, SR = n_turbine / n_pump [-]
    stall_torque_ratio : float or array, TR_s [-]

    Returns
    -------
    TR [-], the broadcast shape.

    >>> torque_ratio([0.0, 0.425, 0.9], 2.0).tolist()
    [2.0, 1.5, 1.0]
    """
    sr = np.clip(speed_ratio, 0.0, 1.0)
    return np.where(sr < COUPLING_SPEED_RATIO,
                    stall_torque_ratio + (1.0 - stall_torque_ratio) * sr / COUPLING_SPEED_RATIO, 1.0)


def converter_speed_ratio(turbine_speed_rpm, turbine_torque_Nm, K_rpm_per_sqrtNm, stall_torque_ratio):
    """Speed ratio SR = n_t / n_p of an unlocked converter delivering T_t > 0 at n_t.

    Solves TR(SR) (n_t / (SR K))^2 = T_t in closed form: in the coupling range
    SR = n_t / (K sqrt(T_t)); below it the quadratic T_t SR^2 - b SR - c TR_s = 0 with
    c = (n_t / K)^2 and b = c (1 - TR_s) / SR_c.

    Parameters
    ----------
    turbine_speed_rpm : float or array, n_t [rpm]
    turbine_torque_Nm : float or array, T_t [N m]
    K_rpm_per_sqrtNm : float or array, capacity factor K [rpm / sqrt(N m)]
    stall_torque_ratio : float or array, TR_s [-]

    Returns
    -------
    SR [-] in [0, :data:`MAX_SPEED_RATIO`], the broadcast shape.
    """
    nt = np.maximum(turbine_speed_rpm, 0.0)
    Tt = np.maximum(turbine_torque_Nm, 1e-9)
    c = (nt / K_rpm_per_sqrtNm) ** 2
    sr_coupling = nt / (K_rpm_per_sqrtNm * np.sqrt(Tt))
    b = c * (1.0 - stall_torque_ratio) / COUPLING_SPEED_RATIO
    sr_converter = (b + np.sqrt(b * b + 4.0 * Tt * c * stall_torque_ratio)) / (2.0 * Tt)
    sr = np.where(sr_coupling >= COUPLING_SPEED_RATIO, sr_coupling, sr_converter)
    return np.clip(sr, 0.0, MAX_SPEED_RATIO)


def capacity_factor(stall_speed_rpm, peak_torque_Nm, stall_torque_ratio=None):
    """K [rpm / sqrt(N m)] so that peak engine torque holds the pump at ``stall_speed_rpm``.

    Parameters
    ----------
    stall_speed_rpm : float or array, [rpm]
    peak_torque_Nm : float or array, T_peak [N m]
    stall_torque_ratio : unused (kept for callers that pass it)

    Returns
    -------
    K [rpm / sqrt(N m)].

    >>> float(capacity_factor(2000.0, 400.0))
    100.0
    """
    return np.asarray(stall_speed_rpm, float) / np.sqrt(np.asarray(peak_torque_Nm, float))


def input_torque_Nm(output_torque_Nm, ratio, efficiency, spin_loss_Nm=0.0):
    """Gearbox input torque for a demanded output torque: mesh efficiency plus spin loss.

    Drive: T_in = T_out / (r eta) + T_spin. Overrun (T_out < 0) is given the same mesh loss
    magnitude as drive at |T_out|: T_in = T_out / r + (1 - eta) |T_out| / (r eta) + T_spin.
    The spin loss (:func:`spin_loss_Nm`) drags in either direction. This is the structure of
    EPA ALPHA's transmission model (gear-mesh efficiency times a speed-dependent spin and pump
    loss; Newman, Kargul & Barba, SAE 2015-01-1142) with one efficiency per gear kind.

    Parameters
    ----------
    output_torque_Nm : float or array, T_out [N m] (negative on overrun)
    ratio : float or array, r [-]
    efficiency : float or array, eta [-]
    spin_loss_Nm : float or array, T_spin [N m]

    Returns
    -------
    T_in [N m], the broadcast shape.

    >>> round(float(input_torque_Nm(300.0, 3.0, 0.98, 2.0)), 3)
    104.041
    """
    T = np.asarray(output_torque_Nm, float)
    return T / ratio + (1.0 - efficiency) * np.abs(T) / (ratio * efficiency) + spin_loss_Nm


def spin_loss_Nm(input_speed_rpm, spin_loss_Nm_at_0, spin_loss_Nm_per_krpm):
    """Gearbox spin and pump loss torque at the input [N m]: a + b n / 1000 (0 at standstill).

    Parameters
    ----------
    input_speed_rpm : float or array, gearbox input (turbine) speed n [rpm]
    spin_loss_Nm_at_0 : float or array, a [N m], the pump and drag torque extrapolated to zero speed
    spin_loss_Nm_per_krpm : float or array, b [N m per 1000 rpm], its rise with speed (oil
        churning and clutch drag)

    Returns
    -------
    loss torque [N m], the broadcast shape.

    >>> spin_loss_Nm([0.0, 2000.0], 2.0, 1.0).tolist()
    [0.0, 4.0]
    """
    n = np.asarray(input_speed_rpm, float)
    loss = spin_loss_Nm_at_0 + spin_loss_Nm_per_krpm * n / 1000.0
    turning = n > 0
    return loss if turning.all() and np.shape(loss) == turning.shape else np.where(turning, loss, 0.0)


def cvt_ratio(wheel_side_speed_rpm, required_engine_speed_rpm, max_ratio, min_ratio):
    """Ratio of a continuously variable transmission: the engine speed the schedule asks for.

    The same economy schedule as the stepped gearboxes (lowest engine speed with power
    reserve, n_req), but met exactly, r = n_req / n_out, within the variator's range
    [min_ratio, max_ratio] (the largest ratio at launch and at low speed). This is how
    backward simulators drive a CVT on an operating line (e.g. FASTSim's and ADVISOR's CVT:
    engine speed chosen for the power demand, ratio follows).

    Parameters
    ----------
    wheel_side_speed_rpm : float or array, n_out, the output speed at ratio 1 [rpm]
    required_engine_speed_rpm : float or array, n_req [rpm]
    max_ratio, min_ratio : float or array, the variator's range [-]

    Returns
    -------
    r [-], the broadcast shape.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.asarray(required_engine_speed_rpm, float) / np.asarray(wheel_side_speed_rpm, float)
    return np.clip(np.where(np.isfinite(r), r, max_ratio), min_ratio, max_ratio)


def converter_unlocked(first_gear, turbine_speed_rpm, lockup_speed_rpm, has_lockup):
    """Where an automatic's torque converter slips: always without a lock-up clutch (the EPA
    list's ``Transmission Lockup?`` = N), else in first gear (at launch) and below the lock-up
    turbine speed.

    Parameters
    ----------
    first_gear : bool array, in first gear (or a CVT at its largest ratio)
    turbine_speed_rpm : float or array, [rpm]
    lockup_speed_rpm : float or array, [rpm]
    has_lockup : bool or array, the converter has a lock-up clutch

    Returns
    -------
    bool array, True where the converter slips.
    """
    return ~np.asarray(has_lockup, bool) | first_gear | (turbine_speed_rpm < lockup_speed_rpm)


def choose_gear(wheel_side_speed_rpm, required_engine_speed_rpm, max_engine_speed_rpm, overall_ratios, n_ratios):
    """Index of the highest usable gear per step (the schedule above).

    ``wheel_side_speed_rpm`` (V x N): speed the gearbox output would turn at ratio 1;
    ``required_engine_speed_rpm`` (V x N); ``overall_ratios`` (V x K) sorted from the
    largest (first gear) down, padded with 0 beyond ``n_ratios``. A gear that would turn the
    engine above ``max_engine_speed_rpm`` (V x 1, rated speed) is not used while a lower
    one is available: at full demand that picks the gear nearest rated speed. Returns int (V x N).

    Parameters
    ----------
    wheel_side_speed_rpm : array (V x N), [rpm]
    required_engine_speed_rpm : array (V x N), [rpm]
    max_engine_speed_rpm : array (V x 1), [rpm]
    overall_ratios : array (V x K), [-]
    n_ratios : int array (V,), the gears each vehicle has

    Returns
    -------
    int array (V x N), the gear index (0 = first).
    """
    V, K = overall_ratios.shape
    # compare ratios with the ratio thresholds instead of engine speeds with the speeds:
    # one division per step instead of a multiplication per gear
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / wheel_side_speed_rpm
    need = required_engine_speed_rpm * inv
    limit = max_engine_speed_rpm * inv
    count = np.zeros(np.shape(need), dtype=np.int8)
    hit = np.empty(count.shape, bool)
    for k in range(K):  # count += ratio >= need, without a temporary or a cast per gear
        np.greater_equal(overall_ratios[:, k:k + 1], need, out=hit)
        np.add(count, hit.view(np.int8), out=count)
    top = np.asarray(n_ratios)[:, None] - 1
    if (K < 128 and np.ndim(need) == 2 and need.shape == limit.shape
            and (overall_ratios[:, :-1] >= overall_ratios[:, 1:]).all()
            and (need <= limit).all()):
        # ratios sorted and need <= limit: the gears above the limit are the first ``over`` of
        # the ``count`` gears at or above need (over <= count), so max(count - 1, over) is count
        # where the last of those is above the limit (or count is 0), else count - 1
        # (in int8 up to the gather index and the result: K < 128 gears, the same whole numbers)
        res = count - np.int8(1)
        last = np.maximum(res, np.int8(0)).astype(np.intp)
        last += np.arange(V)[:, None] * K
        above = overall_ratios.reshape(-1).take(last) > limit
        above |= count == 0
        res += above.view(np.int8)
        np.minimum(res, top.astype(np.int8), out=res)
        return res.astype(np.intp)
    over = np.zeros(np.shape(wheel_side_speed_rpm), dtype=np.int8)
    for k in range(K):
        over += overall_ratios[:, k:k + 1] > limit
    return np.minimum(np.maximum(count.astype(np.intp) - 1, over), top)
