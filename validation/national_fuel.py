"""Registrations -> national highway fuel in years no validation state-year uses
(docs/validation-state-fuel.md, "Where the state gasoline error comes from").

    python validation/national_fuel.py

The issue's state workbook (MV-1 counts by type, ``base_year_vmt_million``, ``cycle_mix =
default``, uncalibrated) run for the whole nation in 2000 and 2009 (2008: class mpg only, on 2009's counts)
(``inputs/state_statistics/national_years.csv``, PROVENANCE.md there): highway gasoline and
special fuels against FHWA's national totals, and the light-duty classes' on-road mpg against
FHWA VM-1's passenger-car and other 2-axle 4-tire vehicle mpg (the categories before 2007, the
same split as MV-1's automobiles and light trucks). A national year tests the model's fuel per
mile and class mix without any state's own fuel accounting in it.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "validation"))

import state_fuel  # noqa: E402  (the state validation's workbook, the one owner of it)

DATA = ROOT / "inputs" / "state_statistics" / "national_years.csv"


def run_year(row: pd.Series) -> dict:
    """One national year: model gallons by fuel and light-duty class mpg against the observed."""
    from fleetrun.run.runner import run_fleet
    from fleetrun.workbook import read_fleet

    base = pd.Series({"state": "United States", "year": int(row.year), "mv1_automobiles": row.mv1_automobiles,
                      "mv1_buses": row.mv1_buses, "mv1_trucks": row.mv1_trucks,
                      "mv1_motorcycles": row.mv1_motorcycles, "vmt_million_mi": row.vmt_million_mi})
    with tempfile.TemporaryDirectory() as tmp:
        fiscal = run_fleet(read_fleet(state_fuel.workbook(Path(tmp) / "us.xlsx", base, 1, 0.0)), error_model=None).fiscal
    fiscal = fiscal[fiscal.fiscal_year == int(row.year)]
    gallons = fiscal.groupby("fuel").fuel_gal.sum()
    by_class = fiscal.groupby("vehicle_class")[["miles", "fuel_gal"]].sum()
    mpg = by_class.miles / by_class.fuel_gal
    out = {"year": int(row.year), "gasoline_model_Mgal": gallons.get("gasoline", 0.0) / 1e6,
           "gasoline_observed_Mgal": row.highway_gasoline_mgal, "diesel_model_Mgal": gallons.get("diesel", 0.0) / 1e6,
           "diesel_observed_Mgal": row.special_fuels_mgal, "automobile_mpg": mpg["automobile"],
           "light_truck_mpg": mpg["light_truck"], "vm1_passenger_car_mpg": row.vm1_passenger_car_mpg,
           "vm1_other_2axle_4tire_mpg": row.vm1_other_2axle_4tire_mpg}
    for fuel in ("gasoline", "diesel"):
        out[f"{fuel}_error_pct"] = 100 * (out[f"{fuel}_model_Mgal"] / out[f"{fuel}_observed_Mgal"] - 1)
    out["automobile_mpg_error_pct"] = 100 * (out["automobile_mpg"] / out["vm1_passenger_car_mpg"] - 1)
    out["light_truck_mpg_error_pct"] = 100 * (out["light_truck_mpg"] / out["vm1_other_2axle_4tire_mpg"] - 1)
    return out


def main(argv=None) -> pd.DataFrame:
    table = pd.DataFrame([run_year(row) for _, row in pd.read_csv(DATA).iterrows()])
    for _, r in table.iterrows():
        print(f"{r.year:.0f}: gasoline {r.gasoline_model_Mgal:,.0f} M gal vs {r.gasoline_observed_Mgal:,.0f} "
              f"({r.gasoline_error_pct:+.1f} %), special fuels {r.diesel_model_Mgal:,.0f} vs "
              f"{r.diesel_observed_Mgal:,.0f} ({r.diesel_error_pct:+.1f} %); automobile {r.automobile_mpg:.2f} mpg"
              f" (VM-1 passenger car {r.vm1_passenger_car_mpg}, {r.automobile_mpg_error_pct:+.1f} %), light truck"
              f" {r.light_truck_mpg:.2f} mpg (VM-1 other 2-axle 4-tire {r.vm1_other_2axle_4tire_mpg},"
              f" {r.light_truck_mpg_error_pct:+.1f} %)")
    return table


if __name__ == "__main__":
    main()
