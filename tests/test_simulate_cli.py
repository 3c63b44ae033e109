"""``fleetrun simulate`` (docs/interface.md): JSON line, trace CSV, and errors without tracebacks."""
from __future__ import annotations

import json
import subprocess
import sys

import pandas as pd
import pytest
from click.testing import CliRunner

from fleetrun.cli import cli
from fleetrun.resources import inputs_dir

CAMRY_TOML = inputs_dir() / "dyno" / "camry2018_udds_hot.toml"
FLEET = inputs_dir() / "example_fleet.xlsx"
TRACE = ("time_s", "vehicle_speed_mps", "wheel_torque_Nm", "diff_input_torque_Nm", "diff_input_speed_rpm",
         "diff_efficiency", "gear", "engine_speed_rpm", "engine_torque_Nm", "fuel_rate_g_per_s")


def run(*args):
    return CliRunner().invoke(cli, ["simulate", *map(str, args)], catch_exceptions=False)


def test_workbook_vehicle_json_and_trace(tmp_path):
    out = tmp_path / "trace.csv"
    r = run(FLEET, "--vehicle", "LD-CAMRY-25", "--cycle", "UDDS", "--scenario", "hot_summer", "--mode", "direct",
            "-o", out)
    assert r.exit_code == 0, r.output
    summary = json.loads(r.stdout.strip().splitlines()[-1])
    for key in ("miles", "fuel_gal", "mpg", "diff_efficiency", "drivetrain_efficiency"):
        assert isinstance(summary[key], float)
    assert summary["ambient_temp_C"] == 38.0
    assert summary["mpg"] == pytest.approx(summary["miles"] / summary["fuel_gal"])
    trace = pd.read_csv(out)
    assert list(trace.columns[:len(TRACE)]) == list(TRACE)
    assert len(trace) == 1370
    # the trace integrates to the summary: fuel (1 s steps) and distance
    assert trace.fuel_rate_g_per_s.iloc[1:].sum() == pytest.approx(summary["fuel_g"], rel=1e-5)


def test_vehicle_file_and_all_modes_agree():
    mpg = {}
    for mode in ("direct", "map2d", "map3d"):
        r = run("--vehicle-file", CAMRY_TOML, "--cycle", "HWFET", "--mode", mode)
        assert r.exit_code == 0, r.output
        mpg[mode] = json.loads(r.stdout)["mpg"]
    assert mpg["map2d"] == pytest.approx(mpg["direct"], rel=0.002)
    assert mpg["map3d"] == pytest.approx(mpg["direct"], rel=0.002)


def test_user_cycle_csv_with_grade(tmp_path):
    csv = tmp_path / "hill.csv"
    rows = ["time_s,speed_mps,grade_pct"] + [f"{t},{min(t, 15)},{3.0 if t > 20 else 0.0}" for t in range(0, 60)]
    csv.write_text("\n".join(rows) + "\n")
    flat = tmp_path / "flat.csv"
    flat.write_text("\n".join(r.rsplit(",", 1)[0] for r in rows) + "\n")
    up = json.loads(run("--vehicle-file", CAMRY_TOML, "--cycle", csv).stdout)
    level = json.loads(run("--vehicle-file", CAMRY_TOML, "--cycle", flat).stdout)
    assert up["fuel_g"] > 1.3 * level["fuel_g"]


def _error(result, *words):
    assert result.exit_code == 1, result.output
    err = result.stderr.strip()
    assert err.startswith("Error:") and len(err.splitlines()) == 1, err
    assert "Traceback" not in result.output
    for w in words:
        assert w in err, err


def test_unknown_cycle():
    _error(run("--vehicle-file", CAMRY_TOML, "--cycle", "UDDX"), "UDDX", "UDDS")


def test_non_monotonic_time(tmp_path):
    csv = tmp_path / "back.csv"
    csv.write_text("time_s,speed_mps\n0,0\n1,2\n3,4\n2,3\n4,0\n")
    _error(run("--vehicle-file", CAMRY_TOML, "--cycle", csv), "time_s")


def test_negative_speed(tmp_path):
    csv = tmp_path / "neg.csv"
    csv.write_text("time_s,speed_mps\n0,0\n1,2\n2,-3\n3,0\n")
    _error(run("--vehicle-file", CAMRY_TOML, "--cycle", csv), "negative")


def _toml_with(tmp_path, key, value):
    text = CAMRY_TOML.read_text()
    lines = [f'{key} = "{value}"' if line.startswith(f"{key} =") else line for line in text.splitlines()]
    path = tmp_path / "v.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_tyre_size_that_does_not_parse(tmp_path):
    _error(run("--vehicle-file", _toml_with(tmp_path, "tire_size", "banana"), "--cycle", "UDDS"),
           "tire_size", "banana")


def test_empty_gear_list(tmp_path):
    _error(run("--vehicle-file", _toml_with(tmp_path, "transmission_gear_ratios", ""), "--cycle", "UDDS"),
           "transmission_gear_ratios", "empty")


def test_unknown_vehicle_and_scenario():
    _error(run(FLEET, "--vehicle", "NOPE", "--cycle", "UDDS"), "NOPE", "example_fleet.xlsx")
    _error(run(FLEET, "--vehicle", "LD-CAMRY-25", "--cycle", "UDDS", "--scenario", "nope"), "nope")


def test_missing_vehicle_file(tmp_path):
    _error(run("--vehicle-file", tmp_path / "none.toml", "--cycle", "UDDS"), "not found")


def test_usage_errors_exit_2():
    assert run("--cycle", "UDDS").exit_code == 2
    assert run(FLEET, "--cycle", "UDDS").exit_code == 2


def test_console_entry_point_no_traceback(tmp_path):
    p = subprocess.run([sys.executable, "-m", "fleetrun", "simulate", "--vehicle-file", str(CAMRY_TOML),
                        "--cycle", "NOPE"], capture_output=True, text=True)
    assert p.returncode == 1 and p.stderr.startswith("Error:") and "Traceback" not in p.stderr
