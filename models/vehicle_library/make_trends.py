"""Write the ``[trend.car]`` and ``[trend.light_truck]`` tables of ``models/turnover.toml``: the
estimated real-world fuel economy of new **non-electric** cars and trucks by model year, from EPA
Automotive Trends (``inputs/epa_trends/trends_2022_light_duty.csv``, PROVENANCE.md there).

    python models/vehicle_library/make_trends.py     # prints the two tables

Trends' class mean is production-weighted harmonic (gallons per mile averaged); the electric
vehicles' share e of a class and year is taken out of it at the mpg-equivalent of the export's
all-electric manufacturer of that class and year (the nearest year where it has no row):

    mpg_non_electric = (1 - e) / (1 / mpg_class - e / mpg_electric)

Why non-electric and per class: docs/validation-state-fuel.md, "Why the model's fleet loses mpg
over 2000-2008" (the library's MY2022 vehicles are non-electric, and MV-1's automobile and truck
counts already carry the shift of sales between the classes).
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[2]
SOURCE = ROOT / "inputs" / "epa_trends" / "trends_2022_light_duty.csv"
# turnover.toml trend name -> Trends regulatory class
TABLES = {"car": "car", "light_truck": "truck"}


def nonelectric_mpg(regulatory_class: str, column: str = "real_world_mpg", electric: bool = False) -> pd.Series:
    """Trends' ``column`` [mpg] of ``regulatory_class`` by model year, electric vehicles taken
    out of the harmonic mean (``electric=True``: as published).

    Parameters
    ----------
    regulatory_class : str, ``all``, ``car`` or ``truck``
    column : str, ``real_world_mpg`` or ``two_cycle_mpg``
    electric : bool, keep the electric vehicles

    Returns
    -------
    pandas Series, mpg [mi/gal] indexed by model year.
    """
    data = pd.read_csv(SOURCE)
    part = data[data.regulatory_class == regulatory_class].set_index("model_year")
    if electric:
        return part[column]
    share, proxy = part.ev_share, part[f"ev_proxy_{column}"].ffill().bfill()
    return (1.0 - share) / (1.0 / part[column] - share / proxy)


def toml_tables() -> str:
    """The ``[trend.*]`` tables, mpg to two decimals."""
    out = []
    for name, regulatory_class in TABLES.items():
        mpg = nonelectric_mpg(regulatory_class)
        cells = ", ".join(f"{year} = {value:.2f}" for year, value in mpg.items())
        out.append(f"[trend.{name}]\nmpg_by_model_year = {{{cells}}}\nfuture_from_last_years = 10\n")
    return "\n".join(out)


if __name__ == "__main__":
    print(toml_tables())
