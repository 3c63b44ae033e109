"""Air-conditioning and cold-weather accessory loads from the ambient temperature.

A/C (models/climate.toml [ac]): no load at or below ``onset_temp_C``, the SC03 reference load
``power_at_reference_W`` at ``reference_temp_C`` (EPA SC03, 40 CFR 86.160: 35 C with solar
load), linear in between and beyond:

    P_ac(T) = P_ref * max(0, (T - T_on) / (T_ref - T_on))

Cold weather ([cold]): blower and defroster load, 0 at or above its onset, linear to the
reference load at EPA's cold-FTP temperature (-6.7 C), constant below.

The extra fuel is the accessory power through the engine's Willans slope, as every extra
engine work in the fuel equation (fleetrun/simulation/engine.py):
``fuel [g/s] = P [W] / (eta_indicated * LHV [J/g])``, while the engine burns fuel.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from fleetrun.resources import model_file


@lru_cache(maxsize=1)
def _climate_constants() -> dict:
    """``models/climate.toml``."""
    return model_file("climate.toml")


def ac_power_W(ambient_temp_C: float, onset_temp_C: float, reference_temp_C: float,
               power_at_reference_W: float) -> float:
    """A/C compressor power at the crank [W] at ``ambient_temp_C`` [C] (linear from the onset
    temperature [C] through the SC03 reference point [C, W]).

    Parameters
    ----------
    ambient_temp_C, onset_temp_C, reference_temp_C : float, [C]
    power_at_reference_W : float, [W]

    Returns
    -------
    power [W].

    >>> ac_power_W(30.0, 20.0, 35.0, 1500.0)
    1000.0
    """
    share = (ambient_temp_C - onset_temp_C) / (reference_temp_C - onset_temp_C)
    return power_at_reference_W * max(0.0, share)


def cold_power_W(ambient_temp_C: float, onset_temp_C: float, reference_temp_C: float,
                 power_at_reference_W: float) -> float:
    """Cold-weather accessory power [W] at ``ambient_temp_C`` [C]: 0 above the onset [C],
    linear to the reference [C, W], constant below it.

    Parameters
    ----------
    ambient_temp_C, onset_temp_C, reference_temp_C : float, [C]
    power_at_reference_W : float, [W]

    Returns
    -------
    power [W].

    >>> cold_power_W(0.0, 10.0, -10.0, 800.0)
    400.0
    """
    share = (onset_temp_C - ambient_temp_C) / (onset_temp_C - reference_temp_C)
    return power_at_reference_W * min(1.0, max(0.0, share))


def accessory_power_W(ambient_temp_C: float) -> float:
    """The climate accessory load [W] at ``ambient_temp_C`` [C] (models/climate.toml).

    Parameters
    ----------
    ambient_temp_C : float, [C]

    Returns
    -------
    power [W] (A/C plus cold-weather load).
    """
    c = _climate_constants()
    keys = ("onset_temp_C", "reference_temp_C", "power_at_reference_W")
    return (ac_power_W(ambient_temp_C, *(c["ac"][k] for k in keys))
            + cold_power_W(ambient_temp_C, *(c["cold"][k] for k in keys)))


def per_vehicle_fuel_g_per_s(power_W: float, eta_indicated, lhv_MJ_per_kg) -> np.ndarray:
    """Extra fuel [g/s] per vehicle (V,) of an accessory load ``power_W`` [W]:
    P / (eta_indicated [-] x LHV [MJ/kg = kJ/g] x 1000).

    Parameters
    ----------
    power_W : float, accessory load [W]
    eta_indicated : float or array (V,), Willans slope [-]
    lhv_MJ_per_kg : float or array (V,), [MJ/kg]

    Returns
    -------
    fuel rate [g/s], (V,).

    >>> round(float(per_vehicle_fuel_g_per_s(1000.0, 0.4, 42.9)), 5)
    0.05828
    """
    return power_W / (np.asarray(eta_indicated, float) * np.asarray(lhv_MJ_per_kg, float) * 1000.0)


def extra_fuel_g_per_s(power_W: float, eta_indicated, lhv_MJ_per_kg, burning) -> np.ndarray:
    """Extra fuel [g/s] of an accessory load ``power_W`` [W] while ``burning`` (V, N).

    Parameters
    ----------
    power_W : float, accessory load [W]
    eta_indicated, lhv_MJ_per_kg : array (V,), Willans slope [-] and LHV [MJ/kg]
    burning : bool array (V, N), where the engine runs

    Returns
    -------
    fuel rate [g/s], (V, N).
    """
    return np.where(burning, per_vehicle_fuel_g_per_s(power_W, eta_indicated, lhv_MJ_per_kg)[:, None], 0.0)
