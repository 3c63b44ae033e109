"""``fleetrun import-epa``: EPA Test Car List -> fleet workbook + measured results.

Synthetic excerpts (a handful of rows in the list's own header) check each rule; the real
2022 list (inputs/epa/22-tstcar.csv) is checked against an independent pandas count of the
documented exclusion rules and against published figures.
"""
from __future__ import annotations

import json
import math
import re

import pandas as pd
import pytest
from click.testing import CliRunner

from fleetrun.cli import cli
from fleetrun.epa import import_test_car_list, rules
from fleetrun.workbook import read_fleet
from fleetrun.resources import inputs_dir

REAL = inputs_dir() / "epa" / "22-tstcar.csv"
HEADER = list(pd.read_csv(REAL, encoding="utf-8-sig", nrows=0).columns)
FTP = "Federal fuel 2-day exhaust (w/can load)"
GASOLINE = "Tier 2 Cert Gasoline"


def epa_row(**overrides) -> dict:
    """One test row of a conventional 2.5 L, 8-speed front-drive car (the 2022 Camry's values)."""
    row = dict.fromkeys(HEADER, "")
    row.update({
        "Model Year": 2022, "Vehicle Manufacturer Name": "Toyota", "Represented Test Veh Make": "TOYOTA",
        "Represented Test Veh Model": "CAMRY XLE/XSE", "Test Vehicle ID": "18-AV3A", "Test Veh Configuration #": 1,
        "Test Veh Displacement (L)": 2.487, "Vehicle Type": "Car", "Rated Horsepower": 203,
        "# of Cylinders and Rotors": 4, "Tested Transmission Type Code": "SA", "# of Gears": 8,
        "Transmission Lockup?": "Y", "Drive System Code": "F", "Equivalent Test Weight (lbs.)": 3625,
        "Axle Ratio": 2.8, "N/V Ratio": 24.7, "Test Procedure Description": FTP,
        "Test Fuel Type Description": GASOLINE, "RND_ADJ_FE": 36.0, "FE_UNIT": "MPG",
        "FE Bag 1": 31.0, "FE Bag 2": 35.0, "FE Bag 3": 42.0, "Test Number": "T1",
        "Target Coef A (lbf)": 25.4, "Target Coef B (lbf/mph)": 0.234, "Target Coef C (lbf/mph**2)": 0.0158,
    })
    row.update(overrides)
    return row


def write_list(path, rows):
    pd.DataFrame(rows, columns=HEADER).to_csv(path, index=False, encoding="utf-8-sig")
    return path


def invoke(*args):
    return CliRunner().invoke(cli, ["import-epa", *map(str, args)])


@pytest.fixture
def excerpt(tmp_path):
    """One modelled car with two FTP rows, a HWFE and a placeholder US06, plus one vehicle per
    exclusion rule and an E85 test of the modelled car."""
    rows = [
        epa_row(),
        epa_row(**{"RND_ADJ_FE": 40.0, "FE Bag 1": 33.0, "FE Bag 2": 38.0, "FE Bag 3": 45.0, "Test Number": "T2",
                   "Test Procedure Description": "Federal fuel 3-day exhaust"}),
        epa_row(**{"Test Procedure Description": "HWFE", "RND_ADJ_FE": 52.0, "FE Bag 1": "", "FE Bag 2": "",
                   "FE Bag 3": "", "Test Number": "T3"}),
        epa_row(**{"Test Procedure Description": "US06", "RND_ADJ_FE": 10000.0, "Test Number": "T4"}),
        epa_row(**{"Test Procedure Description": "Cold CO", "RND_ADJ_FE": 20.0,
                   "Test Fuel Type Description": "Cold CO Regular (Tier 2)"}),
        epa_row(**{"Test Fuel Type Description": "E85 (85% Ethanol 15% EPA Unleaded Gasoline)", "RND_ADJ_FE": 27.0}),
        # a CVT car: modelled
        epa_row(**{"Test Vehicle ID": "CVT1", "Test Veh Configuration #": 0, "Tested Transmission Type Code": "CVT",
                   "# of Gears": 1, "N/V Ratio": 30.0, "Axle Ratio": 4.0}),
        # an electric vehicle and a plug-in (charge-depleting test on the same test vehicle)
        epa_row(**{"Test Vehicle ID": "EV1", "Test Fuel Type Description": "Electricity",
                   "Test Procedure Description": "Charge Depleting UDDS"}),
        epa_row(**{"Test Vehicle ID": "PH1", "Test Veh Configuration #": 0,
                   "Test Procedure Description": "Charge Depleting UDDS"}),
        epa_row(**{"Test Vehicle ID": "PH1", "Test Veh Configuration #": 1}),
        # hybrid by name; hybrid by signature (city economy as good as highway)
        epa_row(**{"Test Vehicle ID": "HY1", "Represented Test Veh Model": "CAMRY HYBRID LE"}),
        epa_row(**{"Test Vehicle ID": "HS1", "RND_ADJ_FE": 50.0}),
        epa_row(**{"Test Vehicle ID": "HS1", "Test Procedure Description": "HWFE", "RND_ADJ_FE": 52.0}),
        # unsupported fuel only; missing axle ratio; N/V placeholder; transmission "Other"; 4 gears
        epa_row(**{"Test Vehicle ID": "E85", "Test Fuel Type Description": "E85 (85% Ethanol 15% EPA Unleaded Gasoline)"}),
        epa_row(**{"Test Vehicle ID": "AX0", "Axle Ratio": ""}),
        epa_row(**{"Test Vehicle ID": "NV0", "N/V Ratio": 999.9}),
        epa_row(**{"Test Vehicle ID": "OT1", "Tested Transmission Type Code": "OT"}),
        epa_row(**{"Test Vehicle ID": "G4", "# of Gears": 4}),
    ]
    return write_list(tmp_path / "excerpt.csv", rows)


def by_id(rows):
    return {r["vehicle_id"]: r for r in rows}


def test_excerpt_every_configuration_modelled_or_excluded_with_its_reason(excerpt):
    result = import_test_car_list(excerpt)
    assert [v["vehicle_id"] for v in result.vehicles] == ["18-AV3A_c1", "CVT1_c0"]
    reasons = {k: v["reason"] for k, v in by_id(result.excluded).items()}
    expected = {"EV1_c1": "electric vehicle", "PH1_c0": "plug-in hybrid", "PH1_c1": "plug-in hybrid",
                "HY1_c1": "hybrid (model name 'CAMRY HYBRID LE'", "HS1_c1": "hybrid signature",
                "E85_c1": "unsupported fuel (E85", "AX0_c1": "Axle Ratio is missing",
                "NV0_c1": "N/V Ratio 999.9 rpm/mph is outside", "OT1_c1": "transmission type code 'OT'",
                "G4_c1": "no generic gear set for 4 gears"}
    assert set(reasons) == set(expected)
    for vehicle_id, start in expected.items():
        assert reasons[vehicle_id].startswith(start), reasons[vehicle_id]


def test_excerpt_duplicate_tests_are_combined_by_harmonic_mean(excerpt):
    """Two FTP rows (36 and 40 mpg) give the mpg of equal distances at each: 2/(1/36+1/40);
    the 10000 US06 placeholder, the cold-CO test and the E85 test are not results."""
    measured = [m for m in import_test_car_list(excerpt).measured if m["vehicle_id"] == "18-AV3A_c1"]
    tests = {m["test"]: m for m in measured}
    assert set(tests) == {"FTP", "FTP:bag1", "FTP:bag2", "FTP:bag3", "HWFET"}
    assert tests["FTP"]["mpg"] == pytest.approx(2 / (1 / 36 + 1 / 40), abs=1e-4)
    assert tests["FTP"]["n_tests"] == 2 and tests["FTP"]["test_numbers"] == "T1;T2"
    assert tests["FTP:bag1"]["mpg"] == pytest.approx(2 / (1 / 31 + 1 / 33), abs=1e-4)
    assert tests["HWFET"]["mpg"] == 52.0 and tests["HWFET"]["n_tests"] == 1


def test_analytically_derived_values_are_not_measurements(tmp_path):
    """An analytically derived row (EPA's estimate for the configuration of its ADFE columns,
    here a lighter one at 38 mpg) is not averaged into the tested vehicle's 36 mpg; a
    configuration with only derived values is modelled but has no measured result."""
    rows = [epa_row(), epa_row(**{"RND_ADJ_FE": 38.0, "Test Number": "T9", "Analytically Derived FE?": "Yes",
                                  "ADFE Equiv. Test Weight (lbs.)": 3500}),
            epa_row(**{"Test Procedure Description": "HWFE", "RND_ADJ_FE": 52.0, "Analytically Derived FE?": "No"}),
            epa_row(**{"Test Vehicle ID": "DERIVED", "Analytically Derived FE?": "Yes"})]
    result = import_test_car_list(write_list(tmp_path / "l.csv", rows))
    tests = {m["test"]: m for m in result.measured if m["vehicle_id"] == "18-AV3A_c1"}
    assert tests["FTP"]["mpg"] == 36.0 and tests["FTP"]["test_numbers"] == "T1"
    assert tests["HWFET"]["mpg"] == 52.0
    assert "DERIVED_c1" in {v["vehicle_id"] for v in result.vehicles}
    assert not [m for m in result.measured if m["vehicle_id"] == "DERIVED_c1"]


def tyre_radius_m(size: str) -> float:
    """Half the nominal diameter of a P-metric size, written out here independently."""
    width, aspect, rim = map(float, re.match(r"P?(\d+)/(\d+)R(\d+)", size).groups())
    return (rim * 25.4 + 2 * width * aspect / 100) / 2000


def test_excerpt_vehicle_row_values_and_rules(excerpt):
    result = import_test_car_list(excerpt)
    car = by_id(result.vehicles)["18-AV3A_c1"]
    assert (car["configuration"], car["fuel"], car["transmission"], car["gearbox_type"]) == \
        ("LD_FWD", "gasoline", "automatic", "automatic")
    assert car["test_weight_kg"] == pytest.approx(3625 * 0.45359237, abs=1e-3)
    assert car["rated_power_kW"] == pytest.approx(203 * 0.7457, rel=1e-4)
    assert (car["converter_lockup"], car["cylinders"], car["model_year"], car["nv_ratio_rpm_per_mph"]) == \
        ("yes", 4, 2022, 24.7)
    # Toyota's published rating of this engine (A25A-FKS, 203 hp): 184 lb-ft = 249 N m; the
    # rule (12.5 bar at 60 kW/L) should land within 3 %
    assert car["peak_engine_torque_Nm"] == pytest.approx(249.0, rel=0.03)
    # the top gear x axle x tyre reproduces EPA's N/V (to the 4-digit rounding of the ratios)
    for vehicle in result.vehicles:
        top = float(vehicle["transmission_gear_ratios"].split(",")[-1])
        nv = top * vehicle["final_drive_ratio"] * 0.44704 * 60 / (2 * math.pi * tyre_radius_m(vehicle["tire_size"]))
        assert nv == pytest.approx(vehicle["nv_ratio_rpm_per_mph"], rel=2e-4)
    eight = [float(x) for x in car["transmission_gear_ratios"].split(",")]
    generic, _ = rules.generic_gear_set(8)
    assert [a / b for a, b in zip(eight, generic)] == pytest.approx([eight[0] / generic[0]] * 8, rel=2e-4)
    cvt = by_id(result.vehicles)["CVT1_c0"]
    ratios = [float(x) for x in cvt["transmission_gear_ratios"].split(",")]
    assert cvt["gearbox_type"] == "cvt" and ratios[0] / ratios[-1] == pytest.approx(2.631 / 0.378, rel=1e-3)
    derived = {(d["vehicle_id"], d["column"]) for d in result.derived}
    for column in ("peak_engine_torque_Nm", "tire_size", "transmission_gear_ratios", "vehicle_class", "annual_miles"):
        assert ("18-AV3A_c1", column) in derived


def test_cli_writes_a_workbook_fleetrun_reads_and_the_measured_csv(excerpt, tmp_path):
    out, measured = tmp_path / "fleet.xlsx", tmp_path / "measured.csv"
    result = invoke(excerpt, "-o", out, "--measured-out", measured)
    assert result.exit_code == 0, result.output
    assert "2 vehicles modelled, 10 excluded" in result.output
    fleet = read_fleet(out)
    assert [v.vehicle_id for v in fleet.vehicles] == ["18-AV3A_c1", "CVT1_c0"]
    assert not [w for w in fleet.warnings if "not a fleetrun column" in w]
    assert fleet.vehicles[0].gearbox_type == "automatic" and fleet.vehicles[1].gearbox_type == "cvt"
    assert fleet.scenarios[0].cycle_mix.keys() >= {"HWFET"}
    sheets = pd.read_excel(out, sheet_name=None, engine="openpyxl")
    assert {"Vehicles", "Scenarios", "Measured", "Derived", "Excluded", "About"} <= set(sheets)
    assert len(sheets["Excluded"]) == 10 and sheets["Excluded"]["reason"].notna().all()
    csv = pd.read_csv(measured)
    assert list(csv.columns[:4]) == ["vehicle_id", "test", "mpg", "manufacturer"]
    assert set(csv["test"]) <= {"FTP", "FTP:bag1", "FTP:bag2", "FTP:bag3", "HWFET", "US06"}
    assert len(csv) == len(sheets["Measured"])


def test_cli_filters_by_make_and_model_year(excerpt, tmp_path):
    result = invoke(excerpt, "-o", tmp_path / "f.xlsx", "--make", "toyota", "--model-year", "2022")
    assert result.exit_code == 0, result.output
    result = invoke(excerpt, "-o", tmp_path / "g.xlsx", "--model-year", "2019")
    assert result.exit_code == 1 and result.stderr.startswith("Error: ")
    assert "no vehicle of the 0 selected rows can be modelled" in result.stderr
    assert not (tmp_path / "g.xlsx").exists()


@pytest.mark.parametrize("case", ["missing", "empty", "header_only", "xlsx", "binary", "other_csv", "absent"])
def test_bad_epa_files_exit_1_naming_file_and_column(case, tmp_path):
    path = tmp_path / f"bad-{case}.csv"
    if case == "missing":
        frame = pd.DataFrame([epa_row()], columns=HEADER).drop(columns=["Axle Ratio", "N/V Ratio"])
        frame.to_csv(path, index=False)
    elif case == "empty":
        path.write_bytes(b"")
    elif case == "header_only":
        write_list(path, [])
    elif case == "xlsx":
        path.write_bytes(b"PK\x03\x04" + b"\x00" * 100)
    elif case == "binary":
        path.write_bytes(bytes(range(256)) * 4)
    elif case == "other_csv":
        path.write_text("time_s,speed_mph\n0,0\n1,2\n")
    out = tmp_path / "fleet.xlsx"
    result = invoke(path, "-o", out)
    assert result.exit_code == 1, result.output
    first = result.stderr.splitlines()[0]
    assert first.startswith("Error: ") and str(path) in first and "Traceback" not in result.stderr
    if case == "missing":
        assert "'Axle Ratio'" in first and "'N/V Ratio'" in first
    if case == "other_csv":
        assert "'Model Year'" in first
    assert not out.exists()


def test_output_must_be_xlsx(excerpt, tmp_path):
    result = invoke(excerpt, "-o", tmp_path / "fleet.csv")
    assert result.exit_code == 1 and "must end in .xlsx" in result.stderr


# --------------------------------------------------------------------------- the real list
def independent_exclusions(frame: pd.DataFrame) -> dict[str, set]:
    """The documented exclusion rules, computed column-wise in pandas (not with the importer's
    per-vehicle loop): vehicle ids excluded by each rule."""
    c = rules.constants()
    frame = frame.assign(vid=frame["Test Vehicle ID"].astype(str) + "_c" + frame["Test Veh Configuration #"].astype(str))
    desc = frame["Test Fuel Type Description"].str.lower()
    electric_tv = set(frame.loc[desc.str.contains("electric|hydrogen") |
                                frame["Test Procedure Description"].str.contains("Charge Depleting"),
                                "Test Vehicle ID"])
    supported = (desc.str.contains("|".join(c["fuels"]["gasoline"] + c["fuels"]["diesel"]))
                 & ~desc.str.contains("|".join(c["fuels"]["unsupported"])))
    names = frame.groupby("vid")["Represented Test Veh Model"].first()
    pattern = "|".join(f"(?:{p})" for p in c["hybrids"]["name_patterns"])
    first = frame[supported].groupby("vid").first()
    axle, nv = first["Axle Ratio"], first["N/V Ratio"]
    out = {
        "electric": set(frame.loc[frame["Test Vehicle ID"].isin(electric_tv), "vid"]),
        "name": set(names[names.str.contains(pattern, case=False, regex=True)].index),
        "fuel": set(frame["vid"]) - set(frame.loc[supported, "vid"]),
        "range": set(first.index[(axle < 1.2) | (axle > 12) | (nv < 10) | (nv > 100)]),
        "transmission": set(first.index[~first["Tested Transmission Type Code"].isin(list(c["transmissions"]))]),
    }
    tests = frame[supported & (frame["RND_ADJ_FE"] < 1000)]
    fe = tests.assign(test=tests["Test Procedure Description"].map(c["procedures"]), inv=1 / tests["RND_ADJ_FE"])
    mean = 1 / fe.groupby(["vid", "test"])["inv"].mean().unstack()
    out["signature"] = set(mean.index[mean["FTP"] >= c["hybrids"]["city_highway_ratio"] * mean["HWFET"]])
    return out


def test_real_list_counts_match_an_independent_pandas_count():
    frame = pd.read_csv(REAL, encoding="utf-8-sig")
    result = import_test_car_list(REAL)
    modelled = {v["vehicle_id"] for v in result.vehicles}
    excluded = {e["vehicle_id"] for e in result.excluded}
    all_ids = set(frame["Test Vehicle ID"].astype(str) + "_c" + frame["Test Veh Configuration #"].astype(str))
    assert not modelled & excluded and modelled | excluded == all_ids      # nothing silently dropped
    rule_sets = independent_exclusions(frame)
    assert excluded == set().union(*rule_sets.values())
    assert len(modelled) == len(all_ids - set().union(*rule_sets.values()))
    # what the 2022 list holds (counted by the pandas rules above, printed for the docs)
    print(json.dumps({"configurations": len(all_ids), "modelled": len(modelled), "excluded": len(excluded),
                      **{k: len(v) for k, v in rule_sets.items()}}))
    assert len(rule_sets["electric"]) >= 100 and len(modelled) >= 900


def test_real_list_cli_then_validate(tmp_path):
    out, measured = tmp_path / "fleet.xlsx", tmp_path / "measured.csv"
    result = invoke(REAL, "-o", out, "--measured-out", measured)
    assert result.exit_code == 0, result.output
    fleet = read_fleet(out)   # raises on any error
    assert len(fleet.vehicles) >= 900
    csv = pd.read_csv(measured)
    ids = {v.vehicle_id for v in fleet.vehicles}
    assert set(csv["vehicle_id"]) <= ids
    both = csv.pivot_table(index="vehicle_id", columns="test", values="mpg")
    assert both[["FTP", "HWFET"]].notna().all(axis=1).mean() > 0.95


def test_imported_powertrain_columns_reach_the_simulation(tmp_path):
    """The agreed optional columns the importer writes (gearbox_type, converter_lockup,
    cylinders) are what the simulation's parameters use, read back from the workbook."""
    from fleetrun.simulation.engine import stroke_m
    from fleetrun.simulation.params import vehicle_arrays

    rows = [epa_row(**{"Test Vehicle ID": "CVT1", "Tested Transmission Type Code": "CVT", "# of Gears": 1,
                       "Transmission Lockup?": "N", "# of Cylinders and Rotors": 6}),
            epa_row(**{"Test Vehicle ID": "DCT1", "Tested Transmission Type Code": "AMS", "# of Gears": 7})]
    out = tmp_path / "fleet.xlsx"
    assert invoke(write_list(tmp_path / "l.csv", rows), "-o", out).exit_code == 0
    cvt, dct = read_fleet(out).vehicles
    arrays = vehicle_arrays([cvt, dct])
    assert arrays.cvt.tolist() == [True, False] and arrays.automatic.tolist() == [True, False]
    assert arrays.has_lockup.tolist() == [False, True]
    assert arrays.stroke_m[0] == pytest.approx(stroke_m(2.487, 6))


def test_other_years_header_spacing_case_and_windows_1252(tmp_path):
    """Lists of other model years differ in header spacing/case and older ones are
    Windows-1252: the same vehicle comes out."""
    frame = pd.DataFrame([epa_row(**{"Model Year": 2019, "Represented Test Veh Model": "CAMRY é"}),
                          epa_row(**{"Model Year": 2019, "Test Procedure Description": "HWFE", "RND_ADJ_FE": 52.0})],
                         columns=HEADER)
    frame.columns = [f" {c.upper()}  " if i % 2 else c.lower() for i, c in enumerate(frame.columns)]
    path = tmp_path / "19-tstcar.csv"
    frame.to_csv(path, index=False, encoding="cp1252")
    result = import_test_car_list(path, model_years=[2019])
    assert [v["vehicle_id"] for v in result.vehicles] == ["18-AV3A_c1"]
    assert result.vehicles[0]["model"] == "CAMRY é" and result.vehicles[0]["model_year"] == 2019
    assert {m["test"] for m in result.measured} >= {"FTP", "HWFET"}
