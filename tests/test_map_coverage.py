"""Every valid Vehicles row runs in the default mode (issue 10 item 6).

A final drive ratio beyond the cached map3d gear-ratio grid (LD 2-6, HD 2.5-8) gets maps
built at its own ratio; the run notes those vehicles. The workbook refuses ratios beyond
the range the differential model's gear-ratio scaling covers (1.2-12), so `validate` catches
what `run` would refuse. docs/interface.md: the modes agree within 0.2 % on cycle fuel.
"""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from click.testing import CliRunner
from openpyxl import load_workbook

from fleetrun.cli import cli
from fleetrun.simulation import simulate
from fleetrun.simulation.diffmodes import outside_map3d_grid
from fleetrun.testing.vehicles import CIVIC
from test_epa_import import epa_row, write_list

# the FCA 9-speeds of the 2022 list (1.56, 1.68, 1.79), the ends of the workbook's range, and
# ratios beyond the grid's top
RATIOS = (1.2, 1.5, 1.56, 1.68, 1.79, 1.8, 6.5, 8.5, 12.0)


@pytest.mark.parametrize("configuration", ["LD_FWD", "LD_RWD", "LD_AWD", "LD_4WD"])
def test_map3d_agrees_with_direct_beyond_the_grid(configuration, tmp_path):
    vehicles = [dataclasses.replace(CIVIC, vehicle_id=f"G{g}", configuration=configuration, final_drive_ratio=g)
                for g in RATIOS]
    assert all(outside_map3d_grid(configuration, g) for g in RATIOS)
    direct = simulate(vehicles, "UDDS", mode="direct")
    mapped = simulate(vehicles, "UDDS", mode="auto", cache_dir=tmp_path)
    worst = np.max(np.abs(mapped.fuel_g / direct.fuel_g - 1.0))
    assert worst < 0.002, f"{configuration}: worst cycle-fuel difference {worst:.3%}"


@pytest.fixture
def low_axle_fleet(tmp_path):
    rows = [epa_row(**{"Test Vehicle ID": "FCA1", "Axle Ratio": 1.56, "N/V Ratio": 30.1}),
            epa_row(**{"Test Vehicle ID": "FCA2", "Axle Ratio": 1.79, "N/V Ratio": 28.5,
                       "Drive System Code": "A"})]
    csv = write_list(tmp_path / "fca.csv", rows)
    fleet = tmp_path / "fca.xlsx"
    assert CliRunner().invoke(cli, ["import-epa", str(csv), "-o", str(fleet)]).exit_code == 0
    return fleet


def test_default_run_handles_low_axle_ratios_with_a_note(low_axle_fleet, tmp_path):
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["run", str(low_axle_fleet), "--out", str(out), "--cache-dir",
                                      str(tmp_path / "maps"), "-q"])
    assert result.exit_code == 0, result.stderr
    manifest = json.loads((out / "manifest.json").read_text())
    notes = [w for w in manifest["warnings"] if "beyond the map3d gear-ratio grid" in w]
    assert len(notes) == 1 and "FCA1_c1 (row 2: 1.56)" in notes[0] and "FCA2_c1 (row 3: 1.79)" in notes[0]


@pytest.mark.parametrize("value", [0.9, 1.0, 12.5])
def test_validate_refuses_ratios_the_model_cannot_take(low_axle_fleet, value):
    book = load_workbook(low_axle_fleet)
    sheet = book["Vehicles"]
    column = [c.value for c in sheet[1]].index("final_drive_ratio") + 1
    sheet.cell(row=3, column=column, value=value)
    book.save(low_axle_fleet)
    letter = sheet.cell(row=3, column=column).column_letter
    for command in ("validate", "run"):
        result = CliRunner().invoke(cli, [command, str(low_axle_fleet)])
        assert result.exit_code == 1
        text = result.stderr
        assert text.startswith("Error: ") and str(low_axle_fleet) in text
        assert f"Vehicles!{letter}3 final_drive_ratio: {value:g} must be at" in text


def test_validate_names_the_cell_the_simulation_would_refuse(low_axle_fleet):
    """An extra column the simulation reads (gear_efficiency overrides models/transmissions.toml)
    holding text: the simulation's own check, reported by validate at its cell, and run stops
    with the same line before simulating."""
    book = load_workbook(low_axle_fleet)
    sheet = book["Vehicles"]
    column = sheet.max_column + 1
    sheet.cell(row=1, column=column, value="gear_efficiency")
    sheet.cell(row=2, column=column, value="abc")
    book.save(low_axle_fleet)
    letter = sheet.cell(row=2, column=column).column_letter
    lines = []
    for command in ("validate", "run"):
        result = CliRunner().invoke(cli, [command, str(low_axle_fleet)])
        assert result.exit_code == 1 and "Traceback" not in result.stderr
        # docs/interface.md: the first line names the file, sheet, cell and value (issue 9)
        assert result.stderr.startswith(f"Error: {low_axle_fleet}: Vehicles!{letter}2 gear_efficiency:")
        line = next(t for t in result.stderr.splitlines() if "gear_efficiency" in t)
        assert f"Vehicles!{letter}2 gear_efficiency:" in line and "'abc'" in line
        lines.append(line)
    assert lines[0] == lines[1]
