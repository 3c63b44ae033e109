"""The ten differential configurations as products of series chains (thesis Eqs 5.23-5.29).

Each configuration in ``models/configurations.toml`` lists its ``factors``; every factor is a
series of reference models evaluated at the configuration's input, each model passing its
output torque fraction and speed to the next (B.3 and B.5 call B.2 and B.4 that way); the
configuration's efficiency is the product of the factors' efficiencies (Eqs 5.26, 5.29).
"""
from __future__ import annotations

import numpy as np

from fleetrun.differential.chain import evaluate_stage_chain
from fleetrun.differential.models import configuration_table, reference_model
from fleetrun.errors import InputError, unknown_name_error
from fleetrun.physics.two_speed_box import auxiliary_box

AXLE_GEARS = ("low", "high")


def configuration_ids() -> list[str]:
    """The configuration ids in the order of ``models/configurations.toml`` (their one source).

    Returns
    -------
    list of str, the canonical ids.
    """
    return list(configuration_table())


def dual_configuration_ids() -> list[str]:
    """The configurations with a two-speed (dual) axle, which need a low gear ratio.

    Returns
    -------
    list of str, the canonical ids of the dual configurations.
    """
    return [c for c in configuration_ids() if uses_two_speed_box(c)]


def canonical_configuration(name: str) -> str:
    """``ld-rwd``, ``LD_RWD``, ``Ld-Rwd`` -> ``LD_RWD``; unknown names raise InputError.

    Parameters
    ----------
    name : str, a configuration id in any case, with ``-`` or ``_``

    Returns
    -------
    str, the canonical id.
    """
    key = str(name).strip().upper().replace("-", "_")
    table = configuration_table()
    if key not in table:
        raise unknown_name_error("configuration", str(name), table,
                                 hint="Configuration ids are listed in docs/interface.md and `fleetrun map --help`")
    return key


def uses_two_speed_box(configuration: str) -> bool:
    """True for the dual (two-speed) configurations, which need a low gear ratio.

    Parameters
    ----------
    configuration : str, a configuration id

    Returns
    -------
    bool.
    """
    factors = configuration_table()[canonical_configuration(configuration)]["factors"]
    return any(reference_model(m).kind == "two_speed_box" for chain in factors for m in chain)


def _main_axle_model(configuration: str):
    """The last stage-chain model of the last factor: the axle that drives the wheels."""
    factors = configuration_table()[canonical_configuration(configuration)]["factors"]
    models = [reference_model(m) for m in factors[-1] if reference_model(m).kind == "stage_chain"]
    return models[-1]


def configuration_lubricant(configuration: str) -> str:
    """The lubricant of the configuration's driving axle (ATF for a transaxle, else gear oil).

    Parameters
    ----------
    configuration : str, a configuration id

    Returns
    -------
    str, a lubricant name of ``models/lubricants.toml``.
    """
    return _main_axle_model(configuration).lubricant


def reference_capacity_Nm(configuration: str) -> float:
    """Torque capacity of the driving axle's reference differential (thesis Sec. 5.2.1.A).

    A torque fraction of 1 is this torque at the reference differential; used where a map
    needs absolute torque without a vehicle (VECTO baseline, effects in ``fleetrun map``).

    Parameters
    ----------
    configuration : str, a configuration id

    Returns
    -------
    float, torque capacity [N m].
    """
    return _main_axle_model(configuration).capacity_torque_Nm


def evaluate_series(chain, torque_fraction, speed_rpm, gear_ratio, *, low_gear_ratio, axle_gear, oil_temp_C):
    """Run a series of reference models; returns the product efficiency.

    Parameters
    ----------
    chain : sequence of str, reference model ids, run in order
    torque_fraction : float or array, input torque / Kim torque scale [-]
    speed_rpm : float or array, input speed [rpm]
    gear_ratio : float, final-drive ratio [-]
    low_gear_ratio : float or None, two-speed axle low ratio [-]
    axle_gear : str, ``high`` or ``low``
    oil_temp_C : float, lubricant temperature [C]

    Returns
    -------
    efficiency [-], an array of the broadcast shape.
    """
    eta_total = None
    tf, rpm = torque_fraction, speed_rpm
    for model_id in chain:
        model = reference_model(model_id)
        if model.kind == "stage_chain":
            eta, tf, rpm = evaluate_stage_chain(model, tf, rpm, gear_ratio, oil_temp_C)
        elif model.kind == "fixed_efficiency":
            # B.3: the next model sees the reduced torque; the efficiency multiplies after.
            eta = np.full(np.broadcast(tf, rpm).shape, model.efficiency)
            tf = np.asarray(tf, dtype=float) * model.efficiency
        elif model.kind == "two_speed_box":
            eta, tf, rpm = auxiliary_box(tf, rpm, low_gear_ratio, axle_gear)
        else:
            raise InputError(f"{model.path.name}: unknown model kind '{model.kind}'; "
                             "valid: stage_chain, fixed_efficiency, two_speed_box")
        eta_total = eta if eta_total is None else eta_total * eta
    return eta_total


def thesis_efficiency(configuration, torque_fraction, speed_rpm, gear_ratio, *, low_gear_ratio=None,
                      axle_gear="high", oil_temp_C=70.0):
    """Efficiency of a configuration for one scalar gear ratio (arrays of torque and speed).

    Parameters
    ----------
    configuration : str, a configuration id
    torque_fraction : float or array, input torque / Kim torque scale [-]
    speed_rpm : float or array, differential input speed [rpm]
    gear_ratio : float, final-drive ratio [-]
    low_gear_ratio : float or None, two-speed axle low ratio [-] (dual configurations)
    axle_gear : str, ``high`` or ``low``
    oil_temp_C : float, lubricant temperature [C] (70 C: thesis code B.7)

    Returns
    -------
    efficiency [-], the product over the configuration's factors (thesis Ch. 5, Appendix B).
    """
    config = configuration_table()[canonical_configuration(configuration)]
    eta = None
    for chain in config["factors"]:
        e = evaluate_series(chain, torque_fraction, speed_rpm, gear_ratio, low_gear_ratio=low_gear_ratio,
                            axle_gear=axle_gear, oil_temp_C=oil_temp_C)
        eta = e if eta is None else eta * e
    return eta
