"""A run into a folder that holds an earlier run: what changed (inputs, totals) in the log,
the HTML and a sheet; the earlier run kept in earlier-runs/ unless --replace."""
from __future__ import annotations

import json
import math

import openpyxl
import pytest

import test_fleet_fakes as fakes
from test_fleet_fakes import scenario, vehicle, write_fleet


def test_rerun_with_a_changed_workbook_says_what_changed_and_keeps_the_earlier_run(tmp_path):
    out = tmp_path / "out"
    first = write_fleet(tmp_path / "fleet.xlsx", [vehicle("A", count=1000)], [scenario("s")])
    assert fakes.invoke_run(first, "--out", out, "--no-cache", "-q").exit_code == 0
    earlier = json.loads((out / "manifest.json").read_text())
    write_fleet(tmp_path / "fleet.xlsx", [vehicle("A", count=1100)], [scenario("s")])
    result = fakes.invoke_run(tmp_path / "fleet.xlsx", "--out", out, "--no-cache")
    assert result.exit_code == 0, result.stderr
    # the log names the changed input and the totals' change (+10 % vehicles -> +10 % gallons)
    assert f"input changed: {tmp_path / 'fleet.xlsx'}" in result.stdout
    assert "s fuel_gal_total:" in result.stdout and "(+10.00%)" in result.stdout
    kept = list((out / "earlier-runs").iterdir())
    assert len(kept) == 1 and json.loads((kept[0] / "manifest.json").read_text()) == earlier
    assert {p.name for p in kept[0].iterdir()} >= {"report.xlsx", "results.csv", "manifest.json"}
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["changes"]["earlier_created_utc"] == earlier["created_utc"]
    sheet = openpyxl.load_workbook(out / "report.xlsx")["What changed"]
    values = [c for row in sheet.iter_rows(values_only=True) for c in row if c is not None]
    assert "changed" in values and "fuel_gal_total" in values
    html = (out / "summary.html").read_text()
    assert "input changed:" in html
    # a third run keeps both earlier runs; --replace keeps none of its predecessor
    assert fakes.invoke_run(tmp_path / "fleet.xlsx", "--out", out, "--no-cache", "-q").exit_code == 0
    assert len(list((out / "earlier-runs").iterdir())) == 2
    assert fakes.invoke_run(tmp_path / "fleet.xlsx", "--out", out, "--no-cache", "-q", "--replace").exit_code == 0
    assert len(list((out / "earlier-runs").iterdir())) == 2


def test_first_run_has_nothing_to_compare(tmp_path):
    out = tmp_path / "out"
    path = write_fleet(tmp_path / "fleet.xlsx", [vehicle("A")], [scenario("s")])
    assert fakes.invoke_run(path, "--out", out, "--no-cache", "-q").exit_code == 0
    assert not (out / "earlier-runs").exists()
    assert json.loads((out / "manifest.json").read_text())["changes"] is None
    assert "No earlier run in this folder" in (out / "summary.html").read_text()


def _causes(out) -> dict:
    manifest = json.loads((out / "manifest.json").read_text())
    return {(c["scenario_id"], c["total"], c["cause"]): c["amount"] for c in manifest["changes"]["causes"]}


def test_each_totals_change_is_attributed_to_its_causes(tmp_path):
    out = tmp_path / "out"
    path = write_fleet(tmp_path / "fleet.xlsx", [vehicle("A", count=1000)], [scenario("s")])
    assert fakes.invoke_run(path, "--out", out, "--no-cache", "-q").exit_code == 0
    before = json.loads((out / "manifest.json").read_text())["totals"]["s"]
    # the state rate 0.20 -> 0.25 and 10 % more vehicles at once
    write_fleet(tmp_path / "fleet.xlsx", [vehicle("A", count=1100)], [scenario("s", state_tax_gasoline_usd_per_gal=0.25)])
    result = fakes.invoke_run(path, "--out", out, "--no-cache")
    assert result.exit_code == 0, result.stderr
    causes = _causes(out)
    now = json.loads((out / "manifest.json").read_text())["totals"]["s"]
    change = now["state_tax_usd"] - before["state_tax_usd"]
    # revenue = gallons x rate: ln(1.1) of the change is the vehicles', ln(1.25) the rate's
    share = math.log(1.25) / (math.log(1.25) + math.log(1.1))
    assert causes[("s", "state_tax_usd", "tax rates")] == pytest.approx(change * share, rel=1e-9)
    assert causes[("s", "state_tax_usd", "vehicles")] == pytest.approx(change * (1 - share), rel=1e-9)
    # gallons moved by the vehicles only; the federal rate did not change
    assert causes[("s", "fuel_gal_total", "vehicles")] == pytest.approx(now["fuel_gal_total"] - before["fuel_gal_total"],
                                                                        rel=1e-9)
    assert ("s", "federal_tax_usd", "tax rates") not in causes
    assert "of which: vehicles" in result.stdout


def test_a_renamed_workbook_is_followed(tmp_path):
    out = tmp_path / "out"
    path = write_fleet(tmp_path / "fleet.xlsx", [vehicle("A")], [scenario("s")])
    assert fakes.invoke_run(path, "--out", out, "--no-cache", "-q").exit_code == 0
    renamed = path.rename(tmp_path / "fleet-2027.xlsx")
    assert fakes.invoke_run(renamed, "--out", out, "--no-cache", "-q").exit_code == 0
    inputs = json.loads((out / "manifest.json").read_text())["changes"]["inputs"]
    statuses = [i["status"] for i in inputs]
    # one "renamed" entry, not "removed" + "added"; the other inputs (cycle files) the same
    assert statuses[0] == "renamed" and set(statuses[1:]) <= {"same"}
    assert inputs[0]["path"].endswith("fleet.xlsx -> " + str(renamed))
    # the manifest hashes every model file the constants come from
    models = json.loads((out / "manifest.json").read_text())["model_files"]
    assert {"budget.toml", "fleet_error.toml", "climate.toml", "engine_calibration.toml"} <= {m["path"] for m in models}
