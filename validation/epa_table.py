"""The EPA 2022 Test Car List as measured targets and (until `fleetrun import-epa` is used)
simulation rows, for validation/epa_fuel_economy.py.

Measured targets per test vehicle and configuration (unadjusted certification values, mpg):
``FTP`` (the composite), ``FTP:bag1..3``, ``HWFET`` (EPA's "HWFE"), ``US06``, and ``UDDS:hot``
= the hot-start UDDS made of bag 3 (the bag-1 trace driven hot) and bag 2:
mpg = (d1 + d2) / (d1 / mpg3 + d2 / mpg2), d1, d2 the bag distances of the UDDS trace.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
TSTCAR = ROOT / "inputs" / "epa" / "22-tstcar.csv"

FTP_PROCEDURES = {"Federal fuel 2-day exhaust (w/can load)", "Federal fuel 3-day exhaust",
                  "CVS 75 and later (w/o can. load)"}
FUELS = {"Tier 2 Cert Gasoline": "gasoline", "Federal Cert Diesel 7-15 PPM Sulfur": "diesel"}
DRIVE = {"F": "LD_FWD", "R": "LD_RWD", "A": "LD_AWD", "4": "LD_4WD", "P": "LD_4WD"}
GEARBOX = {"A": "automatic", "SA": "automatic", "AM": "automated_manual", "AMS": "automated_manual",
           "M": "manual", "CVT": "cvt", "SCV": "cvt"}
UDDS_BAG1_END_S = 505.0
KEY = ["Test Vehicle ID", "Test Veh Configuration #"]


def read_tstcar(path=TSTCAR) -> pd.DataFrame:
    return pd.read_csv(path, encoding="utf-8-sig", low_memory=False)


def _hybrid_ids(d: pd.DataFrame) -> set:
    """Test vehicles with an electric test, a 4-bag FTP or a hybrid name (not modelled)."""
    proc = d["Test Procedure Description"]
    name = (d["Represented Test Veh Model"].fillna("") + " " + d["Actual Tested Testgroup"].fillna("")).str.lower()
    bad = (proc.str.contains("Charge Depleting") | d["Test Fuel Type Description"].isin(["Electricity", "Hydrogen 5"])
           | (proc.isin(FTP_PROCEDURES) & d["FE Bag 4"].notna())
           | name.str.contains("hybrid|phev|plug-in|e-hybrid| 4xe|recharge|energi"))
    return set(d.loc[bad, "Test Vehicle ID"])


def measured_table(d: pd.DataFrame, udds_bag_miles=(3.59, 3.91)) -> pd.DataFrame:
    """One row per test vehicle and configuration with FTP, bags, HWFET, US06 and hot UDDS."""
    d = d[d["Test Fuel Type Description"].isin(FUELS)]
    d = d[~d["Test Vehicle ID"].isin(_hybrid_ids(d))]
    proc = d["Test Procedure Description"]
    take = lambda mask, cols: d[mask].groupby(KEY)[cols].mean()  # noqa: E731 (repeat tests: mean)
    ftp = take(proc.isin(FTP_PROCEDURES), ["RND_ADJ_FE", "FE Bag 1", "FE Bag 2", "FE Bag 3"])
    ftp.columns = ["FTP", "FTP:bag1", "FTP:bag2", "FTP:bag3"]
    hw = take(proc == "HWFE", ["RND_ADJ_FE"]).rename(columns={"RND_ADJ_FE": "HWFET"})
    us = take(proc == "US06", ["RND_ADJ_FE"]).rename(columns={"RND_ADJ_FE": "US06"})
    m = ftp.join(hw, how="inner").join(us, how="left")
    d1, d2 = udds_bag_miles
    m["UDDS:hot"] = (d1 + d2) / (d1 / m["FTP:bag3"] + d2 / m["FTP:bag2"])
    first = d.groupby(KEY).first()
    return first.join(m, how="inner").reset_index()


# Generic ratio sets per gear count (first gear first), from common production gearboxes: 4 GM 4T65,
# 5 Aisin, 6 GM 6T40, 7 Mercedes 7G, 8 ZF 8HP, 9 ZF 9HP, 10 Ford/GM 10R80; the CVT entry is the
# ratio span of a Jatco CVT8 (7.0). Only the steps matter: the top gear is scaled by N/V.
GENERIC_GEARS = {
    4: (2.92, 1.57, 1.00, 0.70),
    5: (3.52, 2.04, 1.40, 1.00, 0.76),
    6: (4.58, 2.96, 1.91, 1.45, 1.00, 0.75),
    7: (4.38, 2.86, 1.92, 1.37, 1.00, 0.82, 0.73),
    8: (4.71, 3.14, 2.11, 1.67, 1.29, 1.00, 0.84, 0.67),
    9: (4.70, 2.84, 1.91, 1.38, 1.00, 0.81, 0.70, 0.58, 0.48),
    10: (4.70, 2.99, 2.15, 1.80, 1.52, 1.28, 1.00, 0.85, 0.69, 0.64),
}
CVT_SPAN = (2.63, 0.378)
MPH_MPS = 0.44704


def spec_rows(table: pd.DataFrame):
    """(VehicleSpec list, kept table) for the rows that can be simulated (temporary builder
    until validation uses `fleetrun import-epa`'s workbook)."""
    from fleetrun.vehicle import VehicleSpec

    specs, keep = [], []
    for i, r in table.iterrows():
        box = GEARBOX.get(r["Tested Transmission Type Code"])
        n = int(r["# of Gears"])
        if box is None or r["Axle Ratio"] <= 0 or r["N/V Ratio"] <= 0 or r["Rated Horsepower"] <= 0:
            continue
        if box == "cvt":
            gears = CVT_SPAN
        elif n in GENERIC_GEARS:
            gears = GENERIC_GEARS[n]
        else:
            continue
        P_kW = float(r["Rated Horsepower"]) * 0.745699872
        T_peak = 1.1 * P_kW * 1e3 / (6000 * 2 * math.pi / 60)
        # N/V [rpm per mph] = axle x top / r x 60 / (2 pi) x 0.44704  ->  r
        radius = float(r["Axle Ratio"]) * gears[-1] * MPH_MPS * 60 / (2 * math.pi) / float(r["N/V Ratio"])
        nominal = 0.5 * (17 * 0.0254 + 2 * 0.225 * 0.60)  # 225/60R17
        fuel = FUELS[r["Test Fuel Type Description"]]
        extra = {"tire_rolling_radius_factor": radius / nominal, "gearbox_type": box,
                 "converter_lockup": "yes" if r["Transmission Lockup?"] == "Y" else "no",
                 "cylinders": r["# of Cylinders and Rotors"], "nv_ratio_rpm_per_mph": float(r["N/V Ratio"]),
                 "manufacturer": r["Vehicle Manufacturer Name"]}
        specs.append(VehicleSpec(
            vehicle_id=f"{r['Test Vehicle ID']}#{r['Test Veh Configuration #']}", vehicle_class="epa", duty_class="LD",
            configuration=DRIVE.get(r["Drive System Code"], "LD_AWD"), count=1, annual_miles=10000.0, fuel=fuel,
            peak_engine_torque_Nm=T_peak, transmission="manual" if box in ("manual", "automated_manual") else "automatic",
            transmission_gear_ratios=tuple(gears), final_drive_ratio=float(r["Axle Ratio"]),
            test_weight_kg=float(r["Equivalent Test Weight (lbs.)"]) * 0.45359237,
            coastdown_A_lbf=float(r["Target Coef A (lbf)"]), coastdown_B_lbf_per_mph=float(r["Target Coef B (lbf/mph)"]),
            coastdown_C_lbf_per_mph2=float(r["Target Coef C (lbf/mph**2)"]), tire_size="225/60R17",
            rated_power_kW=P_kW, engine_displacement_L=float(r["Test Veh Displacement (L)"]), extra=extra))
        keep.append(i)
    return specs, table.loc[keep].reset_index(drop=True)


if __name__ == "__main__":
    t = measured_table(read_tstcar())
    s, k = spec_rows(t)
    print(len(t), len(s), k["Tested Transmission Type Code"].value_counts().to_dict(), np.isfinite(k["US06"]).sum())
