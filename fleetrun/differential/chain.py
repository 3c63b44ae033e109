"""Evaluate a reference differential's ordered chain of loss components (thesis Eqs 5.23-5.29).

The torque travels through the stages in order (thesis Sec. 5.3: "each efficiency will modify
the torque as the torque travels ... before the torque gets to the next component"). After
every stage the efficiency floor B.6 applies (negative -> NaN); at the end NaN -> 0.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from fleetrun.differential.expressions import evaluate
from fleetrun.differential.models import ReferenceModel, reference_model
from fleetrun.errors import InputError
from fleetrun.physics import bearings, gear_mesh, seals, windage
from fleetrun.physics.floor import mark_negative, zero_nan
from fleetrun.units import RAD_S_PER_RPM

# Stage parameters that steer the chain rather than feed the component.
_CONTROL_KEYS = {"component", "label", "split"}


def _seal(p, torque, speed_rpm):
    return seals.seal_torque_Nm(p["shaft_radius_m"], seals.seal_tangential_force_N_per_m(p["seal_strength"]))


def _bearing(p, torque, speed_rpm):
    load = bearings.bearing_load_thesis(torque, p["load_radius"], p["pressure_angle_rad"],
                                        p["bearings"], p.get("load_multiplier", 1.0))
    return bearings.taper_roller_moment(
        load, speed_rpm, p["bore_mm"], p["outer_mm"], p["kinematic_viscosity"],
        p.get("friction_coefficient", 0.0018), p.get("lubrication_factor", 8.0),
        p.get("f1", 20.0), p.get("f2", 25.0))


def _cylinder(p, torque, speed_rpm):
    return windage.cylindrical_windage_torque_Nm(p["viscosity_Pa_s"], p["diameter_m"], p["length_m"],
                                                 p["clearance_m"], RAD_S_PER_RPM * speed_rpm)


def _sphere(p, torque, speed_rpm):
    # The printed code feeds rpm where Eq. 5.2 wants rad/s (docs/thesis-quirks.md).
    return windage.spherical_windage_torque_Nm(p["viscosity_Pa_s"], speed_rpm,
                                               p["inner_radius_m"], p["outer_radius_m"])


def _helical_windage(p, torque, speed_rpm):
    return windage.helical_gear_windage_torque_Nm(
        speed_rpm, p["face_width_m"], p["pitch_radius_m"], p["outer_diameter_m"], p["inner_diameter_m"],
        p["immersion"], p["rho_oil"], p["nu_oil"], p["rho_air"], p["nu_air"], p["enclosure_factor"])


def _bevel_windage(p, torque, speed_rpm):
    return windage.bevel_gear_windage_torque_Nm(
        speed_rpm, p["pitch_radius_in"], p["face_width_in"], p["face_factor"], p["helix_angle_rad"],
        p["immersion"], p["mu_oil"], p["mu_air"], p.get("inner_radius_in"))


def _helical_mesh(p, speed_rpm):
    return gear_mesh.helical_mesh_efficiency(p["friction_coefficient"], p["center_distance"],
                                             p["pressure_angle_rad"], p["gear_ratio"], p["contact_ratio"])


def _hypoid_mesh(p, speed_rpm):
    v = gear_mesh.hypoid_sliding_speed_fpm(speed_rpm, p["outer_pitch_radius_gap_in"],
                                           p["face_width_gap_in"], p["pinion_teeth"])
    f = gear_mesh.dudley_friction_coefficient(v)
    return gear_mesh.hypoid_mesh_efficiency(f, p["normal_pressure_angle_rad"],
                                            p["pinion_spiral_rad"], p["gear_spiral_rad"])


#: Components that take a loss torque from the power path: f(params, torque_Nm, speed_rpm).
LOSS_COMPONENTS = {
    "seal": _seal,
    "bearing": _bearing,
    "cylindrical_windage": _cylinder,
    "spherical_windage": _sphere,
    "helical_gear_windage": _helical_windage,
    "bevel_gear_windage": _bevel_windage,
}
#: Gear meshes: f(params, speed_rpm) -> efficiency; torque x ratio x eta, speed / ratio.
MESH_COMPONENTS = {"helical_mesh": _helical_mesh, "hypoid_mesh": _hypoid_mesh}

# Fluid names every stage may read without naming them in the model file.
_FLUIDS = ("mu_air", "rho_air", "nu_air", "mu_oil", "rho_oil", "nu_oil")


@lru_cache(maxsize=1024)
def resolved_stages(model_id: str, gear_ratio: float, oil_temp_C: float):
    """The model's stages with every parameter evaluated to a number (cached).

    Parameters
    ----------
    model_id : str, a reference differential id (``models/differentials/``)
    gear_ratio : float, final-drive ratio [-]
    oil_temp_C : float, lubricant temperature [C]

    Returns
    -------
    tuple of (component name, dict of parameters (units as the model file names them), split [-]).
    """
    model = reference_model(model_id)
    names = model.resolve(gear_ratio, oil_temp_C)
    stages = []
    for i, stage in enumerate(model.stages, start=1):
        component = stage.get("component")
        if component not in LOSS_COMPONENTS and component not in MESH_COMPONENTS:
            valid = sorted(LOSS_COMPONENTS) + sorted(MESH_COMPONENTS)
            raise InputError(f"{model.path.name} stage {i}: unknown component '{component}'; "
                             f"valid: {', '.join(valid)}")
        params = {k: names[k] for k in _FLUIDS if k in names}
        for key, value in stage.items():
            if key not in _CONTROL_KEYS:
                params[key] = evaluate(value, names, where=f"{model.path.name} stage {i} {key}")
        stages.append((component, params, float(stage.get("split", 1))))
    return tuple(stages)


def evaluate_stage_chain(model: ReferenceModel, torque_fraction, speed_rpm, gear_ratio: float,
                         oil_temp_C: float, *, stage_losses: list | None = None):
    """Run one reference differential: returns (eta, output torque fraction, output speed).

    ``torque_fraction`` is scaled to the model's capacity (thesis Sec. 5.2.1.A), the stages
    run in order, and the output torque is renormalised as the code does:
    ``torque / capacity / g * output_shafts`` (B.1, B.2, B.4). If ``stage_losses`` is a
    list, (label, loss torque [N m]) of each loss stage is appended to it.

    Parameters
    ----------
    model : ReferenceModel, the reference differential
    torque_fraction : float or array, input torque / Kim torque scale [-]
    speed_rpm : float or array, input speed [rpm]
    gear_ratio : float, final-drive ratio [-]
    oil_temp_C : float, lubricant temperature [C]
    stage_losses : list or None, receives (label, loss torque [N m]) per loss stage

    Returns
    -------
    (efficiency [-], output torque fraction [-], output speed [rpm]), arrays of the broadcast shape.
    """
    torque_fraction, speed_rpm = np.broadcast_arrays(np.asarray(torque_fraction, dtype=float),
                                                     np.asarray(speed_rpm, dtype=float))
    shape = torque_fraction.shape
    # work on flat arrays (0-d arithmetic yields numpy scalars, which cannot be masked)
    torque = torque_fraction.ravel() * model.capacity_torque_Nm
    speed = speed_rpm.ravel().copy()
    eta = np.ones_like(torque)
    labels = [s.get("label", s["component"]) for s in model.stages]
    with np.errstate(all="ignore"):
        for label, (component, params, split) in zip(labels, resolved_stages(model.id, gear_ratio, oil_temp_C)):
            if component in MESH_COMPONENTS:
                eta_s = MESH_COMPONENTS[component](params, speed)
                ratio = params["gear_ratio"]
                torque = torque * ratio * eta_s
                speed = speed / ratio
            else:
                loss = LOSS_COMPONENTS[component](params, torque, speed)
                if stage_losses is not None:
                    stage_losses.append((label, np.broadcast_to(loss, torque.shape).reshape(shape).copy()))
                eta_s = 1 - loss / torque
                torque = torque * eta_s / split if split != 1 else torque * eta_s
            eta = eta * eta_s
            # thesis B.6 EtaNTorqCorrect(eta, torque, true): negative -> NaN, NaN rides along
            eta, torque = mark_negative(eta, torque, copy=False)
        out_fraction = torque / model.capacity_torque_Nm / gear_ratio * model.output_shafts
    # thesis B.6 EtaNTorqCorrect(eta, torque, false): NaN -> 0
    eta, out_fraction = zero_nan(eta, out_fraction, copy=False)
    return eta.reshape(shape), out_fraction.reshape(shape), np.broadcast_to(speed, torque.shape).reshape(shape)
