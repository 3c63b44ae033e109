"""The EPA 2022 Test Car List as `fleetrun import-epa` turns it into a fleet, for
validation/epa_fuel_economy.py: the Vehicles rows as `fleetrun run` reads them (the importer's
workbook, read back by the fleet reader) and the measured results, one row per vehicle.

Measured (unadjusted certification values, mpg): ``FTP`` (the composite), ``FTP:bag1..3``,
``HWFET`` (EPA's "HWFE"), ``US06``, and ``UDDS:hot`` = the hot-start UDDS made of bag 3 (the
bag-1 trace driven hot) and bag 2: mpg = (d1 + d2) / (d1 / mpg3 + d2 / mpg2) with d1, d2 the
distances of the UDDS trace before and after 505 s.

``test_rows`` / ``own_fuel_rows``: the list's own rows behind those measured values (all its
columns), for the scripts that look past the Vehicles row (epa_fuel_economy ``--candidates``,
epa_information_bound).
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from fleetrun.cycles import ftp_bag1_end_s

ROOT = Path(__file__).resolve().parents[1]
TSTCAR = ROOT / "inputs" / "epa" / "22-tstcar.csv"
UDDS_BAG1_END_S = ftp_bag1_end_s()
TESTS = ("FTP", "FTP:bag1", "FTP:bag2", "FTP:bag3", "HWFET", "US06")


DT_NOT_RATED = 99.0   # the list's drive-quality ratings (DT-*) hold 99.99 where none was computed


def drive_quality_rating(values) -> pd.Series:
    """A DT-* drive-quality rating column as numbers, its 99.99 placeholders as missing."""
    numbers = pd.to_numeric(values, errors="coerce")
    return numbers.where(numbers.abs() < DT_NOT_RATED)


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
    from fleetrun.workbook.reader import read_fleet

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


def test_rows(path=TSTCAR, derived=False):
    """Every fuel-economy test row (FTP, HWFET, US06) with a valid mpg, with all columns of the
    list, ``vehicle_id``, ``test`` and ``mpg``; without the analytically derived ones (as
    fleetrun/epa/measured.py: with ``own_fuel_rows`` these are the rows the importer's measured
    values are made of), or only those with ``derived=True``."""
    from fleetrun.epa import read_test_car_list
    from fleetrun.epa.rules import constants, fuel_of

    named = read_test_car_list(path)
    raw = pd.read_csv(path, encoding="utf-8-sig", dtype=str)
    raw.columns = [" ".join(c.split()) for c in raw.columns]
    raw["vehicle_id"], raw["csv_row"] = named["vehicle_id"].to_numpy(), named["csv_row"].to_numpy()
    raw["test"] = named["procedure"].map(constants()["procedures"]).to_numpy()
    raw["mpg"] = named["fe_mpg"].to_numpy()
    raw["row_fuel"] = named["fuel_description"].map(fuel_of).to_numpy()
    limit = constants()["measured"]["max_valid_mpg"]
    marks = {str(v).lower() for v in constants()["measured"]["analytically_derived"]}
    adfe = raw["Analytically Derived FE?"].fillna("").str.strip().str.lower().isin(marks).to_numpy()
    return raw[raw.test.notna() & (raw.mpg > 0) & (raw.mpg < limit) & (adfe == derived)]


def own_fuel_rows(rows, table):
    """The rows of ``rows`` (of :func:`test_rows`) on their vehicle's own fuel (the vehicle's
    fuel in ``table``)."""
    fuel = dict(zip(table.vehicle_id, table.fuel))
    return rows[rows.row_fuel.to_numpy() == rows.vehicle_id.map(fuel).to_numpy()]
