"""fleetrun diagnose-fleet (issue 11 item 4): physics hidden in a whole fleet's test results.

Unit checks build a fleet problem with a known pattern (the selection's logic, no simulation);
the EPA 2022 Test Car List (inputs/epa, via `fleetrun import-epa`) is the real case: the cold
start is found in FTP bag 1 and not in bag 3 or the highway test, and the FTP composite's
error on held-out manufacturers falls.
"""
import json

import numpy as np
import pytest
from click.testing import CliRunner

from fleetrun.cli import cli
from fleetrun.diagnose.fleet import (TESTS, FleetProblem, FleetSettings, analyse_fleet,
                                     manufacturer_folds, read_measured)
from fleetrun.errors import InputError
from fleetrun.resources import inputs_dir


def _problem(seed, share=0.0, noise=0.03, n_vehicles=120, makers=12):
    """Residuals ln(measured / simulated fuel per mile) with a cold start of ``share`` of bag
    1's fuel (and its 0.43-weighted part of the FTP composite), a maker-level offset and noise."""
    rng = np.random.default_rng(seed)
    vehicle = np.repeat(np.arange(n_vehicles), len(TESTS))
    test = np.tile(np.array(TESTS, dtype=object), n_vehicles)
    maker = np.array([f"m{v % makers}" for v in vehicle], dtype=object)
    warm = np.where(test == "FTP:bag1", 1.0, np.where(test == "FTP", 0.2, 0.0))
    accessory = rng.uniform(0.01, 0.03, n_vehicles)[vehicle] * np.where(test == "HWFET", 0.5, 1.0)
    cyl = -np.where(rng.random(n_vehicles) < 0.4, 1.0, 0.0)[vehicle] * np.where(test == "HWFET", 0.6, 0.2)
    offset = rng.normal(0, 0.02, makers)[np.array([int(m[1:]) for m in maker])]
    r = 0.03 + share * warm + offset + rng.normal(0, noise, len(vehicle))
    props = {"specific_power_W_per_kg": rng.uniform(50, 150, n_vehicles),
             "engine_displacement_L": rng.uniform(1.5, 5.0, n_vehicles),
             "drive": rng.choice(np.array(["LD_FWD", "LD_RWD"], dtype=object), n_vehicles),
             "transmission": rng.choice(np.array(["automatic", "cvt"], dtype=object), n_vehicles),
             "test_weight_kg": rng.uniform(1300, 2600, n_vehicles), "cylinders": rng.choice([4.0, 6.0, 8.0], n_vehicles)}
    cols = {"warmup": warm, "accessory_load": accessory, "cylinder_deactivation": cyl}
    return FleetProblem([f"v{i}" for i in range(n_vehicles)], vehicle, test, maker, r, r - share * warm,
                        cols, {}, props)


def test_cold_start_pattern_is_found_in_bag1_with_its_share():
    res = analyse_fleet(_problem(1, share=0.12), FleetSettings(n_perm=50))
    assert [f["effect"] for f in res["findings"]] == ["warmup"]
    f = res["findings"][0]
    assert f["parameters"]["bag1_extra_share"] == pytest.approx(0.12, abs=0.01)
    assert f["tests"] == ["FTP:bag1", "FTP"]           # not bag 3, HWFET or US06
    assert f["by_test"]["FTP"]["heldout_mae_after"] < f["by_test"]["FTP"]["heldout_mae_before"]
    assert res["schema"] == "fleetrun.fleet-diagnosis/1"
    assert {c["effect"]: c["status"] for c in res["candidates"]}["accessory_load"] == "rejected"


def test_no_pattern_no_finding_and_nothing_unexplained():
    res = analyse_fleet(_problem(2, share=0.0), FleetSettings(n_perm=50))
    assert res["findings"] == []
    assert res["unexplained"]["tests"] == []
    assert not any(d["significant"] for d in res["unexplained"]["drivers"])


def test_folds_hold_out_whole_manufacturers():
    makers = np.array(["a"] * 50 + ["b"] * 30 + ["c"] * 20 + ["d"] * 20 + ["e"] * 5 + ["f"] * 5, dtype=object)
    folds = manufacturer_folds(makers, 3)
    for m in np.unique(makers):
        assert len(set(folds[makers == m])) == 1
    assert sorted(np.bincount(folds)) == [40, 40, 50]     # largest first, to the lightest fold


def test_measured_csv_errors_name_row_and_column(tmp_path):
    p = tmp_path / "m.csv"
    p.write_text("vehicle_id,test,mpg,manufacturer\nv1,FTP,30,x\nv1,LA92,30,x\n")
    with pytest.raises(InputError, match="unknown test 'LA92'") as e:
        read_measured(p, ["v1"])
    assert e.value.row == 3 and e.value.column == "test"
    p.write_text("vehicle_id,test,mpg,manufacturer\nv2,FTP,30,x\n")
    with pytest.raises(InputError, match="'v2' is not in the fleet workbook"):
        read_measured(p, ["v1"])
    p.write_text("vehicle_id,test,mpg,manufacturer\nv1,FTP,-3,x\n")
    with pytest.raises(InputError, match="positive number"):
        read_measured(p, ["v1"])


@pytest.fixture(scope="module")
def epa(tmp_path_factory):
    """The whole EPA 2022 Test Car List through import-epa and diagnose-fleet."""
    d = tmp_path_factory.mktemp("epa")
    runner = CliRunner()
    res = runner.invoke(cli, ["import-epa", str(inputs_dir() / "epa" / "22-tstcar.csv"), "-o",
                              str(d / "fleet.xlsx"), "--measured-out", str(d / "measured.csv")])
    assert res.exit_code == 0, res.output
    res = runner.invoke(cli, ["diagnose-fleet", str(d / "fleet.xlsx"), "--measured", str(d / "measured.csv"),
                              "--out", str(d / "out")])
    assert res.exit_code == 0, res.output
    return json.loads((d / "out" / "diagnosis.json").read_text()), res.output, d


@pytest.mark.slow
def test_epa_list_cold_start_in_bag1_not_bag3_or_highway(epa):
    doc, output, d = epa
    assert doc["schema"] == "fleetrun.fleet-diagnosis/1" and doc["vehicles"] > 900
    f = doc["findings"][0]
    assert f["effect"] == "warmup" and "FTP:bag1" in f["tests"]
    assert not {"FTP:bag3", "HWFET"} & set(f["tests"])
    assert 0.05 < f["parameters"]["bag1_extra_share"] < 0.3
    ftp = f["by_test"]["FTP"]
    assert ftp["heldout_mae_after"] < ftp["heldout_mae_before"]   # held-out manufacturers
    assert "finding: warmup" in output
    assert (d / "out" / "diagnosis.html").read_text().count("data:image/png;base64,") >= 1
    assert {"significant", "tests", "drivers"} <= set(doc["unexplained"])
    assert all({"property", "strength"} <= set(x) for x in doc["unexplained"]["drivers"])


def test_cli_bad_measured_file_is_one_error_line(tmp_path):
    p = tmp_path / "m.csv"
    p.write_text("vehicle_id,test,mpg,manufacturer\nno_such_vehicle,FTP,30,x\n")
    res = CliRunner().invoke(cli, ["diagnose-fleet", str(inputs_dir() / "example_fleet.xlsx"),
                                   "--measured", str(p), "--out", str(tmp_path / "o")])
    assert res.exit_code == 1
    assert res.output.startswith("Error:") and "m.csv: row 2, column vehicle_id" in res.output
    assert "Traceback" not in res.output and not (tmp_path / "o").exists()
