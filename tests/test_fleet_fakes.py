"""Test helpers for the fleet runner: a small stand-in for fleetrun.simulation.simulate and
workbook builders. (No tests here; pytest collects the module harmlessly.)"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import openpyxl

from fleetrun.workbook.schema import SCENARIO_COLUMNS, VEHICLE_COLUMNS
from fleetrun.workbook.template import write_template
from fleetrun.simulation import FleetCycleResult

CONFIG_ETA = {"LD_FWD": 0.96, "LD_RWD": 0.95, "LD_4WD": 0.93, "LD_AWD": 0.92, "HD_RWD": 0.955,
              "HD_DUAL": 0.94, "HD_TANDEM": 0.93, "HD_TANDEM_DUAL": 0.92, "HD_TAG": 0.95,
              "HD_TAG_DUAL": 0.935}


CALLS: list = []


def fake_simulate(vehicles, cycle, *, mode="auto", ambient_temp_C=20.0, physics="thesis",
                  effects=(), trace=False, cache_dir=None):
    """Deterministic, cycle- and temperature-dependent numbers in the real result type."""
    CALLS.append((len(vehicles), cycle.name, ambient_temp_C))
    n = len(vehicles)
    miles = np.full(n, float(cycle.miles))
    weight = np.array([v.test_weight_kg for v in vehicles])
    aggressiveness = float(np.mean(cycle.speed_mps)) / 20.0
    gal_per_mile = (0.01 + 1.5e-5 * weight) * (1 + 0.3 * aggressiveness) * (1 + 0.002 * abs(ambient_temp_C - 20))
    fuel_gal = miles * gal_per_mile
    wheel = miles * weight * 900.0 * (1 + aggressiveness)
    eta = np.array([CONFIG_ETA[v.configuration] for v in vehicles]) - 0.0005 * (ambient_temp_C - 20) / 10
    diff_out = wheel / 0.985
    diff_in = diff_out / eta
    drivetrain_in = diff_in / 0.93
    shortfall = np.array([5.0 if v.vehicle_id.endswith("SLOW") and cycle.name == "US06" else 0.0
                          for v in vehicles])
    zeros = np.zeros(n)
    return FleetCycleResult(
        vehicle_ids=[v.vehicle_id for v in vehicles], cycle=cycle.name, mode=mode, miles=miles,
        fuel_g=fuel_gal * 2819.0, fuel_gal=fuel_gal, mpg=miles / fuel_gal, diff_input_energy_J=diff_in,
        diff_output_energy_J=diff_out, drivetrain_input_energy_J=drivetrain_in, wheel_energy_J=wheel,
        engine_energy_J=drivetrain_in, shortfall_time_s=shortfall, shortfall_distance_m=zeros,
        shortfall_max_speed_mps=zeros, shortfall_steps=zeros)


def write_fleet(path: Path, vehicles: list[dict] | None = None, scenarios: list[dict] | None = None) -> Path:
    """The template workbook with its example rows replaced by ``vehicles`` / ``scenarios``
    (dicts keyed by column name; None keeps the template's example rows)."""
    write_template(path)
    wb = openpyxl.load_workbook(path)
    for sheet, columns, rows in (("Vehicles", VEHICLE_COLUMNS, vehicles), ("Scenarios", SCENARIO_COLUMNS, scenarios)):
        if rows is None:
            continue
        ws = wb[sheet]
        ws.delete_rows(2, ws.max_row)
        names = [c.name for c in columns]
        for r, row in enumerate(rows, start=2):
            for key, value in row.items():
                cell = ws.cell(row=r, column=names.index(key) + 1, value=value)
                if isinstance(value, str):
                    cell.data_type = "s"  # labels like '=1+1' stay text
    wb.save(path)
    return path


def vehicle(vehicle_id="CAR-1", **overrides) -> dict:
    row = {"vehicle_id": vehicle_id, "vehicle_class": "Passenger car", "duty_class": "LD",
           "configuration": "LD_FWD", "count": 1000, "annual_miles": 12000, "fuel": "gasoline",
           "peak_engine_torque_Nm": 250, "transmission": "automatic",
           "transmission_gear_ratios": "4.6,3.0,2.0,1.6,1.2,1.0", "final_drive_ratio": 3.2,
           "test_weight_kg": 1600, "coastdown_A_lbf": 30, "coastdown_B_lbf_per_mph": 0.1,
           "coastdown_C_lbf_per_mph2": 0.02, "tire_size": "P215/55R17"}
    row.update(overrides)
    return row


def scenario(scenario_id="baseline", **overrides) -> dict:
    row = {"scenario_id": scenario_id, "description": "test", "ambient_temp_C": 20,
           "cycle_mix": "UDDS:0.55,HWFET:0.45", "budget_years": 2, "vmt_growth_pct_per_year": 1.5,
           "state_tax_gasoline_usd_per_gal": 0.2, "state_tax_diesel_usd_per_gal": 0.2,
           "federal_tax_gasoline_usd_per_gal": 0.184, "federal_tax_diesel_usd_per_gal": 0.244}
    row.update(overrides)
    return row


def small_fleet(path: Path) -> Path:
    """Two classes, both fuels, a two-speed axle, three scenarios."""
    vehicles = [
        vehicle("CAR-1"),
        vehicle("CAR-2", configuration="LD_RWD", count=500.5, test_weight_kg=1800),
        vehicle("PICKUP-1", vehicle_class="Pickup", configuration="LD_4WD", test_weight_kg=2500,
                peak_engine_torque_Nm=550, count=800),
        vehicle("TRUCK-1", vehicle_class="Heavy truck", duty_class="HD", configuration="HD_TANDEM_DUAL",
                fuel="diesel", transmission="manual", transmission_gear_ratios="12.8,9.3,6.8,4.9,3.6,2.6,1.9,1.4,1.0,0.73",
                final_drive_ratio=3.55, low_gear_ratio=4.9, test_weight_kg=29000, peak_engine_torque_Nm=2500,
                coastdown_A_lbf=240, coastdown_B_lbf_per_mph=1.5, coastdown_C_lbf_per_mph2=0.12,
                tire_size="295/75R22.5", count=300, annual_miles=80000),
    ]
    scenarios = [scenario("baseline"),
                 scenario("hot", ambient_temp_C=38, cycle_mix="UDDS:0.5,HWFET:0.4,US06:0.1"),
                 scenario("urban", cycle_mix="NYCC:0.3,UDDS:0.7", budget_years=3, vmt_growth_pct_per_year=-0.5)]
    return write_fleet(path, vehicles, scenarios)


def read_csv(path, **kwargs):
    """pandas.read_csv that gives back exactly the floats written (round-trip parsing is the
    default from pandas 3, where asking for it is deprecated)."""
    import pandas as pd

    if int(pd.__version__.split(".")[0]) < 3:
        kwargs.setdefault("float_precision", "round_trip")
    return pd.read_csv(path, **kwargs)


ERROR_FIXTURE = Path(__file__).parent / "data" / "fleet_error_fixture.toml"


def injected(simulate=fake_simulate, error_model=ERROR_FIXTURE) -> dict:
    """What the tests hand ``fleetrun run`` through click's context object: the stand-in
    simulation and the fixture error distribution (None: no ranges)."""
    from fleetrun.budget.uncertainty import read_error_model

    return {"simulate": simulate, "error_model": read_error_model(error_model) if error_model else None}


def invoke_run(*args, simulate=fake_simulate, error_model=ERROR_FIXTURE):
    """``fleetrun run ARGS`` in-process with the stand-in simulation injected."""
    from click.testing import CliRunner

    from fleetrun.cli import cli

    return CliRunner().invoke(cli, ["run", *map(str, args)], obj=injected(simulate, error_model))


def run_small_fleet_with_fake(base: Path) -> Path:
    """``fleetrun run`` on :func:`small_fleet` with the fake simulation; the output folder."""
    out = base / "out"
    result = invoke_run(small_fleet(base / "fleet.xlsx"), "--out", out, "--no-cache", "-q")
    assert result.exit_code == 0, result.stderr
    return out
