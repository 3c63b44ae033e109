"""Vehicles typed by hand the way an analyst would, against the importer's rows of the same
vehicles: do the two reach the same accuracy on EPA's measurements? (issue 10, done-when)

    PYTHONPATH=. python validation/hand_workbook.py

The analyst's rows give what a spec sheet gives: peak torque, the gear ratios, the tyre size,
the final drive (EPA's axle ratio), rated power and displacement ("with engine size"), or only
torque, gears and tyre ("basics"); test weight and road load (A, B, C) from EPA's list as an
analyst would copy them; ``transmission`` automatic; none of the importer's extra columns
(gearbox_type, converter_lockup, cylinders, N/V). Torque and gear ratios are the manufacturers'
published figures (model year 2022 brochures and press kits); tyres the base trim's.
Both sets of rows run with the same fleet-calibrated constants (models/), so the difference in
their errors is what the rows' content makes.
"""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from epa_table import epa_fleet  # noqa: E402

from fleetrun.simulation import simulate  # noqa: E402

LBFT_NM = 1.3558179483
AISIN_8 = (5.519, 3.184, 2.050, 1.492, 1.235, 1.000, 0.801, 0.673)       # Toyota UA80 (Direct Shift-8AT)
FORD_GM_10 = (4.696, 2.985, 2.146, 1.769, 1.520, 1.275, 1.000, 0.854, 0.689, 0.636)  # 10R80 / 10L80
ZF_8HP = (4.71, 3.14, 2.10, 1.67, 1.29, 1.00, 0.84, 0.67)                # ZF 8HP70 (FCA 850RE)
ZF_8HP50 = (5.25, 3.36, 2.17, 1.72, 1.32, 1.00, 0.82, 0.64)              # ZF 8HP50 (BMW)
MAZDA_6 = (3.552, 2.022, 1.452, 1.000, 0.708, 0.599)                     # Skyactiv-Drive 6AT

# importer vehicle id (EPA test vehicle _c configuration): peak torque [lb-ft], gears, tyre,
# rated power [hp], displacement [L], fuel
TYPED = {
    "19-AA4A_c3": (184, AISIN_8, "225/65R17", 203, 2.5, "gasoline"),        # Toyota RAV4 FWD
    "20-AV1A_c0": (182, AISIN_8, "205/65R16", 202, 2.5, "gasoline"),        # Toyota Camry AWD LE
    "MKD00017_c0": (500, FORD_GM_10, "275/65R18", 400, 3.5, "gasoline"),    # Ford F-150 3.5 EcoBoost RWD
    "53CPNN1361_c0": (383, FORD_GM_10, "265/70R17", 355, 5.3, "gasoline"),  # Chevrolet Silverado 5.3
    "30C1K85358_c0": (460, FORD_GM_10, "265/65R18", 277, 3.0, "diesel"),    # Chevrolet Silverado 3.0 Duramax
    "1EBPYUG1-003_c1": (186, MAZDA_6, "215/45R18", 186, 2.5, "gasoline"),   # Mazda3 2.5 6AT
    "8EBPYUDG1-002_c0": (186, MAZDA_6, "225/65R17", 187, 2.5, "gasoline"),  # Mazda CX-5 2.5 FWD
    "AE81240_c0": (295, ZF_8HP50, "225/45R18", 255, 2.0, "gasoline"),       # BMW 330i
    "J5100034_c0": (420, FORD_GM_10, "255/40R19", 460, 5.0, "gasoline"),    # Ford Mustang GT
    "JZG1-2.3-J-086_c1": (350, FORD_GM_10, "235/55R17", 310, 2.3, "gasoline"),  # Ford Mustang 2.3 EcoBoost
    "L6WKT7878_c0": (260, ZF_8HP, "265/60R18", 295, 3.6, "gasoline"),      # Jeep Grand Cherokee 3.6 4x2
}
TESTS = ("FTP", "HWFET", "US06")


def typed_rows(imported, engine_size=True):
    """The analyst's rows for the importer's rows ``imported`` (same ids, road load, weight,
    drive and axle ratio; typed torque, gears, tyre; optional power and displacement)."""
    rows = []
    for v in imported:
        torque, gears, tyre, hp, litres, fuel = TYPED[v.vehicle_id]
        rows.append(dataclasses.replace(
            v, peak_engine_torque_Nm=torque * LBFT_NM, transmission="automatic", transmission_gear_ratios=gears,
            tire_size=tyre, fuel=fuel, rated_power_kW=hp * 0.745699872 if engine_size else None,
            engine_displacement_L=litres if engine_size else None, rated_speed_rpm=None, gearbox_type=None,
            converter_lockup=None, cylinders=None, nv_ratio_rpm_per_mph=None, manufacturer=None, make=None,
            model=None, model_year=None, extra={}))
    return rows


def errors(rows, measured):
    """Predicted mpg / measured mpg - 1 per vehicle and test (25 C, the validation's ambient)."""
    out = {}
    for test in TESTS:
        r = simulate(rows, test, ambient_temp_C=25.0)
        out[test] = r.mpg / measured[test].to_numpy(float) - 1.0
    return pd.DataFrame(out, index=[v.vehicle_id for v in rows])


def compare():
    specs, table = epa_fleet()
    by_id = {v.vehicle_id: v for v in specs}
    imported = [by_id[i] for i in TYPED]
    measured = table.set_index("vehicle_id").loc[list(TYPED)]
    result = {"importer": errors(imported, measured),
              "typed, with engine size": errors(typed_rows(imported, True), measured),
              "typed, basics only": errors(typed_rows(imported, False), measured)}
    return result, measured


def summary(e):
    x = e.to_numpy().ravel()
    x = x[np.isfinite(x)]
    return dict(n=x.size, mean=x.mean(), mean_abs=np.abs(x).mean(), within_5pct=np.mean(np.abs(x) <= 0.05))


def main():
    result, measured = compare()
    for name, e in result.items():
        s = summary(e)
        print(f"{name:26s} n={s['n']} mean {s['mean']:+.1%}  mean |e| {s['mean_abs']:.1%}  "
              f"within 5 % {s['within_5pct']:.0%}")
    print(pd.concat(result, axis=1).round(3).to_string())
    return result


if __name__ == "__main__":
    main()
