"""``fleetrun simulate``: one vehicle over one drive cycle (docs/interface.md).

    fleetrun simulate FLEET.xlsx --vehicle ID --cycle NAME [--scenario ID]
                     [--mode direct|map2d|map3d] [--with EFFECT[,EFFECT...]] [-o trace.csv]
    fleetrun simulate --vehicle-file VEHICLE.toml --cycle NAME [...]

Prints one JSON line (miles, fuel_gal, mpg, diff_efficiency, drivetrain_efficiency, ...) and,
with ``-o``, writes the per-step trace CSV atomically.
"""
from __future__ import annotations

import json
from pathlib import Path

import click

from fleetrun.cycles import load_cycle
from fleetrun.effects import parse_with
from fleetrun.errors import InputError
from fleetrun.fileio import atomic_file, refuse_replacing_inputs
from fleetrun.simulation import simulate
from fleetrun.workbook.reader import read_fleet
from fleetrun.workbook.vehicle_file import read_vehicle_toml


def _write_atomic(frame, path: Path) -> None:
    with atomic_file(path) as tmp:
        frame.to_csv(tmp, index=False, float_format="%.6g", lineterminator="\n")


@click.command("simulate")
@click.argument("fleet_file", required=False, type=click.Path(dir_okay=False), metavar="[FLEET.xlsx]")
@click.option("--vehicle", "vehicle_id", help="vehicle_id of the Vehicles row to simulate.")
@click.option("--vehicle-file", type=click.Path(dir_okay=False),
              help="A TOML file with the keys of one Vehicles row, instead of FLEET.xlsx.")
@click.option("--cycle", "cycle_name", required=True, help="Shipped cycle name (see `fleetrun cycles`) or a CSV path.")
@click.option("--scenario", "scenario_id", help="Scenario whose ambient temperature to use (default 20 C).")
@click.option("--mode", type=click.Choice(["direct", "map2d", "map3d", "auto"]), default="auto", show_default=True,
              help="Differential running mode (thesis Ch. 6); auto = the fastest within 0.2 % of direct.")
@click.option("--physics", default="thesis", show_default=True, help="Differential physics baseline.")
@click.option("--ambient-temp-C", "ambient_temp_C", type=float, default=None,
              help="Ambient temperature [C] (overrides the scenario's).")
@click.option("--with", "with_effects", metavar="EFFECT[,EFFECT...]",
              help="Add physics the thesis left out (docs/effects.md), e.g. bearing_preload:drag_torque_Nm=3,warmup.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), help="Write the per-step trace CSV here.")
def command(fleet_file, vehicle_id, vehicle_file, cycle_name, scenario_id, mode, physics, ambient_temp_C,
            with_effects, output):
    """Simulate one vehicle over a drive cycle; print a JSON summary line."""

    effects = parse_with(with_effects)  # a misspelt effect fails here, before any work
    if output:
        refuse_replacing_inputs(Path(output), [fleet_file, vehicle_file, cycle_name], "-o")

    ambient = 20.0
    if vehicle_file:
        if fleet_file:
            raise click.UsageError("give FLEET.xlsx or --vehicle-file, not both")
        if scenario_id:
            raise click.UsageError("--scenario needs FLEET.xlsx")
        vehicle = read_vehicle_toml(vehicle_file)
    else:
        if not fleet_file:
            raise click.UsageError("give FLEET.xlsx (with --vehicle ID) or --vehicle-file VEHICLE.toml")
        if not vehicle_id:
            raise click.UsageError("--vehicle ID is required with FLEET.xlsx")
        fleet = read_fleet(fleet_file)
        try:
            vehicle = fleet.vehicle(vehicle_id)
        except InputError as exc:
            exc.file = exc.file or fleet_file
            raise
        if scenario_id:
            try:
                ambient = fleet.scenario(scenario_id).ambient_temp_C
            except InputError as exc:
                exc.file = exc.file or fleet_file
                raise
    if ambient_temp_C is not None:
        ambient = ambient_temp_C
    cycle = load_cycle(cycle_name)
    result = simulate([vehicle], cycle, mode=mode, ambient_temp_C=ambient, physics=physics, effects=effects,
                      trace=bool(output))
    if output:
        _write_atomic(result.trace_frame(0), Path(output))
    summary = result.summary(0)
    summary["ambient_temp_C"] = ambient
    click.echo(json.dumps(summary))
