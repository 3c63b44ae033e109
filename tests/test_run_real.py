"""``fleetrun run`` on the shipped example fleet with the real simulation: the README's first
command, reconciliation, the map cache on a re-run, and dask = local."""
from __future__ import annotations

import json
import math

import pytest
from click.testing import CliRunner

from fleetrun.cli import cli
from fleetrun.resources import inputs_dir
from test_fleet_fakes import read_csv

pytest.importorskip("fleetrun.simulation")
EXAMPLE = inputs_dir() / "example_fleet.xlsx"
OUTPUTS = {"report.xlsx", "summary.html", "results.csv", "results.parquet", "class_summary.csv", "fiscal_summary.csv",
           "revenue_memo.csv", "fiscal_periods.csv", "manifest.json"}


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("maps")


@pytest.fixture(scope="module")
def example_run(tmp_path_factory, cache):
    out = tmp_path_factory.mktemp("example") / "out"
    result = CliRunner().invoke(cli, ["run", str(EXAMPLE), "--out", str(out), "--cache-dir", str(cache), "-q"])
    assert result.exit_code == 0, result.stderr
    return out


def test_example_fleet_writes_five_outputs(example_run):
    assert {p.name for p in example_run.iterdir()} == OUTPUTS
    manifest = json.loads((example_run / "manifest.json").read_text())
    assert manifest["scenarios"] == ["baseline", "hot_summer", "congested_urban"]
    assert manifest["vehicle_types"] == 23 and manifest["mode"] == "auto"


def test_example_fleet_reconciles_and_is_plausible(example_run):
    results = read_csv(example_run / "results.csv")
    classes = read_csv(example_run / "class_summary.csv")
    assert len(results) == 3 * 23
    assert set(results.configuration) == {"LD_FWD", "LD_RWD", "LD_4WD", "LD_AWD", "HD_RWD", "HD_DUAL",
                                          "HD_TANDEM", "HD_TANDEM_DUAL", "HD_TAG", "HD_TAG_DUAL"}
    for row in results.itertuples():
        rate = 0.2
        assert row.state_tax_usd == row.fuel_gal_total * rate
        assert row.mpg == row.miles_total / row.fuel_gal_total
        assert 0.5 < row.diff_efficiency < 1 and 0.5 < row.drivetrain_efficiency < 1
    for row in classes.itertuples():
        group = results[(results.scenario_id == row.scenario_id) & (results.vehicle_class == row.vehicle_class)]
        assert row.fuel_gal_total == math.fsum(group.fuel_gal_total)
        assert row.state_tax_usd == math.fsum(group.state_tax_usd)
        assert row.mpg == row.miles_total / row.fuel_gal_total
    base = results[results.scenario_id == "baseline"].set_index("vehicle_id")
    assert 25 < base.loc["LD-CAMRY-25", "mpg"] < 45          # EPA-like for a 2.5 L sedan
    assert 3 < base.loc["HD-TRACTOR-LONGHAUL", "mpg"] < 9      # class 8 tractor-trailer
    urban = results[results.scenario_id == "congested_urban"].set_index("vehicle_id")
    assert urban.loc["LD-CAMRY-25", "mpg"] < base.loc["LD-CAMRY-25", "mpg"]


def test_rerun_reuses_cached_maps(example_run, cache, tmp_path):
    maps = sorted(p.name for p in cache.iterdir())
    assert maps, "the first run should have cached its maps"
    before = {p.name: p.stat().st_mtime_ns for p in cache.iterdir()}
    out = tmp_path / "again"
    result = CliRunner().invoke(cli, ["run", str(EXAMPLE), "--out", str(out), "--cache-dir", str(cache), "-q"])
    assert result.exit_code == 0, result.stderr
    assert {p.name: p.stat().st_mtime_ns for p in cache.iterdir()} == before
    assert (out / "results.csv").read_bytes() == (example_run / "results.csv").read_bytes()


def test_dask_engine_same_numbers_as_local(example_run, cache, tmp_path):
    pytest.importorskip("distributed")
    out = tmp_path / "dask"
    result = CliRunner().invoke(cli, ["run", str(EXAMPLE), "--out", str(out), "--engine", "dask",
                                      "--cache-dir", str(cache), "-q"])
    assert result.exit_code == 0, result.stderr
    for name in ("results.csv", "class_summary.csv"):
        assert (out / name).read_bytes() == (example_run / name).read_bytes()
