"""Engine: full-load torque curve, friction, pumping and fuel rate (gasoline and diesel).

Fuel (a Willans line whose offset is built from Chen-Flynn friction, throttle pumping and an
accessory load, and whose slope rises at high load):

    m_dot LHV = [ P_b (1 + k_hl L) + (FMEP + PMEP) V_d omega / (4 pi) + P_acc + k_tr P_acc+ ] / eta_ind

- P_b = T_e omega the brake power (T_e >= 0), L = T_e / T_max(n) the load fraction;
- FMEP = f_0 + f_cm c_m + f_pk bmep_max: Chen & Flynn (SAE 650733, 1965; Heywood 1988,
  Eq. 13.16) write the friction mean effective pressure as A + B p_max + C c_m + D c_m^2 with
  c_m = 2 S n the mean piston speed and p_max the peak cylinder pressure; here p_max is taken
  in proportion to the engine's peak brake mean effective pressure bmep_max = 4 pi T_peak / V_d
  (a boosted engine of high specific torque has higher peak pressures and bearing loads), and
  the c_m^2 term is left out (the certification cycles do not separate it from c_m). The
  same linear-in-c_m friction appears in the JRC CO2MPAS normalised fuel map,
  BMEP = (a + b c_m + c c_m^2) FuMEP - (l + l2 c_m^2);
- PMEP = p_th (1 - L) for throttled (spark-ignition) engines: the intake is throttled to the
  load, so the pumping work falls from about p_th at closed throttle to 0 at full load
  (Heywood 1988, Sec. 13.3); unthrottled diesels have PMEP = 0;
- P_acc: a constant accessory load (alternator, pumps) while the engine runs (EPA ALPHA
  models it as a constant electrical plus mechanical accessory power);
- k_hl: the fall of efficiency towards full load (enrichment and spark retard of gasoline
  engines; smoke-limited injection of diesels): the Willans slope rises by k_hl at full load;
- P_acc+ = max(m (1 + f_rot) a v, 0), the power going into the vehicle's kinetic energy, and
  k_tr the extra fuel an acceleration costs beyond its brake work: the acceleration term of
  the ARRB power-based fuel model (Bowyer, Akcelik & Biggs 1985, ARRB Special Report 39;
  Akcelik & Besley 2003), which lumps what a backward model at 1 Hz does not resolve during
  accelerations: transient enrichment and wall-wetting (Heywood 1988, Sec. 7.6), converter
  slip and the lower gears of real shift schedules while accelerating, the engine's own
  inertia. Fitted on the EPA list, it is what separates the city and US06 fuel from the
  highway's (docs/validation-epa.md).

The equation is linear in the eight coefficients (1, k_hl, f_0, f_cm, f_pk, p_th, P_acc, k_tr)
/ eta_ind, so :func:`fuel_power_terms_W` returns its terms and :func:`fuel_rate_g_per_s`
weights them: the fleet-wide calibration (validation/epa_fuel_economy.py) sums the same terms
over each cycle and fits the coefficients by least squares. Idle is the same equation at idle
speed and zero load unless the vehicle gives ``idle_fuel_g_per_s``; on overrun above the fuel
cut-off speed the injectors are shut. Engine braking is limited to the motoring torque
(friction and closed-throttle pumping, :func:`motoring_torque_Nm`).
"""
from __future__ import annotations

import numpy as np

from fleetrun.simulation import bounds
from fleetrun.units import RAD_S_PER_RPM

FUEL_TERMS = ("brake", "brake_high_load", "friction", "friction_piston_speed", "friction_peak_pressure",
              "pumping", "accessory", "transient")


def stroke_m(displacement_L, cylinders, bore_stroke_ratio=1.0):
    """Stroke S [m] of ``cylinders`` equal cylinders of bore B = ratio x S sweeping ``displacement_L``.

    V_cyl = pi/4 B^2 S  ->  S = (4 V_cyl / (pi ratio^2))^(1/3); square engines (ratio 1) by default.

    Parameters
    ----------
    displacement_L : float or array, V_d [L]
    cylinders : int or array, number of cylinders
    bore_stroke_ratio : float or array, B / S [-]

    Returns
    -------
    stroke S [m].

    >>> round(float(stroke_m(2.0, 4)), 4)
    0.086
    """
    v_cyl = np.asarray(displacement_L, float) * 1e-3 / np.asarray(cylinders, float)
    return np.cbrt(4.0 * v_cyl / (np.pi * np.asarray(bore_stroke_ratio, float) ** 2))


def mean_piston_speed_m_s(speed_rpm, stroke_m):
    """Mean piston speed c_m = 2 S n [m/s] (Heywood 1988, Eq. 2.2).

    Parameters
    ----------
    speed_rpm : float or array, n [rpm]
    stroke_m : float or array, S [m]

    Returns
    -------
    c_m [m/s], the broadcast shape.

    >>> round(float(mean_piston_speed_m_s(3000.0, 0.086)), 2)
    8.6
    """
    return (np.asarray(stroke_m, float) * (2.0 / 60.0)) * np.asarray(speed_rpm, float)   # per-engine factor first


def mep_power_W_per_kPa(speed_rpm, displacement_L):
    """Power [W] of 1 kPa of mean effective pressure in a four-stroke engine: V_d omega / (4 pi).

    Parameters
    ----------
    speed_rpm : float or array, n [rpm]
    displacement_L : float or array, V_d [L]

    Returns
    -------
    power per kPa of mean effective pressure [W/kPa].

    >>> round(float(mep_power_W_per_kPa(3000.0, 2.0)), 2)
    50.0
    """
    return (np.asarray(displacement_L, float) * (RAD_S_PER_RPM / (4.0 * np.pi))) * np.asarray(speed_rpm, float)


def load_fraction(torque_Nm, max_torque_Nm, positive_torque_Nm=None):
    """L = T_e / T_max in [0, 1] (0 on overrun).

    Parameters
    ----------
    torque_Nm : float or array, brake torque T_e [N m]
    max_torque_Nm : float or array, full-load torque at the same speed [N m]
    positive_torque_Nm : array or None, max(T_e, 0) [N m] if the caller has it (not changed)

    Returns
    -------
    L [-] in [0, 1], the broadcast shape.

    >>> load_fraction([-5.0, 50.0, 300.0], 200.0).tolist()
    [0.0, 0.25, 1.0]
    """
    positive = bounds.maximum(torque_Nm, 0.0) if positive_torque_Nm is None else positive_torque_Nm
    load = positive / bounds.maximum(max_torque_Nm, 1e-9)
    return bounds.minimum(load, 1.0, out=load) if isinstance(load, np.ndarray) else min(load, 1.0)


def fuel_power_terms_W(torque_Nm, speed_rpm, max_torque_Nm, displacement_L, stroke_m, peak_torque_Nm, throttled,
                       inertial_power_W=0.0, pumping_share=None, brake_gain=None, load=None, positive_torque_Nm=None,
                       piston_speed_m_s=None):
    """The eight terms of the fuel equation (module docstring), in the order of FUEL_TERMS.

    Parameters
    ----------
    torque_Nm : brake torque T_e (negative on overrun: no brake power).
    speed_rpm : engine speed n.
    max_torque_Nm : full-load torque at n (:func:`full_load_torque_Nm`).
    displacement_L, stroke_m, peak_torque_Nm : the engine's V_d, S and T_peak.
    throttled : bool, True for spark-ignition (gasoline) engines.
    inertial_power_W : m (1 + f_rot) a v of the vehicle (only its positive part counts).
    pumping_share : the throttle-pumping share in place of (1 - L) (technology classes,
        fleetrun/simulation/technology.py); None: (1 - L).
    brake_gain : multiplier of the two brake-work terms (a higher expansion ratio); None: 1.
    load : :func:`load_fraction` of ``torque_Nm`` and ``max_torque_Nm`` if the caller has it.
    positive_torque_Nm : max(T_e, 0) [N m] if the caller has it (not changed).
    piston_speed_m_s : :func:`mean_piston_speed_m_s` at ``speed_rpm`` [m/s] if the caller has it.

    Returns
    -------
    list of arrays [W per unit coefficient]: P_b, P_b L, mep power (per kPa) x 1,
    x c_m [m/s], T_peak omega (the bmep_max term: f_pk bmep_max V_d omega / (4 pi) = f_pk T_peak
    omega), mep power x (1 - L) for throttled engines, 1, max(inertial power, 0). Terms that
    do not vary with the step keep their own (broadcastable) shape.
    """
    n = np.asarray(speed_rpm, float)
    omega = n * RAD_S_PER_RPM
    positive = bounds.maximum(torque_Nm, 0.0) if positive_torque_Nm is None else positive_torque_Nm
    brake_W = positive * omega
    load = load_fraction(torque_Nm, max_torque_Nm, positive) if load is None else load
    mep = mep_power_W_per_kPa(n, displacement_L)
    pumping_W = ((1.0 - load) if pumping_share is None else np.asarray(pumping_share, float)) * mep
    if not _ones_within(throttled, pumping_W):   # x 1 (every engine throttled) changes nothing
        pumping_W = pumping_W * throttled
    if brake_gain is not None:       # technology classes: a higher expansion ratio
        brake_W = np.multiply(brake_W, brake_gain, out=brake_W if _fits(brake_W, brake_gain) else None)
    brake_high_load_W = brake_W * load
    c_m = mean_piston_speed_m_s(n, stroke_m) if piston_speed_m_s is None else piston_speed_m_s
    # the accessory term is 1 and the peak-pressure and transient terms keep their own shape:
    # they broadcast in fuel_rate_g_per_s instead of filling a vehicles x steps array each
    return [brake_W, brake_high_load_W, mep, mep * c_m, np.asarray(peak_torque_Nm) * omega, pumping_W,
            np.float64(1.0), bounds.maximum(inertial_power_W, 0.0)]


def _fits(values, other) -> bool:
    """Whether ``values`` (an array of its own) can take the result of an operation with ``other`` in place."""
    return isinstance(values, np.ndarray) and np.broadcast(values, other).shape == values.shape


def _ones_within(flags, values) -> bool:
    """Whether multiplying ``values`` by the bool array ``flags`` would change nothing: every
    flag true and ``values`` already of the broadcast shape."""
    return (isinstance(flags, np.ndarray) and isinstance(values, np.ndarray) and flags.dtype == bool
            and flags.ndim <= values.ndim and np.broadcast_shapes(flags.shape, values.shape) == values.shape
            and bool(flags.all()))


def fuel_coefficients(eta_indicated, high_load_factor, fmep_0_kPa, fmep_piston_speed_kPa_s_per_m,
                      fmep_peak_fraction, pmep_throttle_kPa, accessory_power_W, transient_factor):
    """Weights of :func:`fuel_power_terms_W`: (1, k_hl, f_0, f_cm, f_pk, p_th, P_acc, k_tr) / eta_ind.

    Fitted fleet-wide in models/engine_calibration.toml.

    Parameters
    ----------
    eta_indicated : float or array, the Willans slope [-]
    high_load_factor : float or array, k_hl [-]
    fmep_0_kPa : float or array, f_0 [kPa]
    fmep_piston_speed_kPa_s_per_m : float or array, f_cm [kPa s/m]
    fmep_peak_fraction : float or array, f_pk [-] (of bmep_max)
    pmep_throttle_kPa : float or array, p_th [kPa]
    accessory_power_W : float or array, P_acc [W]
    transient_factor : float or array, k_tr [-]

    Returns
    -------
    list of eight float arrays, the coefficients divided by eta_indicated (units of the inputs).
    """
    parts = (1.0, high_load_factor, fmep_0_kPa, fmep_piston_speed_kPa_s_per_m, fmep_peak_fraction,
             pmep_throttle_kPa, accessory_power_W, transient_factor)
    return [np.asarray(p, float) / eta_indicated for p in parts]


def fuel_rate_g_per_s(terms, coefficients, fueled, lhv_MJ_per_kg):
    """Fuel rate [g/s] = sum(coefficient x term) / LHV; 0 where ``fueled`` is False (fuel cut-off).

    Never negative. ``terms`` from :func:`fuel_power_terms_W`, ``coefficients`` from
    :func:`fuel_coefficients` (arrays that broadcast against the terms).

    Parameters
    ----------
    terms : list of arrays, :func:`fuel_power_terms_W` [W per unit coefficient]
    coefficients : list of floats or arrays, :func:`fuel_coefficients` [-, kPa, W, ... / eta]
    fueled : bool or array, False where the injectors are shut
    lhv_MJ_per_kg : float or array, the fuel's lower heating value [MJ/kg]

    Returns
    -------
    fuel rate [g/s], the broadcast shape.
    """
    shape = np.broadcast(*terms, *coefficients).shape
    power = np.zeros(shape)
    scratch = np.empty(shape)
    small = 0.0     # terms that do not vary over the steps (e.g. the accessory load) add once
    for term, c in zip(terms, coefficients):
        if np.shape(term) == shape:            # in place: vehicles x steps arrays
            np.multiply(term, c, out=scratch)
            power += scratch
        else:
            small = small + np.multiply(term, c)
    power += small
    bounds.maximum(power, 0.0, out=power)
    power /= np.asarray(lhv_MJ_per_kg, float) * 1e3
    if not _ones_within(fueled, power):   # x 1 (fuel nowhere cut off) changes nothing
        power *= fueled
    return power


def motoring_torque_Nm(speed_rpm, displacement_L, stroke_m, peak_torque_Nm, fmep_0_kPa,
                       fmep_piston_speed_kPa_s_per_m, fmep_peak_fraction, pmep_throttle_kPa, throttled,
                       piston_speed_m_s=None):
    """Torque [N m] to turn the unfuelled engine: friction plus closed-throttle pumping,
    (FMEP + PMEP(L=0)) V_d / (4 pi) with FMEP as in the module docstring.

    Parameters
    ----------
    speed_rpm : float or array, n [rpm]
    displacement_L : float or array, V_d [L]
    stroke_m : float or array, S [m]
    peak_torque_Nm : float or array, T_peak [N m] (the bmep_max term)
    fmep_0_kPa, fmep_piston_speed_kPa_s_per_m, fmep_peak_fraction : float or array, f_0 [kPa], f_cm [kPa s/m], f_pk [-]
    pmep_throttle_kPa : float or array, p_th [kPa]
    throttled : bool or array, spark-ignition (gasoline) engine
    piston_speed_m_s : array or None, :func:`mean_piston_speed_m_s` at ``speed_rpm`` [m/s] if the
        caller has it (not changed)

    Returns
    -------
    motoring torque [N m] (positive: what it takes to turn the engine), the broadcast shape.
    """
    # per-engine factors first (arrays of vehicles x 1), one pass over the steps for each of
    # c_m, f_cm c_m and the sum
    per_kPa = np.asarray(displacement_L, float) / (4.0 * np.pi)           # [N m per kPa]
    constant = (fmep_0_kPa + np.where(throttled, pmep_throttle_kPa, 0.0)) * per_kPa + fmep_peak_fraction * peak_torque_Nm
    if piston_speed_m_s is None:
        torque = mean_piston_speed_m_s(speed_rpm, stroke_m)
        torque *= fmep_piston_speed_kPa_s_per_m * per_kPa
    else:
        torque = piston_speed_m_s * (fmep_piston_speed_kPa_s_per_m * per_kPa)
    torque += constant
    return torque


def full_load_torque_Nm(speed_rpm, peak_torque_Nm, rated_power_kW, rated_speed_rpm,
                        idle_speed_rpm, peak_torque_speed_rpm, idle_torque_fraction):
    """Maximum brake torque [N m] at ``speed_rpm``.

    Rises linearly from ``idle_torque_fraction`` x peak at idle to peak at the peak-torque
    speed, is capped by rated power (T = P / omega) and falls to zero 10 % above rated speed
    (governor / rev limiter). Evaluated in place in one array of the arguments' broadcast
    shape (no temporaries for vehicles x steps arrays).

    Parameters
    ----------
    speed_rpm : float or array, n [rpm]
    peak_torque_Nm : float or array, T_peak [N m]
    rated_power_kW : float or array, P_rated [kW]
    rated_speed_rpm, idle_speed_rpm, peak_torque_speed_rpm : float or array, [rpm]
    idle_torque_fraction : float or array, full-load torque at idle / T_peak [-]

    Returns
    -------
    torque [N m], the broadcast shape (a float for float arguments).

    >>> round(float(full_load_torque_Nm(3000.0, 200.0, 100.0, 6000.0, 700.0, 4000.0, 0.7)), 2)
    181.82
    """
    n = np.asarray(speed_rpm, float)
    rise = np.clip((n - idle_speed_rpm) / np.maximum(peak_torque_speed_rpm - idle_speed_rpm, 1.0), 0.0, 1.0)
    shape = np.broadcast(rise, peak_torque_Nm, rated_power_kW, rated_speed_rpm, idle_torque_fraction).shape
    torque = np.multiply(rise, 1.0 - idle_torque_fraction, out=np.empty(shape))
    torque += idle_torque_fraction
    torque *= peak_torque_Nm
    power_cap = np.multiply(n, RAD_S_PER_RPM, out=np.empty(shape))
    bounds.maximum(power_cap, 1e-9, out=power_cap)
    np.divide(rated_power_kW * 1e3, power_cap, out=power_cap)
    np.minimum(torque, power_cap, out=torque)
    governor = np.subtract(1.1 * rated_speed_rpm, n, out=power_cap)
    governor /= 0.1 * rated_speed_rpm
    np.clip(governor, 0.0, 1.0, out=governor)
    torque *= governor
    return torque if torque.ndim else torque[()]
