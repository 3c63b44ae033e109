"""Convert the Argonne 2018 Toyota Camry XLE dynamometer tests to fleetrun recordings.

Run once from the repository root (numpy/pandas only; no network):

    python inputs/dyno/convert.py

Reads the four original files ``inputs/dyno/6181101x Test Data.txt`` (copied unchanged from
fastsim 2.1.5, see PROVENANCE.md) and writes, for each test, the vehicle-level recording of
docs/interface.md ("Recordings for fleetrun diagnose")

    camry2018_<test>.csv   time_s, vehicle_speed_mph, fuel_rate_cc_per_s

and its sidecar ``camry2018_<test>.toml`` holding the keys of one ``Vehicles`` row of the fleet
workbook. The conversion renames columns only: ``Time[s]`` -> ``time_s`` [s] (the first
stamp, written ``-0.0``, becomes ``0.0``), ``Dyno_Spd[mph]`` -> ``vehicle_speed_mph`` [mph],
``Eng_FuelFlow_Direct_DI[ccps]`` -> ``fuel_rate_cc_per_s`` [cm^3/s]; values are not changed,
rows are not dropped (soak periods included).

The EPA road-load and certification numbers are read from ``inputs/epa/22-tstcar.csv``
(test vehicle 18-AV3A, configuration 1: the 203 hp 2.5 L "CAMRY XLE/XSE" build; the 2018
model year is not in that file). The other values are constants below, each with its source.
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd

HERE = Path(__file__).resolve().parent
EPA_FILE = HERE.parent / "epa" / "22-tstcar.csv"

LB_TO_KG = 0.45359237          # exact
HP_TO_KW = 0.745699872         # mechanical horsepower
LBFT_TO_NM = 1.3558179483      # lbf ft -> N m

# original file -> (test id used in the output names, what the test contains)
TESTS = {
    "61811011 Test Data.txt": ("udds_cold",
                               "cold-start UDDS, ~10 min engine-off soak, hot UDDS"),
    "61811012 Test Data.txt": ("udds_hot", "hot-start UDDS"),
    "61811013 Test Data.txt": ("hwfet", "two HWFETs back to back (warm-up + test)"),
    "61811014 Test Data.txt": ("us06", "two US06 back to back"),
}

RENAME = {
    "Time[s]": "time_s",
    "Dyno_Spd[mph]": "vehicle_speed_mph",
    "Eng_FuelFlow_Direct_DI[ccps]": "fuel_rate_cc_per_s",
}

# EPA 2022 Test Car List row used for the EPA numbers (see PROVENANCE.md for the choice).
EPA_TEST_VEHICLE_ID = "18-AV3A"
EPA_CONFIGURATION = 1

# Values not in the EPA file (sources in PROVENANCE.md).
TRANSMISSION_GEAR_RATIOS = (5.519, 3.184, 2.050, 1.492, 1.235, 1.000, 0.801, 0.673)  # UA80E
PEAK_TORQUE_LBFT = 184.0      # A25A-FKS, Toyota 2018 Camry LE/SE/XLE specification
RATED_SPEED_RPM = 6600.0      # rpm at rated power, same specification
TIRE_SIZE = "235/45R18"       # 2018 Camry XLE (4-cylinder) original-equipment size
ANNUAL_MILES = 10000.0        # placeholder: a single test car has no fleet mileage


def epa_row() -> dict:
    """The EPA target coefficients etc. of the chosen test vehicle/configuration."""
    epa = pd.read_csv(EPA_FILE, encoding="utf-8-sig")
    rows = epa[(epa["Test Vehicle ID"] == EPA_TEST_VEHICLE_ID)
               & (epa["Test Veh Configuration #"] == EPA_CONFIGURATION)]
    cols = ["Represented Test Veh Make", "Represented Test Veh Model", "Test Veh Displacement (L)",
            "Rated Horsepower", "# of Gears", "Drive System Code", "Tested Transmission Type",
            "Equivalent Test Weight (lbs.)", "Axle Ratio", "Target Coef A (lbf)",
            "Target Coef B (lbf/mph)", "Target Coef C (lbf/mph**2)", "Test Fuel Type Description"]
    distinct = rows[cols].drop_duplicates()
    if len(distinct) != 1:
        raise SystemExit(f"expected one distinct EPA row for {EPA_TEST_VEHICLE_ID} "
                         f"config {EPA_CONFIGURATION}, found {len(distinct)}")
    r = distinct.iloc[0].to_dict()
    assert r["Drive System Code"] == "F" and r["# of Gears"] == 8, r
    return r


def sidecar(test: str, r: dict) -> dict:
    """One Vehicles row (docs/interface.md, 'Fleet workbook') for this car."""
    return {
        "vehicle_id": f"camry2018_{test}",
        "vehicle_class": "midsize sedan",
        "duty_class": "LD",
        "configuration": "LD_FWD",
        "count": 1,
        "annual_miles": ANNUAL_MILES,
        "fuel": "gasoline",
        "peak_engine_torque_Nm": round(PEAK_TORQUE_LBFT * LBFT_TO_NM, 1),
        "transmission": "automatic",
        "transmission_gear_ratios": ",".join(f"{g:.3f}" for g in TRANSMISSION_GEAR_RATIOS),
        "final_drive_ratio": float(r["Axle Ratio"]),
        "test_weight_kg": round(float(r["Equivalent Test Weight (lbs.)"]) * LB_TO_KG, 2),
        "coastdown_A_lbf": float(r["Target Coef A (lbf)"]),
        "coastdown_B_lbf_per_mph": float(r["Target Coef B (lbf/mph)"]),
        "coastdown_C_lbf_per_mph2": float(r["Target Coef C (lbf/mph**2)"]),
        "tire_size": TIRE_SIZE,
        "rated_power_kW": round(float(r["Rated Horsepower"]) * HP_TO_KW, 1),
        "rated_speed_rpm": RATED_SPEED_RPM,
        "engine_displacement_L": float(r["Test Veh Displacement (L)"]),
    }


def _toml_value(v) -> str:
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    return repr(float(v))


def write_toml(path: Path, data: dict, comment: str) -> None:
    lines = [f"# {line}" for line in comment.splitlines()]
    lines += [f"{k} = {_toml_value(v)}" for k, v in data.items()]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def main() -> None:
    r = epa_row()
    for src, (test, what) in TESTS.items():
        raw = pd.read_csv(HERE / src)
        if sorted(raw.columns) != sorted(RENAME):
            raise SystemExit(f"{src}: unexpected columns {list(raw.columns)}")
        out = raw.rename(columns=RENAME)[list(RENAME.values())]
        out["time_s"] = out["time_s"] + 0.0  # -0.0 -> 0.0
        out.to_csv(HERE / f"camry2018_{test}.csv", index=False, lineterminator="\n")
        write_toml(
            HERE / f"camry2018_{test}.toml", sidecar(test, r),
            f"2018 Toyota Camry XLE 2.5 L, Argonne test {src.split()[0]}: {what}.\n"
            f"Written by inputs/dyno/convert.py; sources in inputs/dyno/PROVENANCE.md.\n"
            f"EPA numbers: 2022 Test Car List, {r['Represented Test Veh Model']} "
            f"{EPA_TEST_VEHICLE_ID} configuration {EPA_CONFIGURATION}.")


if __name__ == "__main__":
    main()
