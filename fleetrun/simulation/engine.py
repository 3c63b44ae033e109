"""Engine: full-load torque curve and fuel rate (Willans line), gasoline and diesel.

Fuel (Willans line; Heywood 1988, Sec. 13.5; Guzzella & Sciarretta 2013, Eq. 3.9): the fuel
power is the engine's brake power plus a speed-dependent offset (friction and pumping),
divided by an indicated efficiency,

    m_dot = (T_e + T_0(n)) * omega / (eta_ind * LHV),   T_0 = p_me0(n) V_d / (4 pi),

with the offset mean effective pressure p_me0 = a + b (n/1000) + c (n/1000)^2 (the
Chen-Flynn / Patton-Nitschke-Heywood form). Idle fuel is the same line at idle speed and
zero load unless the vehicle gives ``idle_fuel_g_per_s``; on overrun above the fuel cut-off
speed the injectors are shut (m_dot = 0). Displacement, rated power and speed default from
peak torque (``models/engines.toml``) when the row leaves them blank.
"""
from __future__ import annotations

import numpy as np

RPM_RAD_S = 2.0 * np.pi / 60.0


def _result_buffer(*arrays) -> np.ndarray:
    """An empty float array of the arguments' broadcast shape: each function below evaluates
    its equation once, in place in this buffer (no temporaries for vehicles x steps arrays)."""
    return np.empty(np.broadcast_shapes(*(np.shape(a) for a in arrays)))


def _scalar_if_0d(a: np.ndarray):
    return a if a.ndim else a[()]


def offset_torque_Nm(speed_rpm, displacement_L, a_kPa, b_kPa, c_kPa):
    """Willans offset torque T_0 = p_me0 V_d / (4 pi) [N m] of a four-stroke engine,
    p_me0 = a + b (n/1000) + c (n/1000)^2 [kPa]."""
    k = np.asarray(speed_rpm, float) / 1000.0
    t = np.multiply(c_kPa, k, out=_result_buffer(k, displacement_L, a_kPa, b_kPa, c_kPa))
    t += b_kPa
    t *= k
    t += a_kPa
    t *= 1e3                                  # p_me0 [Pa]
    t *= np.asarray(displacement_L, float)
    t *= 1e-3
    t /= 4.0 * np.pi
    return _scalar_if_0d(t)


def full_load_torque_Nm(speed_rpm, peak_torque_Nm, rated_power_kW, rated_speed_rpm,
                        idle_speed_rpm, peak_torque_speed_rpm, idle_torque_fraction):
    """Maximum brake torque [N m] at ``speed_rpm``.

    Rises linearly from ``idle_torque_fraction`` x peak at idle to peak at the peak-torque
    speed, is capped by rated power (T = P / omega) and falls to zero 10 % above rated speed
    (governor / rev limiter).
    """
    n = np.asarray(speed_rpm, float)
    rise = np.clip((n - idle_speed_rpm) / np.maximum(peak_torque_speed_rpm - idle_speed_rpm, 1.0), 0.0, 1.0)
    torque = np.multiply(rise, 1.0 - idle_torque_fraction,
                         out=_result_buffer(rise, peak_torque_Nm, rated_power_kW, rated_speed_rpm,
                                            idle_torque_fraction))
    torque += idle_torque_fraction
    torque *= peak_torque_Nm
    power_cap = np.multiply(n, RPM_RAD_S, out=np.empty(torque.shape))
    np.maximum(power_cap, 1e-9, out=power_cap)
    np.divide(rated_power_kW * 1e3, power_cap, out=power_cap)
    np.minimum(torque, power_cap, out=torque)
    governor = np.subtract(1.1 * rated_speed_rpm, n, out=power_cap)
    governor /= 0.1 * rated_speed_rpm
    np.clip(governor, 0.0, 1.0, out=governor)
    torque *= governor
    return _scalar_if_0d(torque)


def fuel_rate_g_per_s(torque_Nm, speed_rpm, fueled, offset_Nm, eta_indicated, lhv_MJ_per_kg):
    """Willans-line fuel rate [g/s]; 0 where ``fueled`` is False (deceleration fuel cut-off).

    Never negative: at loads below the motoring line the engine is unfuelled.
    """
    omega = np.asarray(speed_rpm, float) * RPM_RAD_S
    fuel_power_W = np.add(torque_Nm, offset_Nm,
                          out=_result_buffer(torque_Nm, offset_Nm, omega, eta_indicated, lhv_MJ_per_kg))
    np.maximum(fuel_power_W, 0.0, out=fuel_power_W)
    fuel_power_W *= omega
    fuel_power_W /= eta_indicated
    fuel_power_W /= lhv_MJ_per_kg * 1e3
    return _scalar_if_0d(np.where(fueled, fuel_power_W, 0.0))
