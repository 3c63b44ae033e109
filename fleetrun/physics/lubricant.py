"""Lubricant and air properties at the differential's operating temperature.

Walther's equation fitted through two viscosity points (thesis Eqs 5.13-5.14, code B.7),
Sutherland's law for air (thesis Eqs 5.15-5.17) and densities with a linear thermal-expansion
coefficient (thesis Eqs 5.18-5.19). The lubricant data (standard density and two viscosity
points) live in ``models/lubricants.toml``.

The thesis assumes the lubricant runs 50 K above a 20 C ambient (Sec. 3.1.2), i.e. 70 C; the
printed code (B.7) fixes ``T = 70 + 273.15`` and ``--physics thesis`` keeps that.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from fleetrun.errors import unknown_name_error
from fleetrun.resources import model_file

KELVIN = 273.15
#: Temperature rise of the lubricant over ambient in steady operation (thesis Sec. 3.1.2).
OPERATING_RISE_K = 50.0
#: Operating temperature the printed code fixes (thesis B.7: ``T=70+273.15``).
THESIS_OPERATING_TEMP_C = 70.0
#: Reference temperature of the standard densities (thesis B.7 uses 288.2 K).
DENSITY_REFERENCE_K = 288.2
#: Walther's offset in cSt (thesis Eq. 5.13).
WALTHER_OFFSET_CST = 0.8


def operating_temperature_C(ambient_temp_C, rise_K=OPERATING_RISE_K):
    """Lubricant operating temperature: ambient plus the steady rise (thesis Sec. 3.1.2).

    Parameters
    ----------
    ambient_temp_C : float or array, ambient temperature [C]
    rise_K : float, steady rise over ambient [K] (50 K, thesis Sec. 3.1.2)

    Returns
    -------
    operating temperature [C]

    >>> float(operating_temperature_C(20.0))
    70.0
    """
    return np.asarray(ambient_temp_C, dtype=float) + rise_K


def walther_coefficients(nu1_cSt, temp1_K, nu2_cSt, temp2_K):
    """Walther's A and B through two viscosity points (thesis Eq. 5.13, code B.7).

    ``log10(log10(nu + 0.8)) = A + B log10(T)`` with nu in cSt and T in K. B.7 solves the
    2x2 system with MATLAB's backslash; ``numpy.linalg.solve`` is the same LU solve.

    Parameters
    ----------
    nu1_cSt, nu2_cSt : float, kinematic viscosities at the two points [cSt = mm^2/s]
    temp1_K, temp2_K : float, their temperatures [K]

    Returns
    -------
    (A, B) : Walther's coefficients [-]

    >>> [round(x, 4) for x in walther_coefficients(150.0, 313.15, 15.0, 373.15)]
    [8.8433, -3.4078]
    """
    lhs = np.array([[1.0, np.log10(temp1_K)], [1.0, np.log10(temp2_K)]])
    rhs = np.array([np.log10(np.log10(nu1_cSt + WALTHER_OFFSET_CST)),
                    np.log10(np.log10(nu2_cSt + WALTHER_OFFSET_CST))])
    a, b = np.linalg.solve(lhs, rhs)
    return float(a), float(b)


def walther_kinematic_viscosity_m2_s(temp_K, A, B):
    """Kinematic viscosity from Walther's equation solved for nu (thesis Eq. 5.14).

    ``nu = 10**(10**(A + B log10 T)) - 0.8`` in cSt, returned in m^2/s.

    Parameters
    ----------
    temp_K : float or array, lubricant temperature [K]
    A, B : float, Walther's coefficients [-] (:func:`walther_coefficients`, nu in cSt, T in K)

    Returns
    -------
    kinematic viscosity [m^2/s]

    >>> a, b = walther_coefficients(150.0, 313.15, 15.0, 373.15)
    >>> round(float(walther_kinematic_viscosity_m2_s(343.15, a, b)) * 1e6, 2)   # cSt at 70 C
    38.55
    """
    temp_K = np.asarray(temp_K, dtype=float)
    nu_cSt = 10 ** (10 ** (A + B * np.log10(temp_K))) - WALTHER_OFFSET_CST
    return nu_cSt * 1e-6


def sutherland_air_viscosity_Pa_s(temp_K, b=1.458e-6, s_K=110.4):
    """Dynamic viscosity of air, Sutherland's law (thesis Eqs 5.15-5.17, U.S. Std. Atm. 1976).

    ``mu = b T^(1/2) / (1 + s/T)`` with b = 1.458e-6 kg/(m s K^1/2) and s = 110.4 K.

    Parameters
    ----------
    temp_K : float or array, air temperature [K]
    b : float, Sutherland's constant [kg/(m s K^1/2)]
    s_K : float, Sutherland's temperature [K]

    Returns
    -------
    dynamic viscosity [Pa s]

    >>> round(float(sutherland_air_viscosity_Pa_s(343.15)) * 1e6, 3)
    20.434
    """
    temp_K = np.asarray(temp_K, dtype=float)
    return b * temp_K ** 0.5 / (1 + s_K / temp_K)


def oil_density_kg_m3(temp_K, density_std_kg_m3, cte_per_K=7e-4):
    """Lubricant density with linear thermal expansion (thesis Eqs 5.18-5.19, B.7).

    ``rho = rho_std / (1 + cte (T - 288.2))``.

    Parameters
    ----------
    temp_K : float or array, lubricant temperature [K]
    density_std_kg_m3 : float, density at 288.2 K [kg/m^3]
    cte_per_K : float, volumetric thermal-expansion coefficient [1/K]

    Returns
    -------
    density [kg/m^3]

    >>> round(float(oil_density_kg_m3(343.15, 880.0)), 1)
    847.4
    """
    temp_K = np.asarray(temp_K, dtype=float)
    return density_std_kg_m3 * (1 + cte_per_K * (temp_K - DENSITY_REFERENCE_K)) ** -1


def air_density_thesis_kg_m3(temp_K, density_std_kg_m3=1.2250, cte_per_K=7e-4):
    """Air density as B.7 prints it: ``rho = 1.225 (1 - cte (T - 288.2))^-1``.

    Quirk (docs/thesis-quirks.md): the sign makes air *denser* when hot, and the liquid's
    expansion coefficient is used for a gas. Kept for ``--physics thesis``; the ideal gas
    would give ``1.225 * 288.2 / T``.

    Parameters
    ----------
    temp_K : float or array, air temperature [K]
    density_std_kg_m3 : float, density at 288.2 K [kg/m^3]
    cte_per_K : float, the printed expansion coefficient [1/K]

    Returns
    -------
    density [kg/m^3], the shape of ``temp_K``.

    >>> round(float(air_density_thesis_kg_m3(343.15)), 4)   # 70 C: denser than at 15 C (the quirk)
    1.274
    """
    temp_K = np.asarray(temp_K, dtype=float)
    return density_std_kg_m3 * (1 - cte_per_K * (temp_K - DENSITY_REFERENCE_K)) ** -1


@dataclass(frozen=True)
class FluidProperties:
    """Density [kg/m^3], dynamic viscosity [Pa s] and kinematic viscosity [m^2/s]."""

    rho_kg_m3: float
    mu_Pa_s: float
    nu_m2_s: float


@lru_cache(maxsize=None)
def lubricant_data() -> dict:
    """The lubricants of ``models/lubricants.toml`` keyed by upper-case name.

    Returns
    -------
    dict, lubricant name -> its table of the file: two viscosities ``nu1_cSt``, ``nu2_cSt`` [cSt]
    at ``T1_K``, ``T2_K`` [K] (Walther's two points), ``density_kg_m3`` [kg/m^3] and a description (the source).

    >>> sorted(lubricant_data())
    ['75W90', '80W90', 'ATF']
    """
    data = model_file("lubricants.toml")
    return {name.upper(): spec for name, spec in data["lubricant"].items()}


def lubricant_names() -> list[str]:
    """The lubricant names of ``models/lubricants.toml``.

    Returns
    -------
    list of str, sorted.

    >>> lubricant_names()
    ['75W90', '80W90', 'ATF']
    """
    return sorted(lubricant_data())


def _lubricant(name: str) -> dict:
    data = lubricant_data()
    try:
        return data[name.upper()]
    except KeyError:
        raise unknown_name_error("lubricant", name, data,
                                 hint="Use one of the lubricants in models/lubricants.toml") from None


def walther_viscosity_m2_s(temp_C, lubricant: str):
    """Kinematic viscosity [m^2/s] of a named lubricant at ``temp_C`` (thesis Eqs 5.13-5.14).

    Parameters
    ----------
    temp_C : float or array, lubricant temperature [C]
    lubricant : str, a name of ``models/lubricants.toml`` (e.g. ``80W90``)

    Returns
    -------
    kinematic viscosity [m^2/s], the shape of ``temp_C``.

    >>> round(float(walther_viscosity_m2_s(70.0, "80W90")) * 1e6, 2)   # cSt
    37.51
    """
    spec = _lubricant(lubricant)
    A, B = walther_coefficients(spec["nu1_cSt"], spec["T1_K"], spec["nu2_cSt"], spec["T2_K"])
    return walther_kinematic_viscosity_m2_s(np.asarray(temp_C, dtype=float) + KELVIN, A, B)


def fluid_properties(name: str, temp_C: float = THESIS_OPERATING_TEMP_C) -> FluidProperties:
    """Properties of ``"air"`` or a named lubricant at ``temp_C``, as B.7 computes them.

    B.7 works in kelvin with ``T = 70 + 273.15``; the same arithmetic is kept so that
    ``--physics thesis`` reproduces the printed numbers.

    Parameters
    ----------
    name : str, ``air`` or a lubricant of ``models/lubricants.toml``
    temp_C : float, temperature [C] (default the thesis' operating 70 C)

    Returns
    -------
    FluidProperties: ``rho_kg_m3`` [kg/m^3], ``mu_Pa_s`` (dynamic viscosity [Pa s]),
    ``nu_m2_s`` (kinematic viscosity [m^2/s]).

    >>> round(fluid_properties("air").rho_kg_m3, 4)
    1.274
    """
    temp_K = temp_C + KELVIN
    if name.lower() == "air":
        mu = float(sutherland_air_viscosity_Pa_s(temp_K))
        rho = float(air_density_thesis_kg_m3(temp_K))
        return FluidProperties(rho, mu, mu / rho)
    spec = _lubricant(name)
    A, B = walther_coefficients(spec["nu1_cSt"], spec["T1_K"], spec["nu2_cSt"], spec["T2_K"])
    nu = float(walther_kinematic_viscosity_m2_s(temp_K, A, B))
    rho = float(oil_density_kg_m3(temp_K, spec["density_kg_m3"], spec.get("cte_per_K", 7e-4)))
    return FluidProperties(rho, nu * rho, nu)
