"""Differential-level physics the thesis model leaves out, as extra pinion torque losses.

Each function returns the *extra input torque* [N m] the effect costs at the pinion, per unit
of its linear parameter; :class:`fleetrun.effects.base.Effect` multiplies by that parameter.
The differential then passes ``T_in - dT_in`` through the thesis chain (see
:func:`fleetrun.effects.efficiency_with_effects`), so the measured half-shaft torque sum is
``G * eta(T_in - dT_in) * (T_in - dT_in)``.

Channels (numpy arrays of one length, or scalars at steady state):
``time_s`` (time since the start of the recording), ``input_torque_Nm``,
``input_speed_rad_s``, ``input_accel_rad_s2``, ``wheel_speed_difference_rad_s``
(``abs(w_L - w_R)`` at the wheels), ``ambient_temp_C``, ``oil_temp_C``; scalars
``gear_ratio`` (overall pinion-to-carrier ratio) and ``lubricant``.
"""
from __future__ import annotations

import numpy as np

from fleetrun.differential.chain import resolved_stages
from fleetrun.differential.models import reference_model
from fleetrun.effects.base import Effect, Parameter
from fleetrun.physics import gear_mesh
from fleetrun.physics.lubricant import (OPERATING_RISE_K, THESIS_OPERATING_TEMP_C, operating_temperature_C,
                                        walther_viscosity_m2_s)
from fleetrun.physics.windage import bevel_gear_windage_torque_Nm
from fleetrun.units import RPM_PER_RAD_S

#: Speed [rad/s] below which the pinion counts as stopped: Coulomb drags are regularised with
#: tanh(w / W_STOP) so that a stopped differential has no drag and the fit stays smooth.
W_STOP_RAD_S = 1.0
#: Film-thickness exponent on entraining speed, h_c0 ~ U^0.68 (seed 004, Eq. 9).
FILM_SPEED_EXPONENT = 0.68


def _rotating(w_rad_s):
    """Coulomb direction of a drag: +1 turning forward, 0 stopped, -1 turning backward."""
    return np.tanh(np.asarray(w_rad_s, dtype=float) / W_STOP_RAD_S)


# --------------------------------------------------------------------------- bearing_preload
def preload_drag_torque_Nm(input_speed_rad_s):
    """Constant drag of preloaded taper bearings and pinion seal, per N m of preload drag.

    Thesis Sec. 9.2.2 (seal pre-load) and Sec. 3.1.1.B (bearing loads): the printed bearing
    model (B.2-B.5, Khonsari & Booser Eq. 15.1 ``M_P = 5e-4 mu P d``) only has the
    torque-proportional part; a preloaded bearing keeps a drag at zero torque.

    Parameters
    ----------
    input_speed_rad_s : float or array, pinion speed w_in [rad/s]

    Returns
    -------
    drag direction per N m of preload drag [N m / N m], tanh(w_in / W_STOP_RAD_S): 1 turning
    forward, 0 stopped, -1 turning backward.
    """
    return _rotating(input_speed_rad_s)


def _basis_preload(ch):
    return preload_drag_torque_Nm(ch["input_speed_rad_s"])


# --------------------------------------------------------------------------- cornering
def cornering_extra_torque_Nm(input_torque_Nm, input_speed_rad_s, wheel_speed_difference_rad_s,
                              gear_ratio):
    """Extra pinion torque per unit k_c when the wheels turn at different speeds.

    Seed 003 (Antoni 2014), Eqs 9, 13-17: the spider/side-gear friction power grows with the
    carrier torque and the wheel-speed difference, ``P_loss = k_c T_c |w_L - w_R|`` with
    ``T_c = G T_in`` (docs/interface.md). Referred to the pinion: ``dT_in = P_loss / w_in``.
    Zero when the pinion is (nearly) stopped, where the power balance is undefined.

    Parameters
    ----------
    input_torque_Nm : float or array, pinion torque T_in [N m]
    input_speed_rad_s : float or array, pinion speed w_in [rad/s]
    wheel_speed_difference_rad_s : float or array, ``abs(w_L - w_R)`` at the wheels [rad/s]
    gear_ratio : float, overall pinion-to-carrier ratio G [-]

    Returns
    -------
    extra pinion torque per unit k_c [N m], 0 where ``|w_in| <= W_STOP_RAD_S``.
    """
    w_in = np.asarray(input_speed_rad_s, dtype=float)
    t_c = gear_ratio * np.abs(np.asarray(input_torque_Nm, dtype=float))
    p_per_kc = t_c * np.abs(np.asarray(wheel_speed_difference_rad_s, dtype=float))
    moving = np.abs(w_in) > W_STOP_RAD_S
    return np.where(moving, p_per_kc / np.where(moving, np.abs(w_in), 1.0), 0.0)


def _basis_cornering(ch):
    return cornering_extra_torque_Nm(ch["input_torque_Nm"], ch["input_speed_rad_s"],
                                     ch["wheel_speed_difference_rad_s"], ch["gear_ratio"])


# --------------------------------------------------------------------------- inertia
def inertia_torque_Nm(input_accel_rad_s2):
    """Torque per kg m^2 to accelerate the rotating parts, ``J dw_in/dt`` at the pinion.

    Thesis Sec. 3.1.4 (Eqs 3.2, 3.4) assumes constant speed; seed 001 (Brumercik et al.)
    Eqs 9-10 give the differential's reduced inertia ``I_dr`` and ``I_dr dw_r/dt``;
    referred to the pinion with Eq. 11. Negative while decelerating (the parts give back
    their energy).

    Parameters
    ----------
    input_accel_rad_s2 : float or array, pinion angular acceleration dw_in/dt [rad/s^2]

    Returns
    -------
    torque per kg m^2 of inertia referred to the pinion [N m / (kg m^2)], i.e. dw_in/dt.
    """
    return np.asarray(input_accel_rad_s2, dtype=float)


def _basis_inertia(ch):
    return inertia_torque_Nm(ch["input_accel_rad_s2"])


# --------------------------------------------------------------------------- oil_warmup
def oil_temperature_C(time_s, ambient_temp_C, tau_s, rise_K=OPERATING_RISE_K):
    """Sump temperature after a cold start: ``T_op - (T_op - T_amb) exp(-t / tau)``.

    First-order warm-up towards the thesis operating temperature ``T_op = T_amb + 50 K``
    (thesis Sec. 3.1.2; docs/interface.md oil_warmup).

    Parameters
    ----------
    time_s : float or array, time since the (cold) start [s]; negative times count as 0
    ambient_temp_C : float or array, ambient temperature T_amb [C]
    tau_s : float, warm-up time constant [s]
    rise_K : float, steady rise of T_op over ambient [K] (50 K, thesis Sec. 3.1.2)

    Returns
    -------
    sump temperature [C], the broadcast shape of ``time_s`` and ``ambient_temp_C``.
    """
    t = np.maximum(np.asarray(time_s, dtype=float), 0.0)
    t_amb = np.asarray(ambient_temp_C, dtype=float)
    return t_amb + rise_K - rise_K * np.exp(-t / tau_s)


def warmup_viscosity_excess(oil_temp_C, ambient_temp_C, lubricant, rise_K=OPERATING_RISE_K):
    """``nu(T_oil) / nu(T_op) - 1``: how much thicker the oil is than at operating temperature.

    Thesis Sec. 3.1.2 and 9.8: viscosity (Walther, B.7) governs the churning and film losses;
    the thesis evaluates it only at T_op. Clipped at 0: oil hotter than T_op is not modelled.

    Parameters
    ----------
    oil_temp_C : float or array, sump temperature T_oil [C]
    ambient_temp_C : float or array, ambient temperature T_amb [C]
    lubricant : str, a name of ``models/lubricants.toml``
    rise_K : float, rise of T_op over ambient [K] (50 K, thesis Sec. 3.1.2)

    Returns
    -------
    viscosity excess ``max(nu(T_oil) / nu(T_op) - 1, 0)`` [-].
    """
    t_op = operating_temperature_C(ambient_temp_C, rise_K)
    ratio = walther_viscosity_m2_s(oil_temp_C, lubricant) / walther_viscosity_m2_s(t_op, lubricant)
    return np.maximum(ratio - 1.0, 0.0)


def _basis_oil_warmup(ch, tau_s):
    if "oil_temp_C" in ch and ch["oil_temp_C"] is not None:
        t_oil = ch["oil_temp_C"]  # measured sump temperature beats the first-order model
    else:
        t_oil = oil_temperature_C(ch["time_s"], ch["ambient_temp_C"], tau_s)
    excess = warmup_viscosity_excess(t_oil, ch["ambient_temp_C"], ch["lubricant"])
    return excess * _rotating(ch["input_speed_rad_s"])


# --------------------------------------------------------------------------- bearing_drag
def bearing_viscous_drag_Nm(input_speed_rad_s, reference_speed_rpm=1000.0):
    """Viscous (speed-dependent) bearing drag per N m at the reference speed.

    SKF form used by the thesis code (B.2, Khonsari & Booser Eq. 15.3):
    ``M_L = 1e-10 f_L (n nu)^(2/3) d_m^3`` for ``n nu > 2000``; the printed code compares
    ``n nu`` with nu in m^2/s, so it always takes the constant branch (Eq. 15.4) and the
    speed dependence never activates (thesis Sec. 9.1 asks for the bearing model update).
    Here ``dT = c_b (n / 1000 rpm)^(2/3)``.

    Parameters
    ----------
    input_speed_rad_s : float or array, pinion speed w_in [rad/s]
    reference_speed_rpm : float, pinion speed at which the drag equals c_b [rpm]

    Returns
    -------
    drag per N m of drag at the reference speed [N m / N m], signed with the direction of turning.
    """
    w = np.asarray(input_speed_rad_s, dtype=float)
    n_rpm = np.abs(w) * RPM_PER_RAD_S
    return (n_rpm / reference_speed_rpm) ** (2.0 / 3.0) * _rotating(w)


def _basis_bearing_drag(ch):
    return bearing_viscous_drag_Nm(ch["input_speed_rad_s"])


# --------------------------------------------------------------------------- mixed_lubrication
def greenwood_tripp_F2(film_parameter):
    """Greenwood-Tripp asperity-area function F_2(lambda), seed 004 Eq. 17.

    The quintic fit crosses zero near lambda = 1.95 (and is negative to lambda = 3); the
    asperity contact area cannot be negative, so it is clipped at 0.

    Parameters
    ----------
    film_parameter : float or array, film parameter lambda = h_c0 / sigma [-]

    Returns
    -------
    F_2(lambda) [-], clipped at 0 and 0 for lambda > 3.
    """
    lam = np.asarray(film_parameter, dtype=float)
    f2 = (-0.002 * lam ** 5 + 0.028 * lam ** 4 - 0.173 * lam ** 3 + 0.526 * lam ** 2
          - 0.804 * lam + 0.500)
    return np.where(lam <= 3.0, np.maximum(f2, 0.0), 0.0)


def boundary_share(input_speed_rad_s, speed_ref_rpm):
    """Share of the gear load carried by asperities, 1 at rest and 0 in full film.

    Seed 004: film thickness h_c0 ~ U^0.68 (Eq. 9), film parameter lambda = h_c0 / sigma,
    asperity contact area ~ F_2(lambda) (Eqs 16-17), boundary friction f_b = tau_L A_a
    (Eq. 14). With lambda = (n / n_ref)^0.68 the share is ``F_2(lambda) / F_2(0)``.

    Parameters
    ----------
    input_speed_rad_s : float or array, pinion speed [rad/s]
    speed_ref_rpm : float, pinion speed at which lambda = 1 [rpm]

    Returns
    -------
    share of the load carried by asperities, F_2(lambda) / F_2(0) [-].
    """
    n_rpm = np.abs(np.asarray(input_speed_rad_s, dtype=float)) * RPM_PER_RAD_S
    lam = (n_rpm / speed_ref_rpm) ** FILM_SPEED_EXPONENT
    return greenwood_tripp_F2(lam) / 0.5


def mixed_lubrication_torque_Nm(input_torque_Nm, input_speed_rad_s, speed_ref_rpm):
    """Extra pinion torque per unit mu_b: ``|T_in| * boundary share`` (Stribeck, seed 004).

    Parameters
    ----------
    input_torque_Nm : float or array, pinion torque T_in [N m]
    input_speed_rad_s : float or array, pinion speed [rad/s]
    speed_ref_rpm : float, pinion speed at which lambda = 1 [rpm]

    Returns
    -------
    extra pinion torque per unit mu_b [N m], 0 where the pinion is stopped.
    """
    return (np.abs(np.asarray(input_torque_Nm, dtype=float))
            * boundary_share(input_speed_rad_s, speed_ref_rpm)
            * (np.abs(np.asarray(input_speed_rad_s, dtype=float)) > W_STOP_RAD_S))


def _basis_mixed(ch, speed_ref_rpm):
    return mixed_lubrication_torque_Nm(ch["input_torque_Nm"], ch["input_speed_rad_s"], speed_ref_rpm)


# --------------------------------------------------------------------------- mesh_friction
#: The thesis's reference hypoid (LD RWD rear axle, thesis Sec. 5.4, code B.2) at its own
#: ratio: the geometry whose Dudley friction the mesh-friction and churning effects scale.
REFERENCE_AXLE_MODEL = "gm_1500_rear_axle"


def _reference_stage(component: str, label_has: str = ""):
    """Parameters of a stage of the reference axle at its ratio and the thesis oil temperature."""

    model = reference_model(REFERENCE_AXLE_MODEL)
    ratio = float(model.resolve(1.0, THESIS_OPERATING_TEMP_C)["G"])
    for (comp, params, _), stage in zip(resolved_stages(model.id, ratio, THESIS_OPERATING_TEMP_C),
                                        model.stages):
        if comp == component and label_has in stage.get("label", ""):
            return params
    raise KeyError(f"{REFERENCE_AXLE_MODEL} has no {component} stage '{label_has}'")


def hypoid_mesh_loss_share(input_speed_rad_s):
    """Share of the pinion torque the reference hypoid mesh loses, ``1 - eta``.

    Thesis Eq. 5.9 (code B.2/B.4): sliding speed from the pinion speed and geometry, Dudley's
    friction coefficient ``f = 0.8 / (v + 100)^0.5`` (Fig. 12.8 fit), efficiency after
    Dudley Eq. 12.36; geometry of the thesis's reference hypoid (GM 1500 rear axle).

    Parameters
    ----------
    input_speed_rad_s : float or array, pinion speed [rad/s]

    Returns
    -------
    mesh loss share ``1 - eta`` of the reference hypoid [-], the shape of ``input_speed_rad_s``.
    """
    p = _reference_stage("hypoid_mesh")
    n_rpm = np.abs(np.asarray(input_speed_rad_s, dtype=float)) * RPM_PER_RAD_S
    v = gear_mesh.hypoid_sliding_speed_fpm(n_rpm, p["outer_pitch_radius_gap_in"],
                                           p["face_width_gap_in"], p["pinion_teeth"])
    eta = gear_mesh.hypoid_mesh_efficiency(gear_mesh.dudley_friction_coefficient(v),
                                           p["normal_pressure_angle_rad"], p["pinion_spiral_rad"],
                                           p["gear_spiral_rad"])
    return 1.0 - eta


def mesh_friction_torque_Nm(input_torque_Nm, input_speed_rad_s):
    """Extra pinion torque per unit ``friction_excess``: ``|T_in| (1 - eta_mesh(n))``.

    A mesh friction coefficient ``(1 + friction_excess)`` times Dudley's loses, to first order
    in the coefficient (``f tan psi_p << cos phi_n``), that much more of the torque. Thesis
    Sec. 7.2: "published friction coefficient data for hypoid gears are not sufficiently high
    at low speed" to match measured LD RWD losses; Dudley's curve is one fit (Fig. 12.8).

    Parameters
    ----------
    input_torque_Nm : float or array, pinion torque T_in [N m]
    input_speed_rad_s : float or array, pinion speed [rad/s]

    Returns
    -------
    extra pinion torque per unit friction_excess [N m], 0 where the pinion is stopped.
    """
    w = np.asarray(input_speed_rad_s, dtype=float)
    return (np.abs(np.asarray(input_torque_Nm, dtype=float)) * hypoid_mesh_loss_share(w)
            * (np.abs(w) > W_STOP_RAD_S))


def _basis_mesh_friction(ch):
    return mesh_friction_torque_Nm(ch["input_torque_Nm"], ch["input_speed_rad_s"])


# --------------------------------------------------------------------------- oil_churning
def ring_gear_churning_torque_Nm(input_speed_rad_s, gear_ratio):
    """Extra pinion torque per unit of extra immersion of the ring gear in oil.

    Dudley's bevel-gear windage (thesis Eqs 5.3, 5.10; code B.2) mixes oil and air viscosity
    by the immersed fraction X; ``dT/dX`` is the windage fully immersed minus dry, at the
    ring-gear speed ``n_in / G``, referred to the pinion (``/ G``). Thesis Sec. 5.2.3: a
    "dipped" axle runs at X ~ 0.2 (the fill plug's height); "halfway" is 0.5 and "totally"
    1.0. Grows as the square of the speed. Reference ring gear: the GM 1500 rear axle's.

    Parameters
    ----------
    input_speed_rad_s : float or array, pinion speed [rad/s]
    gear_ratio : float or array, overall pinion-to-carrier ratio G [-]

    Returns
    -------
    extra pinion torque per unit of extra immersed fraction X [N m], signed with the pinion speed.
    """
    p = _reference_stage("bevel_gear_windage", "ring")
    g = np.asarray(gear_ratio, dtype=float)
    n_ring = np.abs(np.asarray(input_speed_rad_s, dtype=float)) * RPM_PER_RAD_S / g

    def windage(x):
        return bevel_gear_windage_torque_Nm(n_ring, p["pitch_radius_in"], p["face_width_in"],
                                            p["face_factor"], p["helix_angle_rad"], x,
                                            p["mu_oil"], p["mu_air"], p["inner_radius_in"])

    return (windage(1.0) - windage(0.0)) / g * np.sign(np.asarray(input_speed_rad_s, dtype=float))


def _basis_churning(ch):
    return ring_gear_churning_torque_Nm(ch["input_speed_rad_s"], ch["gear_ratio"])


def _log_grid(lo, hi, n):
    return tuple(float(v) for v in np.geomspace(lo, hi, n))


DIFFERENTIAL_EFFECTS = (
    Effect(
        id="bearing_preload", level="differential",
        title="bearing and seal preload drag",
        parameters=(Parameter("drag_torque_Nm", 2.0, 0.0, 100.0, "N m",
                              "constant extra input torque loss while the pinion turns"),),
        linear="drag_torque_Nm", channels=(),
        signature="a constant shortfall of output torque whenever the pinion turns, "
                  "independent of torque, speed and time; none at standstill",
        seed="thesis Sec. 3.1.1.B and 9.2.2 (seal pre-load); B.2-B.5 bearing code has only the "
             "torque-proportional Khonsari & Booser Eq. 15.1 term",
        steady_state="subtracts drag_torque_Nm from the input torque at every speed > 0; "
                     "the efficiency drop is largest at low torque",
        basis=_basis_preload,
        separating_test="zero the torque sensors at standstill: a sensor offset persists at rest, "
                        "a preload drag does not"),
    Effect(
        id="cornering", level="differential",
        title="spider and side-gear friction in turns",
        parameters=(Parameter("k_c", 0.05, 0.0, 2.0, "-",
                              "P_loss = k_c * T_c * |w_L - w_R|, T_c = G * input torque"),),
        linear="k_c", channels=("wheel_speed_difference_rad_s",),
        signature="output torque shortfall proportional to torque times the wheel-speed "
                  "difference: only in turns",
        seed="seed 003 (Antoni 2014) Eqs 9-17; thesis Sec. 3.1.6 and 9.7",
        steady_state="zero in a map (straight driving, w_L = w_R) unless channels give "
                     "wheel_speed_difference_rad_s",
        basis=_basis_cornering,
        confounded_with=("mixed_lubrication",),
        separating_test="record both wheel speeds (wheel_speed_left_rpm, wheel_speed_right_rpm), "
                        "or drive straight at low speed and turn at high speed"),
    Effect(
        id="inertia", level="differential",
        title="rotating inertia",
        parameters=(Parameter("J_kg_m2", 0.05, 0.0, 5.0, "kg m^2",
                              "inertia referred to the pinion; extra input torque J dw_in/dt"),),
        linear="J_kg_m2", channels=(),
        signature="output torque below the model while the pinion accelerates and above it "
                  "while it decelerates, following dw/dt",
        seed="thesis Sec. 3.1.4 (Eqs 3.2-3.4, steady-speed assumption); seed 001 "
             "(Brumercik et al.) Eqs 9-11",
        steady_state="zero at constant speed: a map has no acceleration",
        basis=_basis_inertia),
    Effect(
        id="oil_warmup", level="differential",
        title="cold lubricant after a start",
        parameters=(Parameter("c_w_Nm", 0.5, 0.0, 50.0, "N m",
                              "extra input torque c_w * (nu(T_oil)/nu(T_op) - 1)"),
                    Parameter("tau_s", 600.0, 30.0, 7200.0, "s",
                              "time constant of T_oil = T_op - (T_op - T_amb) exp(-t/tau)",
                              grid=_log_grid(60.0, 3600.0, 16))),
        linear="c_w_Nm", channels=("ambient_temp_C",),
        signature="a torque shortfall that is largest right after the start and decays as the "
                  "oil warms up; follows time since start and oil temperature",
        seed="thesis Sec. 3.1.2 and 9.8 (operating temperature fixed at ambient + 50 K), "
             "Walther's equation thesis Eqs 5.13-5.14 / B.7",
        steady_state="zero in a map (the oil is at T_op) unless channels give oil_temp_C or "
                     "time_s and ambient_temp_C",
        basis=_basis_oil_warmup,
        separating_test="record ambient_temp_C (or oil_temp_C) and start the recording cold"),
    Effect(
        id="bearing_drag", level="differential",
        title="speed-dependent viscous bearing drag",
        parameters=(Parameter("drag_1000rpm_Nm", 0.5, 0.0, 50.0, "N m",
                              "extra input torque at 1000 rpm pinion speed; dT ~ n^(2/3)"),),
        linear="drag_1000rpm_Nm", channels=(),
        signature="a torque shortfall growing with pinion speed as n^(2/3), independent of torque",
        seed="thesis B.2 bearing code (Khonsari & Booser Eq. 15.3, SKF), whose n*nu > 2000 test "
             "never passes; thesis Sec. 9.1",
        steady_state="subtracts drag_1000rpm_Nm * (n/1000)^(2/3) from the input torque",
        basis=_basis_bearing_drag),
    Effect(
        id="mixed_lubrication", level="differential",
        title="mixed/boundary lubrication of the gear mesh at low speed",
        parameters=(Parameter("mu_b", 0.02, 0.0, 0.5, "-",
                              "extra share of input torque lost in full boundary contact"),
                    Parameter("speed_ref_rpm", 300.0, 20.0, 3000.0, "rpm",
                              "pinion speed where the film parameter lambda = 1",
                              grid=_log_grid(40.0, 2000.0, 18))),
        linear="mu_b", channels=(),
        signature="a torque-proportional shortfall at low pinion speed that vanishes once the "
                  "oil film separates the teeth (about 2.7 x speed_ref_rpm)",
        seed="seed 004 (Stribeck film parameter, Eqs 9, 14-17, Greenwood-Tripp); thesis Sec. "
             "9.3.2 and Sec. 7.2 (losses at low speed the model cannot explain)",
        steady_state="subtracts mu_b * T_in * F2(lambda)/F2(0) from the input torque; only at "
                     "low speed",
        basis=_basis_mixed,
        confounded_with=("cornering",),
        separating_test="record both wheel speeds, or drive straight at low speed"),
    Effect(
        id="mesh_friction", level="differential",
        title="gear-mesh friction above Dudley's coefficient",
        parameters=(Parameter("friction_excess", 0.3, 0.0, 3.0, "-",
                              "mesh friction coefficient = (1 + friction_excess) x Dudley's "
                              "f = 0.8/(v+100)^0.5; dT = friction_excess |T_in| (1 - eta_mesh)"),),
        linear="friction_excess", channels=(),
        signature="a torque-proportional shortfall at every speed, largest at low speed where "
                  "Dudley's coefficient is high (f ~ 1/sqrt(sliding speed))",
        seed="thesis Eq. 5.9 and code B.2/B.4 (Dudley Fig. 12.8 fit, Eq. 12.36); thesis Sec. 7.2 "
             "(published hypoid friction too low at low speed)",
        steady_state="subtracts friction_excess x |T_in| x (1 - eta_mesh(n)) from the input torque",
        basis=_basis_mesh_friction),
    Effect(
        id="oil_churning", level="differential",
        title="oil churning at a higher oil level",
        parameters=(Parameter("immersion_excess", 0.3, 0.0, 0.8, "-",
                              "ring-gear immersed fraction above the model's (0.2 dipped; 0.5 "
                              "halfway, 1.0 totally immersed)"),),
        linear="immersion_excess", channels=(),
        signature="a torque shortfall growing as the square of the speed, independent of torque",
        seed="thesis Sec. 5.2.3 (immersion fractions: dipped ~0.2, halfway, totally) and Eqs "
             "5.3, 5.10 (Dudley bevel-gear windage, code B.2)",
        steady_state="subtracts immersion_excess x dT/dX of the ring gear's windage",
        basis=_basis_churning,
        separating_test="measure the oil level (fill-plug height) or drain to the nominal level"),
)
