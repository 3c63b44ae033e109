"""The EPA 2022 Test Car List as `fleetrun import-epa` turns it into a fleet, for
validation/epa_fuel_economy.py: the Vehicles rows as `fleetrun run` reads them (the importer's
workbook, read back by the fleet reader) and the measured results, one row per vehicle.

Measured (unadjusted certification values, mpg): ``FTP`` (the composite), ``FTP:bag1..3``,
``HWFET`` (EPA's "HWFE"), ``US06``, and ``UDDS:hot`` = the hot-start UDDS made of bag 3 (the
bag-1 trace driven hot) and bag 2: mpg = (d1 + d2) / (d1 / mpg3 + d2 / mpg2) with d1, d2 the
distances of the UDDS trace before and after 505 s.
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
TSTCAR = ROOT / "inputs" / "epa" / "22-tstcar.csv"
UDDS_BAG1_END_S = 505.0
TESTS = ("FTP", "FTP:bag1", "FTP:bag2", "FTP:bag3", "HWFET", "US06")


def udds_bag_miles() -> tuple[float, float]:
    """Distances [mi] of the UDDS trace up to 505 s (bag 1 = bag 3) and after it (bag 2)."""
    from fleetrun.cycles import load_cycle

    c = load_cycle("UDDS")
    t, v = np.asarray(c.time_s, float), np.asarray(c.speed_mps, float)
    step_m = 0.5 * (v[1:] + v[:-1]) * np.diff(t)
    first = t[1:] <= UDDS_BAG1_END_S
    return float(step_m[first].sum() / 1609.344), float(step_m[~first].sum() / 1609.344)


def epa_fleet(path=TSTCAR):
    """(VehicleSpec list, table): the importer's fleet and, row for row, its identification,
    engine facts and measured mpg per test (NaN where not measured)."""
    from fleetrun.epa import import_test_car_list
    from fleetrun.epa.writer import write_fleet_workbook
    from fleetrun.fleet.workbook import read_fleet

    result = import_test_car_list(path)
    with tempfile.TemporaryDirectory() as tmp:
        book = write_fleet_workbook(result, Path(tmp) / "fleet.xlsx")
        specs = list(read_fleet(book).vehicles)
    measured = pd.DataFrame(result.measured).pivot_table(index="vehicle_id", columns="test", values="mpg")
    table = pd.DataFrame([dict(vehicle_id=v.vehicle_id, manufacturer=v.manufacturer, make=v.make, model=v.model,
                               gearbox_type=v.gearbox_type or v.transmission, configuration=v.configuration,
                               fuel=v.fuel, displacement_L=v.engine_displacement_L, rated_power_kW=v.rated_power_kW,
                               test_weight_kg=v.test_weight_kg, cylinders=v.cylinders,
                               gears=len(v.transmission_gear_ratios)) for v in specs])
    table = table.join(measured.reindex(columns=list(TESTS)), on="vehicle_id")
    d1, d2 = udds_bag_miles()
    table["UDDS:hot"] = (d1 + d2) / (d1 / table["FTP:bag3"] + d2 / table["FTP:bag2"])
    table["specific_power_kW_per_L"] = table.rated_power_kW / table.displacement_L
    return specs, table
