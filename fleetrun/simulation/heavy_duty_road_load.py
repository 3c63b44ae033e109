"""Road load of heavy vehicles from the GEM inputs: tyre rolling resistance and drag area.

EPA's Greenhouse gas Emissions Model (GEM, 40 CFR 1037.520) describes a truck's road load by
its tyres' coefficient of rolling resistance (Crr, kg/t: 40 CFR 1037.520(c)) and its drag area
(CdA, m^2: 40 CFR 1037.520(b)) at the regulatory weight, not by coastdown coefficients. This
module turns them into the EPA target coefficients a Vehicles row holds (F = A + B v + C v^2,
lbf and mph, fleetrun.simulation.road_load):

    A = Crr m g,  B = 0 (GEM's rolling resistance does not vary with speed),  C = rho CdA / 2.
"""
from __future__ import annotations

import numpy as np

from fleetrun.cycles import MPH_TO_MPS
from fleetrun.errors import unknown_name_error
from fleetrun.resources import model_file
from fleetrun.simulation.road_load import LBF_N
from fleetrun.units import STANDARD_GRAVITY_M_S2 as G_MPS2

AIR_DENSITY_KG_M3 = 1.2   # the density make_example_fleet.py and the FHWA class defaults use


def gem_coastdown_lbf(mass_kg, crr, cda_m2, air_density_kg_m3=AIR_DENSITY_KG_M3):
    """EPA target coefficients (A [lbf], B [lbf/mph], C [lbf/mph^2]) of a GEM vehicle.

    Parameters
    ----------
    mass_kg : float or array, regulatory (test) weight [kg]
    crr : float or array, tyre coefficient of rolling resistance [-] (GEM's kg/t / 1000)
    cda_m2 : float or array, drag area [m^2]
    air_density_kg_m3 : float, air density [kg/m^3]

    Returns
    -------
    (A [lbf], B [lbf/mph], C [lbf/mph^2]) as float arrays.
    """
    a = np.asarray(crr, float) * np.asarray(mass_kg, float) * G_MPS2 / LBF_N
    c = 0.5 * air_density_kg_m3 * np.asarray(cda_m2, float) * MPH_TO_MPS ** 2 / LBF_N
    return a, np.zeros_like(a), c


AERO_BINS_FILE = "heavy_duty/gem_aero_bins.toml"


def gem_aero_bin(tractor_type: str, measured_cda_m2: float) -> tuple[str, float]:
    """(bin, GEM input CdA [m^2]) of a Phase 2 tractor of ``tractor_type`` (a key of
    ``models/heavy_duty/gem_aero_bins.toml``, e.g. ``high_roof_sleeper_cab``) whose measured
    drag area is ``measured_cda_m2`` (40 CFR 1037.520(b)(3)); the measured value is rounded
    to one decimal first, as 1037.520(b) asks.

    Parameters
    ----------
    tractor_type : str, a key of ``input_m2`` in ``models/heavy_duty/gem_aero_bins.toml``
    measured_cda_m2 : float, measured drag area CdA [m^2]

    Returns
    -------
    (bin name, GEM input CdA [m^2]).
    """
    data = model_file(AERO_BINS_FILE)
    if tractor_type not in data["input_m2"]:
        raise unknown_name_error("tractor type", tractor_type, tuple(data["input_m2"]))
    cda = round(float(measured_cda_m2), 1)
    index = next(i for i, low in enumerate(data["measured_min_m2"][tractor_type]) if cda >= low - 1e-9)
    return data["bins"][index], float(data["input_m2"][tractor_type][index])


def gem_cda_input_m2(tractor_type: str, measured_cda_m2: float, model_year: int) -> float:
    """The drag area [m^2] GEM runs a Phase 2 tractor with: its bin's input CdA
    (:func:`gem_aero_bin`), less the standard trailer's rear fairing for high-roof tractors
    from model year 2027 (40 CFR 1037.520(b)(4)).

    Parameters
    ----------
    tractor_type : str, a key of ``input_m2`` in ``models/heavy_duty/gem_aero_bins.toml``
    measured_cda_m2 : float, measured drag area CdA [m^2]
    model_year : int, the tractor's model year

    Returns
    -------
    float, drag area GEM runs the tractor with [m^2].
    """
    cda = gem_aero_bin(tractor_type, measured_cda_m2)[1]
    fairing = model_file(AERO_BINS_FILE)["trailer_fairing"]
    if tractor_type.startswith("high_roof") and model_year >= fairing["from_model_year"]:
        cda -= fairing["reduction_m2"]
    return cda
