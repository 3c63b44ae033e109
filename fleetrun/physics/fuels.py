"""Liquid fuel properties: lower heating value, density and CO2 per gallon (``models/fuels.toml``).

The one owner of these facts: the drive-cycle simulation (fuel equation, gallons), the
vehicle-level effects (marginal fuel per unit of work) and the diagnosis recordings (cc -> g)
read them here, the fleet budget its CO2. Sources: EPA certification fuels (40 CFR 1065.710
and 1065.703); CO2 per gallon EPA-420-F-11-041.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

from fleetrun.errors import unknown_name_error
from fleetrun.resources import model_file


@dataclass(frozen=True)
class FuelProperties:
    """``lhv_MJ_per_kg``: lower heating value [MJ/kg] (= kJ/g); ``density_kg_per_L`` [kg/L] (= g/cm^3);
    ``co2_g_per_gal``: tailpipe CO2 per gallon burned [g/gal]."""

    lhv_MJ_per_kg: float
    density_kg_per_L: float
    co2_g_per_gal: float


@lru_cache(maxsize=None)
def fuel_table() -> dict[str, FuelProperties]:
    """Every fuel of ``models/fuels.toml`` by its (lower-case) name.

    Returns
    -------
    dict, fuel name -> FuelProperties (:func:`fuel_properties` gives the units).

    >>> sorted(fuel_table())
    ['diesel', 'gasoline']
    """
    data = model_file("fuels.toml")
    return {name.lower(): FuelProperties(float(v["lhv_MJ_per_kg"]), float(v["density_kg_per_L"]),
                                         float(v["co2_g_per_gal"]))
            for name, v in data.items()}


def fuel_properties(fuel: str) -> FuelProperties:
    """The properties of ``fuel`` (``gasoline``, ``diesel``); an unknown name lists the valid ones.

    Parameters
    ----------
    fuel : str, a fuel name of ``models/fuels.toml`` (case and surrounding blanks ignored)

    Returns
    -------
    FuelProperties: ``lhv_MJ_per_kg`` (lower heating value [MJ/kg]), ``density_kg_per_L``
    [kg/L] and ``co2_g_per_gal`` [g CO2 per US gallon burnt]; their sources are in the file.

    >>> fuel_properties("Gasoline").density_kg_per_L
    0.743
    """
    table = fuel_table()
    try:
        return table[str(fuel).strip().lower()]
    except KeyError:
        raise unknown_name_error("fuel", str(fuel), table, hint="Add it to models/fuels.toml") from None
