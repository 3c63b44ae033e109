"""Build ``inputs/example_fleet.xlsx``: a realistic (illustrative) state fleet.

    python inputs/make_example_fleet.py [-o inputs/example_fleet.xlsx]

Light-duty rows come from the EPA 2022 Test Car List (``inputs/epa/22-tstcar.csv``): the FTP
test row of a named test vehicle and configuration gives the equivalent test weight, axle
ratio, target road-load coefficients A/B/C, displacement, rated power and the drive system
(F -> LD_FWD, R -> LD_RWD, A -> LD_AWD, 4 and P -> LD_4WD). The Test Car List has no peak
torque, gear ratios or tyre size: those are the manufacturers' published values for the same
engine/transmission (rounded), listed beside each row below.

Medium and heavy-duty rows are representative vehicles, one or more for every HD
configuration, with engine/transmission data typical of the class and road load from typical
rolling resistance and drag area (A = Crr m g; B = 0.2 % of A per mph; C = rho CdA / 2),
the way EPA's GEM describes heavy vehicles.

Counts and annual miles are plausible for a mid-size US state (about 3.5 million vehicles),
not registration data. Three scenarios: baseline, hot summer, congested urban, each with a
light-duty cycle mix of four cycles, over fiscal years 2027-2028. Medium and heavy trucks drive
the national split of single-unit / combination-truck miles over road categories (FHWA VM-1
2010, ``inputs/state_statistics/vm1_truck_travel.toml``, which also holds the road -> cycle rule).
"""
from __future__ import annotations

import argparse
import tomllib
from pathlib import Path

import openpyxl
import pandas as pd

HERE = Path(__file__).resolve().parent
EPA_CSV = HERE / "epa" / "22-tstcar.csv"
VM1_TRUCK_TRAVEL = HERE / "state_statistics" / "vm1_truck_travel.toml"
FTP = "Federal fuel 2-day exhaust (w/can load)"
LB_TO_KG = 0.45359237
HP_TO_KW = 0.745699872
N_PER_LBF = 4.4482216152605
MPH_TO_MPS = 0.44704
G = 9.80665
RHO_AIR = 1.2

DRIVE = {"F": "LD_FWD", "R": "LD_RWD", "A": "LD_AWD", "4": "LD_4WD", "P": "LD_4WD"}
AUTOMATIC = {"A", "SA", "AM"}

# Published gear sets (first gear first).
TOYOTA_UA80 = "5.250,3.028,1.950,1.456,1.220,1.000,0.808,0.673"
FORD_10R = "4.696,2.985,2.146,1.769,1.520,1.275,1.000,0.854,0.689,0.636"
GM_10L = "4.70,2.99,2.15,1.80,1.52,1.28,1.00,0.85,0.69,0.64"
ZF_8HP = "4.71,3.14,2.10,1.67,1.29,1.00,0.84,0.67"
HONDA_10AT = "5.405,3.439,2.258,1.667,1.273,1.000,0.787,0.634,0.574,0.518"
TOYOTA_6MT = "3.538,2.045,1.333,1.028,0.820,0.673"
FORD_8F = "4.48,2.87,1.84,1.41,1.00,0.74,0.62,0.52"
AISIN_6AT = "3.600,2.090,1.488,1.000,0.687,0.580"
MAZDA_6AT = "3.552,2.022,1.452,1.000,0.708,0.599"
ALLISON_6 = "3.51,1.91,1.43,1.00,0.74,0.64"
FORD_6R140 = "3.97,2.32,1.52,1.15,0.86,0.67"
EATON_10 = "12.8,9.25,6.76,4.90,3.58,2.61,1.89,1.38,1.00,0.73"
DT12 = "14.93,11.67,9.02,7.06,5.57,4.35,3.46,2.70,2.08,1.63,1.27,1.00"

# (EPA test vehicle id, configuration #, our id, class, torque Nm, gear set, tyre, count, miles)
LIGHT_DUTY = [
    ("18-AV2A", 8, "LD-CAMRY-25", "Passenger car", 249, TOYOTA_UA80, "215/55R17", 420_000, 11_800),
    ("20-ME1M", 0, "LD-COROLLA-20-MT", "Passenger car", 205, TOYOTA_6MT, "205/55R16", 60_000, 11_500),
    ("EJB21A", 2, "LD-ACCORD-20T", "Passenger car", 370, HONDA_10AT, "235/40R19", 180_000, 11_800),
    ("J5100017", 1, "LD-MUSTANG-23", "Passenger car", 475, FORD_10R, "235/55R17", 45_000, 9_500),
    ("19-AA4A", 3, "LD-RAV4-FWD", "SUV / crossover", 243, TOYOTA_UA80, "225/65R17", 300_000, 12_200),
    ("LUA00045", 0, "LD-ESCAPE-AWD", "SUV / crossover", 373, FORD_8F, "225/65R17", 150_000, 12_200),
    ("9EBPYTG1-026", 0, "LD-CX5-4WD", "SUV / crossover", 420, MAZDA_6AT, "225/55R19", 50_000, 12_000),
    ("MGB41622", 0, "LD-EXPLORER-23", "SUV / crossover", 420, FORD_10R, "255/65R18", 120_000, 12_800),
    ("L6WKJ2574", 0, "LD-GRAND-CHEROKEE-4X4", "SUV / crossover", 353, ZF_8HP, "265/60R18", 60_000, 12_000),
    ("MKD00017", 0, "LD-F150-35-RWD", "Pickup", 678, FORD_10R, "275/65R18", 250_000, 13_500),
    ("MFD1-3.5-J-952", 0, "LD-F150-35-4X4", "Pickup", 678, FORD_10R, "275/65R18", 200_000, 13_500),
    ("53CPNN1361", 0, "LD-SILVERADO-53", "Pickup", 519, GM_10L, "265/65R18", 220_000, 13_500),
    ("L3DS19531", 0, "LD-RAM1500-57", "Pickup", 556, ZF_8HP, "275/65R18", 150_000, 13_000),
    ("19-GN1A", 0, "LD-TACOMA-35", "Pickup", 359, AISIN_6AT, "265/70R16", 90_000, 12_500),
]


def hd_road_load(mass_kg: float, crr: float, cda_m2: float) -> tuple[float, float, float]:
    """EPA-style target coefficients [lbf, lbf/mph, lbf/mph^2] from Crr and drag area."""
    a = crr * mass_kg * G / N_PER_LBF
    c = 0.5 * RHO_AIR * cda_m2 * MPH_TO_MPS ** 2 / N_PER_LBF
    return round(a, 1), round(0.002 * a, 3), round(c, 4)


# id, class, duty, configuration, fuel, torque, transmission, gears, final drive, low multiplier,
# mass kg, Crr, CdA m2, tyre, count, miles, power kW, rated rpm, displacement L
HEAVY = [
    ("MD-BOX-CLASS6", "Medium truck (class 6)", "MD", "HD_RWD", "diesel", 880, "automatic", ALLISON_6, 5.29,
     None, 9_000, 0.0075, 5.0, "245/70R19.5", 38_000, 22_000, 194, 2400, 6.7),
    ("MD-STEPVAN-GAS", "Medium truck (class 6)", "MD", "HD_RWD", "gasoline", 637, "automatic", FORD_6R140, 4.88,
     None, 7_000, 0.0080, 4.6, "225/70R19.5", 25_000, 15_000, 261, 5500, 7.3),
    ("HD-DUMP-CLASS7-2SPD", "Vocational truck", "HD", "HD_DUAL", "diesel", 1_356, "automatic", ALLISON_6, 5.57,
     1.36, 14_000, 0.0075, 5.5, "11R22.5", 9_000, 18_000, 224, 2200, 9.0),
    ("HD-TRACTOR-LONGHAUL", "Tractor-trailer (class 8)", "HD", "HD_TANDEM", "diesel", 2_508, "manual", EATON_10,
     3.36, None, 30_000, 0.0065, 5.8, "295/75R22.5", 42_000, 95_000, 336, 1800, 14.8),
    ("HD-TRACTOR-REGIONAL", "Tractor-trailer (class 8)", "HD", "HD_TANDEM", "diesel", 2_237, "manual", DT12,
     2.85, None, 28_000, 0.0068, 6.0, "295/75R22.5", 30_000, 60_000, 317, 1625, 12.8),
    ("HD-DUMP-TANDEM-2SPD", "Vocational truck", "HD", "HD_TANDEM_DUAL", "diesel", 2_305, "manual", EATON_10,
     4.63, 1.35, 31_000, 0.0078, 6.5, "11R22.5", 12_000, 30_000, 324, 1800, 12.9),
    ("HD-REFUSE-TAG", "Vocational truck", "HD", "HD_TAG", "diesel", 2_373, "automatic", ALLISON_6, 5.38,
     None, 27_000, 0.0080, 7.0, "315/80R22.5", 6_000, 25_000, 317, 2100, 11.9),
    ("HD-MOTORCOACH-TAG", "Bus", "HD", "HD_TAG", "diesel", 2_305, "automatic", ALLISON_6, 3.58,
     None, 20_000, 0.0065, 6.0, "315/80R22.5", 3_500, 70_000, 317, 1800, 12.8),
    ("HD-MIXER-TAG-2SPD", "Vocational truck", "HD", "HD_TAG_DUAL", "diesel", 2_508, "manual", EATON_10, 4.88,
     1.36, 32_000, 0.0080, 7.0, "11R22.5", 4_500, 20_000, 336, 1800, 14.8),
]


def vm1_truck_mix(vehicle_type: str, path: Path = VM1_TRUCK_TRAVEL) -> str:
    """A cycle mix (shares of miles) from FHWA VM-1 travel of ``vehicle_type`` by road category,
    each category driven on the cycle its ``[cycle_for_road]`` rule names (the file says why).
    Shares are rounded to 4 decimals, the rounding remainder going to the largest."""
    with open(path, "rb") as fh:
        data = tomllib.load(fh)
    miles = data["vehicle_miles_million"][vehicle_type]
    by_cycle: dict[str, float] = {}
    for road, cycle in data["cycle_for_road"].items():
        by_cycle[cycle] = by_cycle.get(cycle, 0.0) + miles[road]
    total = sum(by_cycle.values())
    shares = {cycle: round(m / total, 4) for cycle, m in by_cycle.items()}
    largest = max(shares, key=shares.get)
    shares[largest] = round(shares[largest] + 1.0 - sum(shares.values()), 4)
    return ",".join(f"{cycle}:{share:g}" for cycle, share in shares.items())


# Light-duty vehicles drive cycle_mix. Medium trucks (single-unit) and heavy trucks drive the
# national split of their FHWA vehicle type's miles over road categories (VM-1 2010; the heavy
# class takes the combination trucks', which are 85 % of its miles here), the same in every
# scenario: no published figure says how a hot summer or congestion shifts trucks' roads.
MD_MIX = vm1_truck_mix("single_unit_trucks")
HD_MIX = vm1_truck_mix("combination_trucks")
SCENARIOS = [
    ("baseline", "Average year: mixed urban, highway and aggressive driving at 20 C", 20,
     "UDDS:0.43,HWFET:0.42,US06:0.10,NYCC:0.05", MD_MIX, HD_MIX),
    ("hot_summer", "Hot summer: 38 C ambient (A/C load, warmer axle oil), more highway driving", 38,
     "UDDS:0.38,HWFET:0.44,US06:0.13,NYCC:0.05", MD_MIX, HD_MIX),
    ("congested_urban", "Congested urban growth: more stop-and-go", 25,
     "UDDS:0.45,HWFET:0.20,US06:0.05,NYCC:0.30", MD_MIX, HD_MIX),
]


def light_duty_rows(epa: pd.DataFrame) -> list[dict]:
    rows = []
    ftp = epa[epa["Test Procedure Description"] == FTP]
    for test_id, config_no, vid, vclass, torque, gears, tyre, count, miles in LIGHT_DUTY:
        match = ftp[(ftp["Test Vehicle ID"] == test_id) & (ftp["Test Veh Configuration #"] == config_no)]
        if match.empty:
            raise SystemExit(f"EPA test vehicle {test_id} configuration {config_no} not found in {EPA_CSV}")
        r = match.iloc[0]
        rows.append({
            "vehicle_id": vid, "vehicle_class": vclass, "duty_class": "LD",
            "configuration": DRIVE[r["Drive System Code"]], "count": count, "annual_miles": miles,
            "fuel": "diesel" if "Diesel" in r["Test Fuel Type Description"] else "gasoline",
            "peak_engine_torque_Nm": torque,
            "transmission": "automatic" if r["Tested Transmission Type Code"] in AUTOMATIC else "manual",
            "transmission_gear_ratios": gears, "final_drive_ratio": float(r["Axle Ratio"]),
            "test_weight_kg": round(float(r["Equivalent Test Weight (lbs.)"]) * LB_TO_KG, 1),
            "coastdown_A_lbf": float(r["Target Coef A (lbf)"]),
            "coastdown_B_lbf_per_mph": float(r["Target Coef B (lbf/mph)"]),
            "coastdown_C_lbf_per_mph2": float(r["Target Coef C (lbf/mph**2)"]),
            "tire_size": tyre,
            "rated_power_kW": round(float(r["Rated Horsepower"]) * HP_TO_KW, 1),
            "engine_displacement_L": float(r["Test Veh Displacement (L)"]),
            "_source": f"EPA 2022 Test Car List: {r['Represented Test Veh Make']} "
                       f"{r['Represented Test Veh Model']}, test vehicle {test_id} config {config_no}, "
                       f"FTP test {r['Test Number']}",
        })
    return rows


def heavy_rows() -> list[dict]:
    rows = []
    for (vid, vclass, duty, config, fuel, torque, trans, gears, fdr, low, mass, crr, cda, tyre, count,
         miles, power, rpm, disp) in HEAVY:
        a, b, c = hd_road_load(mass, crr, cda)
        rows.append({
            "vehicle_id": vid, "vehicle_class": vclass, "duty_class": duty, "configuration": config,
            "count": count, "annual_miles": miles, "fuel": fuel, "peak_engine_torque_Nm": torque,
            "transmission": trans, "transmission_gear_ratios": gears, "final_drive_ratio": fdr,
            "low_gear_ratio": low, "test_weight_kg": mass, "coastdown_A_lbf": a,
            "coastdown_B_lbf_per_mph": b, "coastdown_C_lbf_per_mph2": c, "tire_size": tyre,
            "rated_power_kW": power, "rated_speed_rpm": rpm, "engine_displacement_L": disp,
            "_source": f"representative {vclass.lower()}: Crr {crr}, CdA {cda} m2, {mass} kg",
        })
    return rows


def build(output: Path) -> Path:
    from fleetrun.fileio import atomic_file
    from fleetrun.workbook.schema import SCENARIO_COLUMNS, VEHICLE_COLUMNS
    import tempfile

    from fleetrun.workbook.template import write_template

    epa = pd.read_csv(EPA_CSV, encoding="utf-8-sig", low_memory=False)
    vehicles = light_duty_rows(epa) + heavy_rows()
    with tempfile.TemporaryDirectory() as folder:   # the template (XlsxWriter), filled in with openpyxl
        template = Path(folder) / "template.xlsx"
        write_template(template)
        wb = openpyxl.load_workbook(template)
    for sheet, columns, rows in (
            ("Vehicles", VEHICLE_COLUMNS, vehicles),
            ("Scenarios", SCENARIO_COLUMNS, [
                {"scenario_id": sid, "description": text, "ambient_temp_C": temp, "cycle_mix": mix,
                 "cycle_mix_MD": mix_md, "cycle_mix_HD": mix_hd,
                 "budget_years": 2, "vmt_growth_pct_per_year": 1.2, "first_fiscal_year": 2027,
                 "state_tax_gasoline_usd_per_gal": 0.20, "state_tax_diesel_usd_per_gal": 0.20,
                 "federal_tax_gasoline_usd_per_gal": 0.184, "federal_tax_diesel_usd_per_gal": 0.244}
                for sid, text, temp, mix, mix_md, mix_hd in SCENARIOS])):
        ws = wb[sheet]
        ws.delete_rows(2, ws.max_row)
        names = [c.name for c in columns]
        for r, row in enumerate(rows, start=2):
            for key, value in row.items():
                if key.startswith("_") or value is None:
                    continue
                ws.cell(row=r, column=names.index(key) + 1, value=value)
    sources = wb.create_sheet("Sources")
    sources.append(["vehicle_id", "source"])
    for row in vehicles:
        sources.append([row["vehicle_id"], row["_source"]])
    sources.append([])
    sources.append(["note", "Counts and annual miles are illustrative for a mid-size state; "
                            "torque, gear ratios and tyres are published values (see make_example_fleet.py)."])
    sources.column_dimensions["A"].width = 26
    sources.column_dimensions["B"].width = 110
    with atomic_file(output) as temporary:
        wb.save(temporary)
    return output


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, default=HERE / "example_fleet.xlsx")
    args = parser.parse_args()
    path = build(args.output)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
