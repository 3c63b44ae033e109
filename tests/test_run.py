"""``fleetrun run``: outputs, reconciliation, atomic writes, batch config and exit codes.

These use a deterministic stand-in for the simulation (test_fleet_fakes.fake_simulate) so they
test the runner's bookkeeping quickly; test_run_real.py runs the real simulation.
"""
from __future__ import annotations

import json
import math
import os

import pandas as pd
import pytest
from click.testing import CliRunner

import test_fleet_fakes as fakes
from fleetrun.cli import cli
from fleetrun.run import runner
from test_fleet_fakes import read_csv, scenario, small_fleet, vehicle, write_fleet

OUTPUTS = {"report.xlsx", "summary.html", "results.csv", "results.parquet", "class_summary.csv", "fiscal_summary.csv",
           "revenue_memo.csv", "fiscal_periods.csv", "manifest.json"}
RESULTS_DOCUMENTED = ["scenario_id", "vehicle_id", "vehicle_class", "configuration", "fuel", "count",
                    "miles_total", "fuel_gal_total", "mpg", "diff_efficiency", "drivetrain_efficiency",
                    "state_tax_usd", "federal_tax_usd"]
CLASS_DOCUMENTED = ["scenario_id", "vehicle_class", "vehicles", "miles_total", "fuel_gal_total", "mpg",
                  "diff_efficiency", "state_tax_usd", "federal_tax_usd"]


@pytest.fixture(autouse=True)
def fake_simulation():
    fakes.CALLS.clear()


def run(*args, **injected):
    return fakes.invoke_run(*args, **injected)


@pytest.fixture
def fleet_path(tmp_path):
    return small_fleet(tmp_path / "fleet.xlsx")


def test_run_writes_six_outputs(fleet_path, tmp_path):
    out = tmp_path / "out"
    result = run(fleet_path, "--out", out, "--no-cache", "-q")
    assert result.exit_code == 0, result.stderr
    assert {p.name for p in out.iterdir()} == OUTPUTS
    results = read_csv(out / "results.csv", keep_default_na=False)
    classes = read_csv(out / "class_summary.csv", keep_default_na=False)
    assert list(results.columns[:13]) == RESULTS_DOCUMENTED
    assert list(classes.columns[:9]) == CLASS_DOCUMENTED
    assert len(results) == 3 * 4 and len(classes) == 3 * 3
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["fleetrun_version"] and manifest["physics"] == "thesis"
    assert manifest["inputs"][0]["sha256"] == __import__("hashlib").sha256(fleet_path.read_bytes()).hexdigest()
    assert set(manifest["outputs"]) == OUTPUTS - {"manifest.json"}
    assert "simulate" in manifest["timings_s"] and isinstance(manifest["warnings"], list)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out-staging")]


def test_totals_reconcile_exactly(fleet_path, tmp_path):
    out = tmp_path / "out"
    assert run(fleet_path, "--out", out, "--no-cache", "-q").exit_code == 0
    results = read_csv(out / "results.csv")
    classes = read_csv(out / "class_summary.csv")
    rates = {"baseline": (0.2, 0.2, 0.184, 0.244), "hot": (0.2, 0.2, 0.184, 0.244),
             "urban": (0.2, 0.2, 0.184, 0.244)}
    for row in results.itertuples():
        state_g, state_d, fed_g, fed_d = rates[row.scenario_id]
        gasoline = row.fuel == "gasoline"
        assert row.state_tax_usd == row.fuel_gal_total * (state_g if gasoline else state_d)
        assert row.federal_tax_usd == row.fuel_gal_total * (fed_g if gasoline else fed_d)
        assert row.mpg == row.miles_total / row.fuel_gal_total
        assert row.diff_efficiency == row.diff_output_energy_J / row.diff_input_energy_J
        assert row.drivetrain_efficiency == row.wheel_energy_J / row.drivetrain_input_energy_J
    for row in classes.itertuples():
        group = results[(results.scenario_id == row.scenario_id) & (results.vehicle_class == row.vehicle_class)]
        for column, total in (("count", row.vehicles), ("miles_total", row.miles_total),
                              ("fuel_gal_total", row.fuel_gal_total), ("state_tax_usd", row.state_tax_usd),
                              ("federal_tax_usd", row.federal_tax_usd)):
            assert math.fsum(group[column]) == total, column
        assert row.mpg == row.miles_total / row.fuel_gal_total
        assert row.diff_efficiency == (math.fsum(group.diff_output_energy_J) / math.fsum(group.diff_input_energy_J))


# EPA's derived 5-cycle coefficients (40 CFR 600.210-12(a)(2)) by model year: (intercept
# [gal/mi], slope) of city and highway; the 2008 rule's set before MY2017, the MY2017+ set from
# then and for a row without a model year (models/budget.toml gives the sources)
SET_2008 = {"UDDS": (0.003259, 1.1805), "HWFET": (0.001376, 1.3466)}
SET_2017 = {"UDDS": (0.004091, 1.1601), "HWFET": (0.003191, 1.2945)}


@pytest.mark.parametrize(("model_year", "label"), [(2015, SET_2008), (2017, SET_2017), (None, SET_2017)])
def test_budget_years_growth_and_cycle_mix(tmp_path, model_year, label):
    extra = {} if model_year is None else {"model_year": model_year}
    path = write_fleet(tmp_path / "f.xlsx", [vehicle("A", count=2, annual_miles=10000, **extra)],
                       [scenario("s", cycle_mix="UDDS:0.25,HWFET:0.75", budget_years=3,
                                 vmt_growth_pct_per_year=10)])
    out = tmp_path / "out"
    assert run(path, "--out", out, "--no-cache", "-q").exit_code == 0
    row = read_csv(out / "results.csv").iloc[0]
    assert row.miles_total == pytest.approx(2 * 10000 * (1 + 1.1 + 1.21), rel=1e-12)
    from fleetrun.cycles import load_cycle

    v = fakes.fake_simulate
    per_mile = 0.0
    from fleetrun.workbook import read_fleet

    spec = read_fleet(path).vehicles[0]
    # on-road fuel by EPA's derived 5-cycle formulas: 1/mpg = intercept + slope/mpg, city (UDDS)
    # and highway (HWFET), with the set of the row's model year
    cycle_per_mile = 0.0
    for name, share in (("UDDS", 0.25), ("HWFET", 0.75)):
        sim = v([spec], load_cycle(name))
        gal_per_mile = sim.fuel_gal[0] / sim.miles[0]
        cycle_per_mile += share * gal_per_mile
        per_mile += share * (label[name][0] + label[name][1] * gal_per_mile)
    # and the known fleet bias corrected in the centre (tests/data/fleet_error_fixture.toml: +2 %)
    assert row.fuel_gal_total == pytest.approx(row.miles_total * per_mile * 1.02, rel=1e-12)
    assert row.fuel_gal_cycle_total == pytest.approx(row.miles_total * cycle_per_mile, rel=1e-12)


def test_each_cycle_and_temperature_simulated_once(fleet_path, tmp_path):
    assert run(fleet_path, "--out", tmp_path / "o", "--no-cache", "-q").exit_code == 0
    # baseline: UDDS, HWFET at 20 C; hot: UDDS, HWFET, US06 at 38 C; urban: NYCC (+UDDS at 20 C)
    assert sorted((c, t) for _, c, t in fakes.CALLS) == sorted(
        [("UDDS", 20), ("HWFET", 20), ("UDDS", 38), ("HWFET", 38), ("US06", 38), ("NYCC", 20)])


def test_scenario_filter_and_unknown_scenario(fleet_path, tmp_path):
    out = tmp_path / "out"
    ok = run(fleet_path, "--out", out, "--scenario", "hot", "--no-cache", "-q")
    assert ok.exit_code == 0, ok.stderr
    assert set(read_csv(out / "class_summary.csv").scenario_id) == {"hot"}
    bad = run(fleet_path, "--out", tmp_path / "o2", "--scenario", "hott", "--no-cache", "-q")
    assert bad.exit_code == 1
    assert bad.stderr.startswith("Error: ") and "did you mean 'hot'" in bad.stderr
    assert not (tmp_path / "o2").exists()


def test_bad_workbook_exit_1_nothing_written(tmp_path):
    path = write_fleet(tmp_path / "bad.xlsx", [vehicle(peak_engine_torque_Nm="abc")])
    out = tmp_path / "out"
    result = run(path, "--out", out, "--no-cache", "-q")
    assert result.exit_code == 1
    assert result.stderr.count("Error:") == 1
    assert "Vehicles!H2 peak_engine_torque_Nm: 'abc' is not a number" in result.stderr
    assert not out.exists()


def test_usage_errors_exit_2(fleet_path, tmp_path):
    assert run().exit_code == 2
    assert run(fleet_path, "--engine", "spark").exit_code == 2
    assert run(fleet_path, "--scheduler", "tcp://x:1", "--no-cache").exit_code == 2
    assert run(fleet_path, "--config", tmp_path / "b.toml").exit_code == 2


def test_failed_run_keeps_previous_good_outputs(fleet_path, tmp_path, monkeypatch):
    out = tmp_path / "out"
    assert run(fleet_path, "--out", out, "--no-cache", "-q").exit_code == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def broken(*args, **kwargs):
        raise RuntimeError("disk on fire")

    from fleetrun.reports import html as report_html

    monkeypatch.setattr(report_html, "render_summary", broken)
    result = run(fleet_path, "--out", out, "--no-cache", "-q")
    assert result.exit_code == 4
    assert result.stderr.startswith("Error: ") and "internal error" in result.stderr
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert [p.name for p in tmp_path.iterdir() if "staging" in p.name] == []


def test_batch_config_partial_failure_log_and_exit_3(fleet_path, tmp_path):
    bad = write_fleet(tmp_path / "bad.xlsx", [vehicle(count=-1)])
    config = tmp_path / "batch.toml"
    config.write_text('inputs = ["fleet.xlsx", "bad.xlsx"]\nscenarios = ["baseline"]\nout = "results"\n'
                      'engine = "local"\ncache_dir = "cache"\n')
    result = run("--config", config, "-q")
    assert result.exit_code == 3, result.stderr
    assert result.stderr.startswith("Error: 1 of 2 fleet workbooks failed")
    assert "Vehicles!E2 count: -1 must be at least 0" in result.stderr
    assert {p.name for p in (tmp_path / "results" / "fleet").iterdir()} == OUTPUTS
    assert not (tmp_path / "results" / "bad").exists()
    log = (tmp_path / "results" / "fleetrun-run.log").read_text()
    assert "ERROR" in log and "fleet.xlsx: wrote" in log
    bad.unlink()
    config.write_text('inputs = ["*.xlsx"]\nout = "results"\n')
    assert run("--config", config, "-q").exit_code == 0


def test_batch_config_errors(tmp_path):
    config = tmp_path / "batch.toml"
    config.write_text('inputs = ["nothing*.xlsx"]\n')
    result = run("--config", config)
    assert result.exit_code == 1 and "matches no file" in result.stderr
    config.write_text('inputs = "a.xlsx"\nengin = "dask"\n')
    result = run("--config", config)
    assert result.exit_code == 1 and "unknown key(s) engin" in result.stderr
    config.write_text('inputs = [\n')
    assert run("--config", config).exit_code == 1


def test_plain_log_lines_when_not_a_terminal(fleet_path, tmp_path):
    result = run(fleet_path, "--out", tmp_path / "o", "--no-cache")
    assert result.exit_code == 0
    assert "INFO fleet.xlsx:" in result.stdout and "simulation tasks (100 %)" in result.stdout
    assert "\r" not in result.stdout and result.stderr == ""


def test_failed_simulation_leaves_only_the_error_on_stderr(fleet_path, tmp_path, monkeypatch):
    from fleetrun.errors import DomainError

    def refuses(vehicles, cycle, **kwargs):
        raise DomainError(f"cannot simulate {cycle.name}")

    result = run(fleet_path, "--out", tmp_path / "o", simulate=refuses)
    assert result.exit_code == 1
    assert result.stderr.startswith("Error: cannot simulate") and result.stderr.count("\n") == 1
    assert "INFO fleet.xlsx" in result.stdout and not (tmp_path / "o").exists()


def test_shortfall_becomes_a_warning(tmp_path):
    path = write_fleet(tmp_path / "f.xlsx", [vehicle("CAR-SLOW")],
                       [scenario(cycle_mix="US06:1")])
    out = tmp_path / "out"
    assert run(path, "--out", out, "--no-cache", "-q").exit_code == 0
    warnings = json.loads((out / "manifest.json").read_text())["warnings"]
    assert "vehicle CAR-SLOW cannot follow US06 (20 C); worst shortfall: 5 s behind the trace" in warnings


def test_dask_engine_same_numbers(fleet_path, tmp_path):
    pytest.importorskip("distributed")
    import cloudpickle

    cloudpickle.register_pickle_by_value(fakes)   # workers cannot import the tests folder
    try:
        local, dask = tmp_path / "local", tmp_path / "dask"
        assert run(fleet_path, "--out", local, "--no-cache", "-q").exit_code == 0
        result = run(fleet_path, "--out", dask, "--engine", "dask", "--no-cache", "-q")
        assert result.exit_code == 0, result.stderr
    finally:
        cloudpickle.unregister_pickle_by_value(fakes)
    for name in ("results.csv", "class_summary.csv"):
        a, b = read_csv(local / name), read_csv(dask / name)
        pd.testing.assert_frame_equal(a, b, check_exact=True)   # bit for bit
    assert json.loads((dask / "manifest.json").read_text())["engine"]["engine"] == "dask"


def test_unreachable_scheduler_is_an_input_error(fleet_path, tmp_path):
    pytest.importorskip("distributed")
    result = run(fleet_path, "--out", tmp_path / "o", "--engine", "dask", "--scheduler",
                 "tcp://127.0.0.1:9", "--no-cache", "-q")
    assert result.exit_code == 1
    assert result.stderr.startswith("Error: cannot reach the Dask scheduler")


def test_rows_that_drive_alike_are_simulated_once(tmp_path):
    twins = [vehicle("A", count=10), vehicle("B", count=20, annual_miles=5000, vehicle_class="Other"),
             vehicle("C", test_weight_kg=1700)]
    path = write_fleet(tmp_path / "f.xlsx", twins, [scenario(cycle_mix="UDDS:1")])
    out = tmp_path / "out"
    assert run(path, "--out", out, "--no-cache", "-q").exit_code == 0
    assert fakes.CALLS == [(2, "UDDS", 20)]
    results = read_csv(out / "results.csv").set_index("vehicle_id")
    assert results.loc["A", "mpg"] == pytest.approx(results.loc["B", "mpg"], rel=1e-14)
    assert results.loc["A", "mpg"] != pytest.approx(results.loc["C", "mpg"], rel=1e-6)
    assert json.loads((out / "manifest.json").read_text())["distinct_vehicles_simulated"] == 2


def test_heavy_vehicles_drive_their_own_cycle_mix(tmp_path):
    truck = vehicle("TRUCK", vehicle_class="Truck", duty_class="HD", configuration="HD_RWD", fuel="diesel",
                    test_weight_kg=20000, tire_size="11R22.5")
    path = write_fleet(tmp_path / "f.xlsx", [vehicle("CAR"), truck],
                       [scenario(cycle_mix="UDDS:0.5,HWFET:0.5", cycle_mix_HD="HD-UDDS:1")])
    out = tmp_path / "out"
    result = run(path, "--out", out, "--no-cache", "-q")
    assert result.exit_code == 0, result.stderr
    assert sorted(fakes.CALLS) == [(1, "HD-UDDS", 20), (1, "HWFET", 20), (1, "UDDS", 20)]
    from fleetrun.cycles import load_cycle
    from fleetrun.workbook import read_fleet

    spec = read_fleet(path).vehicle("TRUCK")
    sim = fakes.fake_simulate([spec], load_cycle("HD-UDDS"))
    row = read_csv(out / "results.csv").set_index("vehicle_id").loc["TRUCK"]
    # cycle fuel (no label formula for heavy trucks) with the fixture's fleet bias (+2 %)
    assert row.fuel_gal_total == pytest.approx(row.miles_total * sim.fuel_gal[0] / sim.miles[0] * 1.02, rel=1e-12)


def test_outputs_get_ordinary_file_modes(fleet_path, tmp_path):
    from fleetrun.fileio import default_file_mode

    out = tmp_path / "out"
    assert run(fleet_path, "--out", out, "--no-cache", "-q").exit_code == 0
    assert {oct(p.stat().st_mode & 0o777) for p in out.iterdir()} == {oct(default_file_mode())}
    template = tmp_path / "t.xlsx"
    assert CliRunner().invoke(cli, ["template", "-o", str(template)]).exit_code == 0
    assert template.stat().st_mode & 0o777 == default_file_mode()


def test_dask_scheduler_address(fleet_path, tmp_path):
    distributed = pytest.importorskip("distributed")
    local = tmp_path / "local"
    assert run(fleet_path, "--out", local, "--no-cache", "-q").exit_code == 0
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        result = run(fleet_path, "--out", tmp_path / "remote", "--engine", "dask", "--scheduler",
                     cluster.scheduler_address, "--no-cache", "-q")
    assert result.exit_code == 0, result.stderr
    manifest = json.loads((tmp_path / "remote" / "manifest.json").read_text())
    assert manifest["engine"] == {"engine": "dask", "scheduler": cluster.scheduler_address}
    assert (tmp_path / "remote" / "results.csv").read_bytes() == (local / "results.csv").read_bytes()


def test_docs_name_every_output():
    from pathlib import Path

    from fleetrun.run.outputs import OUTPUT_FILES

    words = {6: "six", 7: "seven", 8: "eight", 9: "nine"}
    batch = (Path(__file__).parents[1] / "docs" / "batch.md").read_text()
    assert f"writes {words[len(OUTPUT_FILES)]} files into DIR" in batch
    assert all(f"`{name}`" in batch for name in OUTPUT_FILES)


def test_the_console_entry_sets_the_collector_for_a_batch_command():
    """``fleetrun.cli.main`` (the console script, ``python -m fleetrun``) loads the command's
    modules, freezes them out of the garbage collector's view and collects the young generation
    every GC_YOUNG_THRESHOLD objects (docs/benchmarks-run.md, "Fourth pass"); a program that only
    imports fleetrun keeps Python's collector as it was; a command that is not one still gets
    click's usage error (exit 2)."""
    import subprocess
    import sys

    from fleetrun.cli import GC_YOUNG_THRESHOLD

    code = ("import gc, sys; from fleetrun import cli; before = gc.get_threshold()[0]; "
            "cli._collect_less(['run', 'x.xlsx']); "
            "print(before, gc.get_threshold()[0], gc.get_freeze_count() > 0, 'fleetrun.commands.run' in sys.modules)")
    from pathlib import Path

    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    before, after, frozen, loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                                   env=env, check=True).stdout.split()
    assert int(before) < GC_YOUNG_THRESHOLD and int(after) == GC_YOUNG_THRESHOLD   # Python's own is 700 (3.11)
    assert (frozen, loaded) == ("True", "True")
    bad = subprocess.run([sys.executable, "-m", "fleetrun", "no-such-command"], capture_output=True, text=True, env=env)
    assert bad.returncode == 2 and "No such command" in bad.stderr
