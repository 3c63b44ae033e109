"""From the list's test rows to fleet-workbook rows: one Vehicles row per test vehicle and
configuration, what was derived for it and how, the vehicles that cannot be modelled (with
the reason) and the measured fuel economy of each modelled vehicle.

Rules (docs/epa-import.md; constants in models/epa_import.toml via :mod:`fleetrun.epa.rules`):

- The vehicle's facts (engine, gearbox, drive, weight, road load, axle ratio, N/V) come from
  its first row of a fuel-economy test (FTP, HWFE, US06) on a fleetrun fuel, else its first row.
- Duplicate tests of one configuration (several rows of one test, e.g. 2-day and 3-day FTP
  runs or repeats) are combined into one measured value by the harmonic mean (the mean fuel
  per mile), with the number of rows and their test numbers kept beside it.
- A vehicle is excluded, with the first reason that applies: electric or plug-in (its test
  vehicle has electricity-fuel or charge-depleting tests), fuel cell, hybrid by model name,
  no test on gasoline or diesel, an unknown transmission or drive code, an axle ratio, N/V,
  power, displacement or weight missing or out of range, missing road-load coefficients, no
  generic gear set for its gear count, or the hybrid signature (FTP composite mpg at least
  ``city_highway_ratio`` of HWFE mpg).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import pandas as pd

from fleetrun.epa import rules
from fleetrun.epa.measured import measured_results
from fleetrun.epa.technology import match_configuration
from fleetrun.epa.vehicle import vehicle_row
from fleetrun.workbook.schema import VEHICLE_COLUMNS, columns_by_name


@dataclass
class ImportResult:
    vehicles: list[dict] = field(default_factory=list)   # Vehicles rows (workbook column -> value)
    derived: list[dict] = field(default_factory=list)    # vehicle_id, column, value, rule
    excluded: list[dict] = field(default_factory=list)   # identification + rule + reason
    measured: list[dict] = field(default_factory=list)   # vehicle_id, test, mpg, ...
    rows_read: int = 0
    rows_selected: int = 0


ID_FIELDS = ("manufacturer", "make", "model", "model_year")


def select_rows(table: pd.DataFrame, model_years=(), makes=()) -> pd.DataFrame:
    """The rows of the model years and makes asked for (all when none; makes case-insensitive)."""
    keep = pd.Series(True, index=table.index)
    if model_years:
        keep &= table["model_year"].isin([float(y) for y in model_years])
    if makes:
        wanted = {m.strip().lower() for m in makes}
        keep &= table["make"].str.lower().isin(wanted) | table["manufacturer"].str.lower().isin(wanted)
    return table[keep]


def import_rows(table: pd.DataFrame, model_years=(), makes=()) -> ImportResult:
    """Vehicles, derivations, exclusions and measured results of the list ``table``
    (:func:`fleetrun.epa.reader.read_test_car_list`)."""
    result = ImportResult(rows_read=len(table))
    table = select_rows(table, model_years, makes)
    result.rows_selected = len(table)
    c = rules.constants()
    table = table.assign(test=table["procedure"].map(c["procedures"]),
                         fuel=table["fuel_description"].map(rules.fuel_of))
    # plain dicts per row: grouping ~1,000 configurations in pandas costs seconds
    records = table.astype(object).where(table.notna(), None).to_dict("records")
    groups: dict[str, list[dict]] = {}
    for record in records:
        groups.setdefault(record["vehicle_id"], []).append(record)
    electric = _electric_test_vehicles(records)
    for vehicle_id, rows in groups.items():
        facts = _facts(rows)
        ident = {"vehicle_id": vehicle_id, **{k: _plain(facts[k]) for k in ID_FIELDS},
                 "csv_rows": ",".join(str(r["csv_row"]) for r in rows)}
        reason = electric.get(facts["test_vehicle_id"]) or _static_reason(rows, facts)
        measured = [] if reason else measured_results(rows, facts["fuel"])
        reason = reason or _signature_reason(measured)
        if reason:
            result.excluded.append({**ident, "rule": reason[0], "reason": reason[1]})
            continue
        row, derived = vehicle_row(vehicle_id, facts)
        match = match_configuration(facts["manufacturer"], facts["displacement_L"], facts["coef_A_lbf"],
                                    facts["coef_B_lbf_per_mph"], facts["coef_C_lbf_per_mph2"])
        row["technology"] = (match.technology or "none") if match.omega_vehicle else None
        derived.append({"vehicle_id": vehicle_id, "column": "technology", "value": match.technology, "rule": match.note})
        result.vehicles.append(row)
        result.derived += derived
        result.measured += [{"vehicle_id": vehicle_id, **m, **{k: ident[k] for k in ID_FIELDS}} for m in measured]
    return result


def _plain(value):
    if isinstance(value, float) and value.is_integer():
        return int(value)
    return value


def _facts(rows: list[dict]) -> dict:
    """The row whose facts describe the vehicle: first fuel-economy test on a fleetrun fuel."""
    for keep in (lambda r: r["test"] and r["fuel"], lambda r: r["fuel"]):
        for row in rows:
            if keep(row):
                return row
    return rows[0]


def _electric_test_vehicles(records: list[dict]) -> dict[str, tuple[str, str]]:
    """Test vehicle id -> exclusion reason, for vehicles tested on electricity or hydrogen or
    in charge-depleting mode (every configuration of that test vehicle)."""
    seen: dict[str, set] = {}
    for r in records:
        flags = seen.setdefault(r["test_vehicle_id"], set())
        desc = r["fuel_description"].lower()
        if "hydrogen" in desc:
            flags.add("hydrogen")
        if "electric" in desc or "charge depleting" in r["procedure"].lower():
            flags.add("electric")
        if r["fuel"]:
            flags.add("fuel")
    reasons: dict[str, tuple[str, str]] = {}
    for tvid, flags in seen.items():
        if "hydrogen" in flags:
            reasons[tvid] = ("fuel_cell", "fuel-cell vehicle (tested on hydrogen): not modelled")
        elif "electric" in flags and "fuel" in flags:
            reasons[tvid] = ("plug_in_hybrid", "plug-in hybrid (charge-depleting or electricity tests): not modelled")
        elif "electric" in flags:
            reasons[tvid] = ("electric", "electric vehicle (tested on electricity): not modelled")
    return reasons


def _static_reason(rows: list[dict], f: dict) -> tuple[str, str] | None:
    """(rule, reason) if the vehicle's own facts rule it out, else None."""
    c = rules.constants()
    pattern = rules.hybrid_name_match(f["model"])
    if pattern:
        return "hybrid_name", f"hybrid (model name '{f['model']}' matches '{pattern}'): not modelled"
    if not f["fuel"]:
        fuels = "; ".join(sorted({r["fuel_description"] for r in rows})) or "none given"
        return "fuel", f"unsupported fuel ({fuels}): fleetrun models gasoline and diesel"
    if f["transmission_code"] not in c["transmissions"]:
        return "transmission", f"transmission type code '{f['transmission_code']}' is not modelled"
    if f["drive_code"] not in c["drives"]:
        return "drive", f"drive system code '{f['drive_code']}' is not modelled"
    power_kW = None if f["rated_hp"] is None else f["rated_hp"] * c["units"]["hp_to_kW"]
    checks = (("Axle Ratio", f["axle_ratio"], "final_drive_ratio", ""),
              ("N/V Ratio", f["nv_ratio"], "nv_ratio_rpm_per_mph", " rpm/mph"),
              ("Rated Horsepower", power_kW, "rated_power_kW", " kW"),
              ("Test Veh Displacement (L)", f["displacement_L"], "displacement_L", " L"),
              ("Equivalent Test Weight (lbs.)", f["test_weight_lb"], "test_weight_lb", " lb"),
              ("Target Coef A (lbf)", f["coef_A_lbf"], None, ""),
              ("Target Coef B (lbf/mph)", f["coef_B_lbf_per_mph"], None, ""),
              ("Target Coef C (lbf/mph**2)", f["coef_C_lbf_per_mph2"], None, ""))
    for label, value, range_key, unit in checks:
        if value is None or math.isnan(value):
            return "missing_value", f"{label} is missing or not a number"
        low, high = _range(range_key)
        if not low <= value <= high:
            return "out_of_range", f"{label} {value:.4g}{unit} is outside the usable range {low:g}-{high:g}{unit}"
    gearbox = c["transmissions"][f["transmission_code"]][0]
    if gearbox != "cvt" and (f["gears"] is None or rules.generic_gear_set(f["gears"]) is None):
        known = ", ".join(sorted(c["gears"], key=int))
        return "gear_count", f"no generic gear set for {_plain(f['gears'])} gears (sets for {known})"
    return None


def _range(key: str | None) -> tuple[float, float]:
    """[min, max] of a checked value: the workbook schema's for final_drive_ratio (what
    `fleetrun validate` accepts), else ``[ranges]`` of the constants file."""
    if key is None:
        return -math.inf, math.inf
    if key == "final_drive_ratio":
        column = columns_by_name(VEHICLE_COLUMNS)[key]
        return column.minimum, column.maximum
    return tuple(rules.constants()["ranges"][key])


def _signature_reason(measured: list[dict]) -> tuple[str, str] | None:
    by_test = {m["test"]: m["mpg"] for m in measured}
    limit = rules.constants()["hybrids"]["city_highway_ratio"]
    if "FTP" in by_test and "HWFET" in by_test and by_test["FTP"] >= limit * by_test["HWFET"]:
        ratio = by_test["FTP"] / by_test["HWFET"]
        return "hybrid_signature", (f"hybrid signature: FTP composite {by_test['FTP']:.1f} mpg is {ratio:.0%} of HWFE "
                f"{by_test['HWFET']:.1f} mpg (conventional vehicles stay below {limit:.0%}): not modelled")
    return None
