"""The two-speed gearbox of the dual differential (thesis Appendix B.5, ``Auxiliary_modified``).

Thesis B.5 is Kyung Jin Kim's model of the auxiliary (two-speed) section of the Eaton Fuller
FRO16210C transmission, written for the TxDOT VCost model and adapted by James Vaughn to serve
as the two-speed box of a heavy-duty dual differential. This module ports it exactly, as
printed, with MATLAB semantics (element-wise operations, degrees in ``sind``/``cosd``/``tand``/
``atand``, IEEE division by zero, chained comparisons evaluated left to right), vectorised over
the inputs.

:func:`auxiliary_box` returns what B.5 holds just before its last statement
``[diffEff,...]=EffDiffRearHD(torque_d_OS_aux,RPM_O_aux,diffG)``: the box efficiency, the
output torque fraction and the output speed. The heavy-duty differential (thesis B.4) is
evaluated by the caller at that torque fraction and speed; B.5's efficiency is the product.

The measured geometry of the box is data: ``models/eaton_fro16210c_two_speed.toml`` (see
:func:`load_geometry`). Formula coefficients and unit conversions stay in the code.

Printed-code quirks are kept and marked ``QUIRK`` below (collected in docs/thesis-quirks.md).
Outside the thesis domain: a negative speed gives NaN here where MATLAB gives complex numbers
(a negative number to a fractional power, ``RPM.^1.85``), and the efficiency floor turns the
NaN into 0; a negative torque fraction is evaluated as printed (real in MATLAB too; e.g. high
gear then returns an efficiency above 1).
"""
from __future__ import annotations

import tomllib
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from fleetrun.errors import InputError
from fleetrun.physics.floor import mark_negative, zero_nan
from fleetrun.resources import models_dir

GEOMETRY_FILE = "eaton_fro16210c_two_speed.toml"

#: Quantities the geometry file must define (descriptive name -> B.5 variable).
GEOMETRY_KEYS = {
    "peak_torque": "peak_torque",
    "normal_pressure_angle": "alpha_n",
    "centre_distance": "C",
    "mesh_friction_coefficient": "mu_fGP",
    "upper_countershaft_immersion": "X",
    "windage_loose_constant": "C_E",
    "seal_tangential_friction": "F_tan",
    "output_seal_diameter": "D_sh_output",
    "initial_drive_teeth": "t_D_i_aux",
    "initial_driven_teeth": "t_d_i_aux",
    "initial_helix_angle": "gamma_i_aux",
    "initial_drive_outer_diameter": "OD_D_i_aux",
    "initial_driven_outer_diameter": "OD_d_i_aux",
    "initial_drive_immersion": "X_D_i_aux",
    "initial_driven_immersion_lower": "X_d_i_aux_lower",
    "initial_face_width": "L_FW_i_aux",
    "low_drive_teeth": "t_D_L_aux",
    "low_driven_teeth": "t_d_L_aux",
    "low_helix_angle": "gamma_L_aux",
    "low_drive_outer_diameter": "OD_D_L_aux",
    "low_driven_outer_diameter": "OD_d_L_aux",
    "low_drive_immersion_lower": "X_D_L_aux_lower",
    "low_driven_immersion": "X_d_L_aux",
    "low_face_width": "L_FW_L_aux",
    "ambient_temperature": "T_ambient",
    "oil_temperature_rise": "T_oil",
    "countershaft_rotation": "R_C_aux",
    "countershaft_hand": "H_C_aux",
    "output_rotation": "R_IO_aux",
    "output_hand": "H_IO_aux",
    "countershaft_bearing_k": "K78910",
    "countershaft_bearing_g": "G78910",
    "output_bearing_k": "K11",
    "output_bearing_g": "G11",
    "bearing7_to_initial_driven_gear": "L_B7_d",
    "bearing7_to_low_drive_gear": "L_B7_LD",
    "bearing7_to_bearing8": "L_B7_B8",
    "shaft_end_to_bearing11": "L_B11_aux",
    "shaft_end_to_low_driven_gear": "L_d_aux",
}

_GEARS = {"low": 1, "high": 2, 1: 1, 2: 2}


# --------------------------------------------------------------------------------------------
# geometry data
# --------------------------------------------------------------------------------------------

def _parse_geometry(data: Mapping, origin: str) -> dict[str, float]:
    values: dict[str, float] = {}
    for name, entry in data.items():
        if name not in GEOMETRY_KEYS:
            raise InputError(f"{origin}: unknown two-speed box quantity '{name}'",
                             hint=f"valid: {', '.join(sorted(GEOMETRY_KEYS))}")
        value = entry.get("value") if isinstance(entry, Mapping) else entry
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InputError(f"{origin}: '{name}' needs a numeric value, got {value!r}")
        values[name] = float(value)
    return values


def _read_toml(path: Path) -> dict[str, float]:
    try:
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
    except FileNotFoundError as exc:
        raise InputError(f"two-speed box geometry file not found: {path}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML ({exc})") from exc
    values = _parse_geometry(data, str(path))
    missing = sorted(set(GEOMETRY_KEYS) - set(values))
    if missing:
        raise InputError(f"{path}: two-speed box quantities missing: {', '.join(missing)}")
    return values


@lru_cache(maxsize=8)
def _read_toml_cached(path: str) -> tuple[tuple[str, float], ...]:
    return tuple(_read_toml(Path(path)).items())


def load_geometry(path=None) -> dict[str, float]:
    """The measured Eaton FRO16210C auxiliary-section constants of thesis B.5, by name.

    ``path`` is a TOML file with one table per quantity (``value``, ``unit``, ``matlab``,
    ``source``); ``None`` loads the shipped ``models/eaton_fro16210c_two_speed.toml``.

    Parameters
    ----------
    path : str, Path or None, the geometry TOML (None: the shipped file)

    Returns
    -------
    dict, quantity name (:data:`GEOMETRY_KEYS`) -> value in the unit its table states (mm,
    degrees, degF, N/m, ...: the units B.5 prints).

    >>> load_geometry()["centre_distance"]   # mm
    149.5044
    """
    if path is None:
        path = models_dir() / GEOMETRY_FILE
    return dict(_read_toml_cached(str(Path(path).resolve())))


def _resolve_geometry(geometry) -> dict[str, float]:
    """``None`` -> shipped file; a path -> that file; a mapping -> overrides of the shipped file."""
    if geometry is None or isinstance(geometry, (str, Path)):
        return load_geometry(geometry)
    if isinstance(geometry, Mapping):
        values = load_geometry()
        values.update(_parse_geometry(geometry, "geometry"))
        return values
    raise InputError(f"geometry must be None, a TOML path or a mapping, not {type(geometry).__name__}")


# --------------------------------------------------------------------------------------------
# MATLAB helpers
# --------------------------------------------------------------------------------------------

def _sind(x):
    return np.sin(np.deg2rad(x))


def _cosd(x):
    return np.cos(np.deg2rad(x))


def _tand(x):
    return np.tan(np.deg2rad(x))


def _atand(x):
    return np.rad2deg(np.arctan(x))


def _bearing_f1(lf, whole_array_third_test: bool = False):
    """The load-factor branch of B.5 for one tapered roller bearing, exactly as printed::

        if LF < 0.47                      f1 = 0.06
        elseif 0.47 <= LF < 0.94          f1 = -0.13443 - 0.15316*LF + 1.238*LF^2
        elseif 0.94 <= LF < 2.0           f1 = -0.13538 + 0.96978*LF + 0.028991*LF^2
        else                              f1 = LF

    QUIRK: MATLAB evaluates ``a <= LF < b`` as ``(a <= LF) < b``: a logical (0 or 1) compared
    with b. ``(0.47 <= LF) < 0.94`` is true only where ``0.47 <= LF`` is false, i.e. never
    after the first test fails, except for NaN (``NaN < 0.47`` false, ``(0.47 <= NaN) = 0 <
    0.94`` true -> the second polynomial). ``(0.94 <= LF) < 2.0`` is always true (0 or 1 < 2),
    so the third polynomial serves every LF >= 0.47 and the ``else`` is unreachable. A corrected
    model would use the second polynomial for 0.47 <= LF < 0.94, the third for
    0.94 <= LF < 2.0, and ``LF`` above.

    ``whole_array_third_test``: B.5's low-gear blocks for bearings #8 and #10 print
    ``elseif 0.94 <= LF8 < 2.0`` with the whole array instead of the element. ``if`` on an
    array is true when every element is non-zero; ``(0.94 <= LF8) < 2.0`` is all true, so the
    outcome is the same as the element-wise test. Kept for fidelity.
    """
    lf = np.asarray(lf, dtype=float)
    branch = bearing_f1_branch(lf, whole_array_third_test)
    return np.select(
        [branch == 1, branch == 2, branch == 3],
        [np.full(lf.shape, 0.06),
         -0.13443 - (0.15316 * lf) + (1.238 * (lf ** 2)),
         -0.13538 + (0.96978 * lf) + (0.028991 * (lf ** 2))],
        default=lf,
    )


def bearing_f1_branch(lf, whole_array_third_test: bool = False):
    """Which branch (1 ``if``, 2 and 3 the ``elseif``s, 4 ``else``) B.5's load-factor
    ``if`` takes for each element, with MATLAB's left-to-right chained comparisons (see
    :func:`_bearing_f1`). Where the printed test uses the whole array, ``if`` is true when
    every element is non-zero; on a block of a large input this is the block's elements,
    which gives the same answer because the test is true for every element.

    Parameters
    ----------
    lf : float or array, the bearing load factor F_a / F_r of B.5 [-]
    whole_array_third_test : bool, apply the third test to the whole array, as printed

    Returns
    -------
    int array of the branch taken (1-4), the shape of ``lf``.

    >>> bearing_f1_branch([0.2, 0.5, 1.0, 3.0])   # MATLAB's (0.47 <= lf) < 0.94: 3, not 2
    array([1, 3, 3, 3])
    """
    lf = np.asarray(lf, dtype=float)
    first = lf < 0.47
    second = (0.47 <= lf).astype(float) < 0.94
    third = (0.94 <= lf).astype(float) < 2.0
    if whole_array_third_test:
        third = np.full(lf.shape, bool(np.all(third)))
    return np.select([first, second, third], [1, 2, 3], default=4)


# --------------------------------------------------------------------------------------------
# sub-results (each a printed B.5 equation; used by the box and by the tests)
# --------------------------------------------------------------------------------------------

def gear_pair_efficiency(drive_teeth, driven_teeth, helix_angle_deg, drive_outer_diameter_mm,
                         driven_outer_diameter_mm, centre_distance_mm, normal_pressure_angle_deg,
                         friction_coefficient, gear_ratio=None, drive_scale=1.0):
    """Helical gear-pair (sliding friction) efficiency of B.5, ``GPEff_i_aux``/``GPEff_L_aux``.

    Pitch radii from the centre distance and tooth counts; ``drive_scale`` multiplies the drive
    gear's pitch radius, base radius and outer diameter (B.5's low-gear-ratio adaptation);
    ``gear_ratio`` defaults to ``driven_teeth/drive_teeth``.

    QUIRK: the base radii are ``R_p * cosd(alpha_n)`` with the NORMAL pressure angle while the
    roll angles use the transverse angle ``alpha_t``; a helical gear's base radius is
    ``R_p * cosd(alpha_t)``. Both roll angles divide by the DRIVE gear's base radius; that is
    consistent (both are drive-gear roll angles in ``(1+1/G)*(mu/2)*(b1^2+b2^2)/(b1+b2)``).

    Parameters
    ----------
    drive_teeth, driven_teeth : int, tooth counts [-]
    helix_angle_deg : float, helix angle [deg]
    drive_outer_diameter_mm, driven_outer_diameter_mm : float, outside diameters [mm]
    centre_distance_mm : float, C [mm]
    normal_pressure_angle_deg : float, alpha_n [deg]
    friction_coefficient : float, mu [-]
    gear_ratio : float or None, G [-] (None: driven_teeth / drive_teeth)
    drive_scale : float, the drive gear's size factor [-]

    Returns
    -------
    mesh efficiency [-].
    """
    alpha_n = normal_pressure_angle_deg
    C = centre_distance_mm
    G = driven_teeth / drive_teeth if gear_ratio is None else gear_ratio
    alpha_t = _atand((_tand(alpha_n) / _cosd(helix_angle_deg)))
    R_p_D = C / (1 + (driven_teeth / drive_teeth))
    R_b_D = R_p_D * _cosd(alpha_n)
    R_p_d = C - R_p_D
    R_b_d = R_p_d * _cosd(alpha_n)
    OD_D = drive_outer_diameter_mm
    OD_d = driven_outer_diameter_mm
    R_p_D = R_p_D * drive_scale
    R_b_D = R_b_D * drive_scale
    OD_D = OD_D * drive_scale
    beta_D = (np.sqrt(((OD_D) ** 2) - ((2 * R_b_D) ** 2)) - (2 * R_p_D * _sind(alpha_t))) / (2 * R_b_D)
    beta_d = (np.sqrt(((OD_d) ** 2) - ((2 * R_b_d) ** 2)) - (2 * R_p_d * _sind(alpha_t))) / (2 * R_b_D)
    return 1 - ((_cosd(alpha_t) / (_cosd(alpha_n) * _cosd(helix_angle_deg))) * (1 + (1 / G))
                * (friction_coefficient / 2) * (((beta_D ** 2) + (beta_d ** 2)) / (beta_D + beta_d)))


def output_seal_loss(seal_diameter_mm, tangential_friction_n_per_m):
    """B.5 ``torqueloss_seal_output = 2*pi*(r_sh_output*(10^-3))^2*F_tan`` in N m.

    Parameters
    ----------
    seal_diameter_mm : float, output shaft diameter at the seal [mm]
    tangential_friction_n_per_m : float, F_tan, seal friction per unit circumference [N/m]

    Returns
    -------
    seal torque loss [N m].

    >>> round(output_seal_loss(100.0, 100.0), 4)
    1.5708
    """
    r_sh_output = seal_diameter_mm / 2
    return 2 * np.pi * (r_sh_output * (10.0 ** -3)) ** 2 * tangential_friction_n_per_m


def oil_and_air_properties(ambient_temperature_degF, oil_temperature_rise):
    """B.5's operating fluid properties (Castrol Syngear CD-50 fit, ideal-gas dry air).

    Returns ``rho_air`` (kg/m3), ``mu_air`` (printed "kinematic viscosity", m2/s), ``rho_oil``
    (kg/m3), ``mu_oil`` (kinematic viscosity, m2/s) and ``mu_oil_dynamic`` (cP).

    QUIRK: ``T_oil = (T_ambient-32)*5/9+273.1+50`` adds 50 K; the commented-out line above it,
    ``T_oil = (((T_ambient+50)-32)*(5/9)) + 273.1``, added 50 degF (27.8 K). With 72 degF the
    oil is at 345.32 K (72.2 degC), where B.4/B.7 use 70 degC and 80W90 oil. 273.1 (not
    273.15) is printed.

    Parameters
    ----------
    ambient_temperature_degF : float, T_ambient [degF] (B.5 prints 72)
    oil_temperature_rise : float, the printed rise of the oil over ambient [K] (50)

    Returns
    -------
    (rho_air [kg/m^3], mu_air [m^2/s], rho_oil [kg/m^3], mu_oil [m^2/s], mu_oil_dynamic [cP])

    >>> [round(float(x), 6) for x in oil_and_air_properties(72.0, 50.0)]
    [1.022168, 2e-05, 808.635, 3.8e-05, 30.748136]
    """
    T_oil = (ambient_temperature_degF - 32) * 5 / 9 + 273.1 + oil_temperature_rise
    T_air = T_oil
    rho_air = 101325 / (287.058 * T_air)
    mu_air = ((-1.1555 * (10.0 ** -14) * T_air ** 3) + (9.5728 * (10.0 ** -11) * T_air ** 2)
              + (3.7604 * (10.0 ** -8) * T_air) - (3.4484 * (10.0 ** -6)))
    rho_oil = ((-0.0007 * (T_oil - 273.1)) + 0.860) * 999
    A_cons = (T_oil / 373.1) ** (-2.965198089)
    mu_oil = ((18.3 ** A_cons) - 0.7) * (10.0 ** -6)
    mu_oil_dynamic = (mu_oil * rho_oil) * (1000)
    return rho_air, mu_air, rho_oil, mu_oil, mu_oil_dynamic


def _windage(rho, C_E, face_width_mm, pitch_radius_mm, rpm, outer_diameter_mm, viscosity):
    # B.5: 1.06948 .* 10.^-4 .* rho .* C_E .* (1+ (2.3 .* (L_FW./R_p))) .* (RPM.^1.85)
    #      .* (OD .* 10.^-3).^4.7 .* (mu).^0.15
    return (1.06948 * 10.0 ** -4 * rho * C_E * (1 + (2.3 * (face_width_mm / pitch_radius_mm)))
            * (rpm ** 1.85) * (outer_diameter_mm * 10.0 ** -3) ** 4.7 * (viscosity) ** 0.15)


def _bearing_loss(G_factor, K_factor, rpm, mu_oil_dynamic, f1, F_r):
    # QUIRK: an unloaded bearing has F_apc = F_r = 0, LF = 0/0 = NaN, f1 = NaN, and the loss
    # 0^0.62 * NaN^0.3 = NaN even at 0 rpm. In high gear at 0 rpm every counter-shaft gear
    # force is a (zero) windage torque, so the box efficiency is NaN -> 0 (low gear at 0 rpm
    # gives ~0.98). Corrected: zero loss for a zero load (and zero speed).
    # B.5: (2.56 .* 10.^-6 .* G) .* ((RPM .* mu_oil_dynamic).^0.62) .* ((f1.*F_r./K).^0.3)
    return (2.56 * 10.0 ** -6 * G_factor) * ((rpm * mu_oil_dynamic) ** 0.62) * ((f1 * F_r / K_factor) ** 0.3)


def _gear_forces(torque, rotation, hand, pitch_radius_mm, alpha_n, helix_deg):
    # B.5: F_t = (1000 .* torque .* R)./(R_p); F_s = (abs(F_t).* tand(alpha_n)./cosd(gamma));
    #      F_a = H .* R .* abs(F_t) .* tand(gamma)
    F_t = (1000 * torque * rotation) / (pitch_radius_mm)
    F_s = (np.abs(F_t) * _tand(alpha_n) / _cosd(helix_deg))
    F_a = hand * rotation * np.abs(F_t) * _tand(helix_deg)
    return F_t, F_s, F_a


# --------------------------------------------------------------------------------------------
# the box
# --------------------------------------------------------------------------------------------

def auxiliary_box(torque_fraction, speed_rpm, low_gear_ratio, axle_gear, geometry=None):
    """Thesis Appendix B.5 (Kim's Eaton Fuller FRO16210C auxiliary section adapted by Vaughn):
    efficiency of the two-speed box of a heavy-duty dual differential.

    Parameters
    ----------
    torque_fraction : array_like
        B.5 ``input_torque_aux``: box input torque / B.5 ``peak_torque`` (5794.088 N m).
    speed_rpm : array_like
        B.5 ``input_RPM_aux``: box input (transmission output) speed in rpm.
    low_gear_ratio : float or array_like [-]
        B.5 ``toospd_lo_gear``: total low ratio (measured box 43/34 * 62/16 = 4.900735...).
        It shapes the low drive gear and so matters in high gear too.
    axle_gear : {"low", "high"} (or B.5's ``gear`` 1 / 2)
    geometry : None, path or mapping
        ``None`` loads ``models/eaton_fro16210c_two_speed.toml``; a path loads that file; a
        mapping of quantity -> value overrides single quantities of the shipped file.

    Returns
    -------
    (eta, torque_fraction_out, speed_rpm_out)
        B.5's ``trans_efficiency_aux``, ``torque_d_OS_aux`` and ``RPM_O_aux`` after the two
        ``EtaNTorqCorrect`` calls, just before ``EffDiffRearHD(torque_d_OS_aux, RPM_O_aux,
        diffG)``. ``torque_fraction_out`` is the output torque / (peak_torque * box ratio);
        B.5 passes it to B.4 as B.4's torque fraction although B.4 scales by its own peak
        torque (32000 N m) - QUIRK, see below. All three have the broadcast shape of the
        inputs; eta and torque are 0 where the losses exceed the input.
    """
    gear = None if isinstance(axle_gear, bool) else _GEARS.get(
        axle_gear.lower() if isinstance(axle_gear, str) else axle_gear)
    if gear is None:
        # B.5 `switch gear` has only `case 1` and `case 2`; anything else leaves the outputs
        # undefined (a MATLAB error).
        raise InputError(f"axle_gear must be 'low' or 'high', not {axle_gear!r}")
    g = _resolve_geometry(geometry)

    tq = np.asarray(torque_fraction, dtype=float)
    rpm_in = np.asarray(speed_rpm, dtype=float)
    lo = np.asarray(low_gear_ratio, dtype=float)
    try:
        shape = np.broadcast_shapes(tq.shape, rpm_in.shape, lo.shape)
    except ValueError as exc:
        raise InputError(f"torque_fraction, speed_rpm and low_gear_ratio do not broadcast: {exc}") from exc
    size = int(np.prod(shape, dtype=np.int64))
    if size <= _CHUNK:
        eta, torque_out, rpm_out = _box(np.broadcast_to(tq, shape), rpm_in, lo, gear, g)
        return (np.array(np.broadcast_to(eta, shape)), np.array(np.broadcast_to(torque_out, shape)),
                np.array(np.broadcast_to(rpm_out, shape)))
    # Large inputs are evaluated in blocks of _CHUNK elements (the model is element-wise):
    # the ~100 temporaries of a block stay in cache and are reused instead of page-faulting
    # fresh memory. The low ratio stays a scalar when it is one (scalar geometry).
    tq = np.broadcast_to(tq, shape).reshape(-1)
    rpm_in = np.broadcast_to(rpm_in, shape).reshape(-1)
    lo = lo if lo.ndim == 0 else np.broadcast_to(lo, shape).reshape(-1)
    outputs = [np.empty(size) for _ in range(3)]
    for start in range(0, size, _CHUNK):
        block = slice(start, start + _CHUNK)
        results = _box(tq[block], rpm_in[block], lo if lo.ndim == 0 else lo[block], gear, g)
        for out, result in zip(outputs, results):
            out[block] = result
    return tuple(out.reshape(shape) for out in outputs)


_CHUNK = 1 << 16


def _gear_pairs(g, lo) -> SimpleNamespace:
    """B.5's initial and low gear pairs: ratios, pitch radii (with the JRV low-gear scaling)
    and mesh efficiencies."""
    C = g["centre_distance"]
    t_D_i_aux = g["initial_drive_teeth"]
    t_d_i_aux = g["initial_driven_teeth"]
    G_i_aux = t_d_i_aux / t_D_i_aux
    R_p_D_i_aux = C / (1 + (t_d_i_aux / t_D_i_aux))
    t_D_L_aux = g["low_drive_teeth"]
    t_d_L_aux = g["low_driven_teeth"]
    G_L_aux = lo / G_i_aux
    R_p_D_L_aux = C / (1 + (t_d_L_aux / t_D_L_aux))
    R_p_d_L_aux = C - R_p_D_L_aux
    OD_D_L_aux = g["low_drive_outer_diameter"]
    # QUIRK (B.5 "JRV: Accounting for different low gear ratio by changing driven gear
    # size"): R_p_D_L_aux=R_p_D_L_aux*G_L_aux/(t_d_L_aux/t_D_L_aux) (and R_b_D_L_aux,
    # OD_D_L_aux). It scales the DRIVE gear, and UP with the ratio; the driven gear and the
    # centre distance stay. A corrected model keeps C and sets R_p_D = C/(1+G_L_aux) (or
    # scales the driven gear up). Identity for the measured box (G_L_aux = 62/16).
    drive_scale_L = G_L_aux / (t_d_L_aux / t_D_L_aux)
    alpha_n, mu_fGP = g["normal_pressure_angle"], g["mesh_friction_coefficient"]
    return SimpleNamespace(
        G_i=G_i_aux, R_p_D_i=R_p_D_i_aux, R_p_d_i=C - R_p_D_i_aux, G_L=G_L_aux,
        R_p_D_L=R_p_D_L_aux * drive_scale_L, R_p_d_L=R_p_d_L_aux, OD_D_L_scaled=OD_D_L_aux * drive_scale_L,
        GPEff_i=gear_pair_efficiency(t_D_i_aux, t_d_i_aux, g["initial_helix_angle"],
                                     g["initial_drive_outer_diameter"], g["initial_driven_outer_diameter"],
                                     C, alpha_n, mu_fGP),
        GPEff_L=gear_pair_efficiency(t_D_L_aux, t_d_L_aux, g["low_helix_angle"], OD_D_L_aux,
                                     g["low_driven_outer_diameter"], C, alpha_n, mu_fGP, gear_ratio=G_L_aux,
                                     drive_scale=drive_scale_L))


def _windage_torques(g, pairs, fluids, RPM_aux, RPM_C_aux) -> SimpleNamespace:
    """B.5's windage torques of the input-shaft and counter-shaft gears (oil share X, air
    share 1 - X), and the function for the low driven gear (its speed depends on the range)."""
    rho_air, mu_air, rho_oil, mu_oil, _ = fluids
    C_E = g["windage_loose_constant"]

    def wind(face, radius, rpm, od, share):
        oil = _windage(rho_oil, C_E, face, radius, rpm, od, mu_oil)
        air = _windage(rho_air, C_E, face, radius, rpm, od, mu_air)
        return (share * oil) + ((1 - share) * air)

    L_FW_i, L_FW_L, X = g["initial_face_width"], g["low_face_width"], g["upper_countershaft_immersion"]
    OD_d_i = g["initial_driven_outer_diameter"]
    return SimpleNamespace(
        i_D=wind(L_FW_i, pairs.R_p_D_i, RPM_aux, g["initial_drive_outer_diameter"], g["initial_drive_immersion"]),
        i_d_upper=wind(L_FW_i, pairs.R_p_d_i, RPM_C_aux, OD_d_i, X),
        i_d_lower=wind(L_FW_i, pairs.R_p_d_i, RPM_C_aux, OD_d_i, g["initial_driven_immersion_lower"]),
        L_D_upper=wind(L_FW_L, pairs.R_p_D_L, RPM_C_aux, pairs.OD_D_L_scaled, X),
        L_D_lower=wind(L_FW_L, pairs.R_p_D_L, RPM_C_aux, pairs.OD_D_L_scaled, g["low_drive_immersion_lower"]),
        low_driven=lambda rpm: wind(L_FW_L, pairs.R_p_d_L, rpm, g["low_driven_outer_diameter"],
                                    g["low_driven_immersion"]))


def _shaft_bearing_forces(g, pairs, torque_i, torque_L, L_d_B8, L_LD_B8, L_B7_d, L_B7_LD, L_B7_B8, shaft):
    """Radial loads of one counter shaft's two bearings (#7/#8 lower, #9/#10 upper) from the
    forces of its initial driven and low drive gears: (F_apc, F_r) of each bearing. ``shaft``
    ("lower" or "upper") as B.5 writes it: the lower shaft's first bearing prints
    ``(-1/L)*(a+b+c+d)``, the upper one's ``(1/L)*(-a-b-c-d)``."""
    alpha_n, R_C, H_C = g["normal_pressure_angle"], g["countershaft_rotation"], g["countershaft_hand"]
    F_t_i, F_s_i, F_a_i = _gear_forces(torque_i, R_C, H_C, pairs.R_p_d_i, alpha_n, g["initial_helix_angle"])
    F_t_L, F_s_L, F_a_L = _gear_forces(torque_L, R_C, H_C, pairs.R_p_D_L, alpha_n, g["low_helix_angle"])
    if shaft == "lower":
        F_apc_a = np.abs((-1 / L_B7_B8) * ((F_s_i * L_d_B8) + (F_s_L * L_LD_B8)
                                           + (F_a_i * pairs.R_p_d_i) + (F_a_L * pairs.R_p_D_L)))
    else:
        F_apc_a = np.abs((1 / L_B7_B8) * (-(F_s_i * L_d_B8) - (F_s_L * L_LD_B8)
                                          - (F_a_i * pairs.R_p_d_i) - (F_a_L * pairs.R_p_D_L)))
    F_apc_b = np.abs((1 / L_B7_B8) * ((F_a_i * pairs.R_p_d_i) + (F_a_L * pairs.R_p_D_L)
                                      - (F_s_i * L_B7_d) - (F_s_L * L_B7_LD)))
    F_ppc_a = np.abs((1 / L_B7_B8) * ((F_t_i * L_d_B8) + (F_t_L * L_LD_B8)))
    F_ppc_b = np.abs((1 / L_B7_B8) * ((F_t_i * L_B7_d) + (F_t_L * L_B7_LD)))
    return (F_apc_a, np.sqrt((F_apc_a) ** 2 + (F_ppc_a) ** 2)), (F_apc_b, np.sqrt((F_apc_b) ** 2 + (F_ppc_b) ** 2))


def _counter_shaft_bearing_losses(g, pairs, mu_oil_dynamic, RPM_C_aux, gear, cs_torques):
    """Torque losses of bearings #7-#10 (B.5), from the counter shafts' gear torques
    ``cs_torques`` = (initial lower, low lower, initial upper, low upper)."""
    L_B7_d, L_B7_LD, L_B7_B8 = (g["bearing7_to_initial_driven_gear"], g["bearing7_to_low_drive_gear"],
                                g["bearing7_to_bearing8"])
    L_d_B8 = L_B7_B8 - L_B7_d
    L_LD_B8 = L_B7_B8 - L_B7_LD
    i_lower, L_lower, i_upper, L_upper = cs_torques
    B7, B8 = _shaft_bearing_forces(g, pairs, i_lower, L_lower, L_d_B8, L_LD_B8, L_B7_d, L_B7_LD, L_B7_B8, "lower")
    # bearings #9 and #10 (upper counter shaft): B.5's L_B9_d = L_B7_d, L_B9_B10 = L_B7_B8, ...
    B9, B10 = _shaft_bearing_forces(g, pairs, i_upper, L_upper, L_d_B8, L_LD_B8, L_B7_d, L_B7_LD, L_B7_B8, "upper")
    K78910, G78910 = g["countershaft_bearing_k"], g["countershaft_bearing_g"]
    losses = []
    for (F_apc, F_r), third_test in ((B7, False), (B8, gear == 1), (B9, False), (B10, gear == 1)):
        # QUIRK: LF = abs(K.*F_apc./F_r) - the Timken load factor is K*Fa/Fr with Fa the
        # bearing's THRUST load; B.5 uses F_apc, a radial component (moment balance in the
        # plane of the separating forces) that is also inside F_r, so LF <= K < 2 always.
        # Corrected: Fa = the shaft's net gear thrust (sum of F_a) carried by that bearing.
        # Low gear prints `elseif 0.94 <= LF8 < 2.0` / `... LF10 < 2.0` (whole array).
        f1 = _bearing_f1(np.abs(K78910 * F_apc / F_r), whole_array_third_test=third_test)
        losses.append(_bearing_loss(G78910, K78910, RPM_C_aux, mu_oil_dynamic, f1, F_r))
    return losses


def _output_bearing_loss(g, pairs, mu_oil_dynamic, torque_d_L_aux, RPM_O_aux):
    """Torque loss of the output-shaft bearing #11 (B.5)."""
    # QUIRK (high gear): the force on the low driven gear is computed from the full
    # throughput torque `F_t_L_d_aux = (1000 .* torque_d_L_aux ...)` although in high gear
    # that gear freewheels and the torque passes the direct coupling; bearing #11 is loaded
    # by a gear force that does not exist. Corrected: no mesh force in direct drive.
    alpha_n, gamma_L_aux = g["normal_pressure_angle"], g["low_helix_angle"]
    R_IO_aux, H_IO_aux = g["output_rotation"], g["output_hand"]
    L_B11_aux, L_d_aux = g["shaft_end_to_bearing11"], g["shaft_end_to_low_driven_gear"]
    K11, G11 = g["output_bearing_k"], g["output_bearing_g"]
    F_t_L_d_aux = (1000 * torque_d_L_aux * R_IO_aux) / (pairs.R_p_d_L)
    F_s_L_d_aux = (np.abs(F_t_L_d_aux) * _tand(alpha_n) / _cosd(gamma_L_aux))
    F_a_L_d_aux = H_IO_aux * R_IO_aux * np.abs(F_t_L_d_aux) * _tand(gamma_L_aux)
    F_apc_B11 = np.abs((1 / L_B11_aux) * ((F_a_L_d_aux * pairs.R_p_d_L) + (F_s_L_d_aux * L_d_aux)))
    F_ppc_B11 = np.abs((1 / L_B11_aux) * ((F_t_L_d_aux * L_d_aux)))
    F_r_B11 = np.sqrt((F_apc_B11) ** 2 + (F_ppc_B11) ** 2)
    f1_B11 = _bearing_f1(np.abs(K11 * F_apc_B11 / F_r_B11))
    return _bearing_loss(G11, K11, RPM_O_aux, mu_oil_dynamic, f1_B11, F_r_B11)


def _box(tq, rpm_in, lo, gear, g):
    """B.5 from ``peak_torque=...`` to the two ``EtaNTorqCorrect`` calls (see auxiliary_box):
    gear pairs, windage, counter-shaft bearings, output bearing and seal, efficiency."""
    with np.errstate(all="ignore"):
        peak_torque = g["peak_torque"]
        input_torque_aux = tq * peak_torque
        pairs = _gear_pairs(g, lo)
        G_i_aux, G_L_aux = pairs.G_i, pairs.G_L
        fluids = oil_and_air_properties(g["ambient_temperature"], g["oil_temperature_rise"])
        # (B.5 also computes mu_air_dynamic; it is never used.)
        RPM_C_aux = rpm_in / G_i_aux
        w = _windage_torques(g, pairs, fluids, rpm_in, RPM_C_aux)
        torque_D_IS_aux = input_torque_aux - w.i_D
        if gear == 1:
            torque_d_IS_aux_lower = 0.5 * G_i_aux * torque_D_IS_aux * pairs.GPEff_i
            torque_d_IS_aux_upper = 0.5 * G_i_aux * torque_D_IS_aux * pairs.GPEff_i
            RPM_O_aux = RPM_C_aux / G_L_aux
            torque_L_d_aux = w.low_driven(RPM_C_aux / G_L_aux)
            # gear forces on the counter shafts; the low drive gear torque is "assumed"
            # without the bearing losses (B.5 recomputes it after them)
            cs_torques = (torque_d_IS_aux_lower, torque_d_IS_aux_lower - w.i_d_lower - w.L_D_lower,
                          torque_d_IS_aux_upper, torque_d_IS_aux_upper - w.i_d_upper - w.L_D_upper)
        else:
            RPM_O_aux = rpm_in
            # QUIRK: `torque_oil_L_d_aux = ... .* ((RPM_O_aux).^1.85) ...` - in high gear the
            # low driven gear freewheels on the output shaft, meshed with the counter shaft, so
            # it turns at RPM_C_aux/G_L_aux, not at the output speed. Corrected: RPM_C_aux/G_L_aux.
            torque_L_d_aux = w.low_driven(RPM_O_aux)
            # In high gear the counter shafts idle: B.5 loads their gears with their own
            # windage torques (`F_t_i_d_aux_lower = (1000 .* torque_i_d_aux_lower ...`).
            cs_torques = (w.i_d_lower, w.L_D_lower, w.i_d_upper, w.L_D_upper)
        B7, B8, B9, B10 = _counter_shaft_bearing_losses(g, pairs, fluids[4], RPM_C_aux, gear, cs_torques)
        if gear == 1:
            torque_D_L_aux_lower = torque_d_IS_aux_lower - w.i_d_lower - w.L_D_lower - B7 - B8
            torque_D_L_aux_upper = torque_d_IS_aux_upper - w.i_d_upper - w.L_D_upper - B9 - B10
            torque_d_L_aux = ((torque_D_L_aux_lower * G_L_aux * pairs.GPEff_L)
                              + (torque_D_L_aux_upper * G_L_aux * pairs.GPEff_L))
        else:
            # QUIRK: `torque_d_L_aux = torque_D_IS_aux - (torque_i_d_aux_upper + ... ) -
            # (torqueloss_B7 + ... + torqueloss_B10)` subtracts counter-shaft torques (windage,
            # bearings) from the input-shaft torque as they stand. Reflected to the input shaft
            # they are 1/G_i_aux as large (the counter shafts turn G_i_aux times slower), and
            # the initial mesh that drives them has its own loss. Corrected: divide the sum by
            # G_i_aux*GPEff_i_aux.
            torque_d_L_aux = (torque_D_IS_aux - (w.i_d_upper + w.i_d_lower + w.L_D_upper + w.L_D_lower)
                              - (B7 + B8 + B9 + B10))
        torqueloss_B11 = _output_bearing_loss(g, pairs, fluids[4], torque_d_L_aux, RPM_O_aux)
        torque_d_L_aux_final = torque_d_L_aux - torque_L_d_aux - torqueloss_B11
        seal = output_seal_loss(g["output_seal_diameter"], g["seal_tangential_friction"])
        torque_d_OS_aux = torque_d_L_aux_final - seal
        return _efficiency(torque_d_OS_aux, input_torque_aux, peak_torque, G_i_aux, G_L_aux, gear, RPM_O_aux)


def _efficiency(torque_d_OS_aux, input_torque_aux, peak_torque, G_i_aux, G_L_aux, gear, RPM_O_aux):
    """B.5's box efficiency and output torque fraction, after the two B.6 floors."""
    if gear == 1:
        trans_efficiency_aux = (torque_d_OS_aux / (input_torque_aux * G_i_aux * G_L_aux))
        # QUIRK: the output torque fraction is output torque / (peak_torque * box ratio),
        # and B.5 hands it to EffDiffRearHD (B.4), which multiplies it by ITS peak torque
        # (32000 N m): the differential sees 32000/5794.088 = 5.52 times the box output
        # torque divided by the box ratio. Corrected: pass torque_d_OS_aux [N m] / 32000.
        torque_d_OS_aux = torque_d_OS_aux / peak_torque / G_i_aux / G_L_aux
    else:
        trans_efficiency_aux = (torque_d_OS_aux / (input_torque_aux))
        torque_d_OS_aux = torque_d_OS_aux / peak_torque
    shape = np.broadcast_shapes(np.shape(trans_efficiency_aux), np.shape(RPM_O_aux))
    trans_efficiency_aux = np.broadcast_to(trans_efficiency_aux, shape)
    torque_d_OS_aux = np.broadcast_to(torque_d_OS_aux, shape)
    # JRV: EtaNTorqCorrect(..., true) then EtaNTorqCorrect(..., false) (thesis B.6)
    trans_efficiency_aux, torque_d_OS_aux = mark_negative(trans_efficiency_aux, torque_d_OS_aux)
    trans_efficiency_aux, torque_d_OS_aux = zero_nan(trans_efficiency_aux, torque_d_OS_aux)
    return trans_efficiency_aux, torque_d_OS_aux, RPM_O_aux
