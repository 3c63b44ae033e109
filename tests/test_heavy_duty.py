"""Heavy-duty defaults (models/heavy_duty/): the FHWA class rows are valid Vehicles rows and
their road load is the one their GEM inputs give."""
from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from fleetrun.workbook.vehicle_file import vehicle_from_mapping
from fleetrun.resources import models_dir
from fleetrun.simulation.heavy_duty_road_load import gem_coastdown_lbf

LB_KG = 0.45359237
HD_DIR = models_dir() / "heavy_duty"
ROW_KEYS = {"duty_class", "configuration", "fuel", "peak_engine_torque_Nm", "transmission",
            "transmission_gear_ratios", "final_drive_ratio", "test_weight_kg", "coastdown_A_lbf",
            "coastdown_B_lbf_per_mph", "coastdown_C_lbf_per_mph2", "tire_size", "rated_power_kW",
            "engine_displacement_L", "annual_miles", "source"}


def _load(name):
    with open(HD_DIR / name, "rb") as fh:
        return tomllib.load(fh)


def test_fhwa_classes_have_the_stable_keys():
    classes = _load("fhwa_classes.toml")
    assert {"single_unit_truck", "combination_truck", "bus"} <= set(classes)
    for name, row in classes.items():
        assert set(row) == ROW_KEYS, name


@pytest.mark.parametrize("name", ["single_unit_truck", "combination_truck", "bus"])
def test_fhwa_class_is_a_valid_vehicles_row(name):
    row = dict(_load("fhwa_classes.toml")[name])
    row.pop("source")
    spec = vehicle_from_mapping({**row, "vehicle_id": name, "vehicle_class": name, "count": 1}, Path(name))
    assert spec.fuel == "diesel" and spec.duty_class in ("MD", "HD")


@pytest.mark.parametrize("name", ["single_unit_truck", "combination_truck", "bus"])
def test_fhwa_class_road_load_is_its_gem_inputs(name):
    """The row's A and C are the GEM inputs' (Crr m g, rho CdA / 2), to the 0.1 lbf / 1e-4
    lbf/mph^2 the file is rounded to; the weight is the basis weight to 1 kg."""
    row, basis = _load("fhwa_classes.toml")[name], _load("gem_basis.toml")[name]
    mass = basis["test_weight_lb"] * LB_KG
    a, b, c = gem_coastdown_lbf(mass, basis["crr_kg_per_t"] / 1000.0, basis["cda_m2"])
    assert row["test_weight_kg"] == pytest.approx(mass, abs=0.5)
    assert row["coastdown_A_lbf"] == pytest.approx(float(a), abs=0.01)
    assert row["coastdown_B_lbf_per_mph"] == float(b) == 0.0
    assert row["coastdown_C_lbf_per_mph2"] == pytest.approx(float(c), abs=5e-5)
