"""Read an EPA Test Car List CSV ("Data on Cars used for Testing Fuel Economy") into a table
with fleetrun's own column names.

The list has one row per test: a test vehicle and configuration appears once per test
procedure (FTP, HWFE, US06, ...). The file is UTF-8 with a byte-order mark (read with
``encoding="utf-8-sig"``); headers are matched after trimming spaces, case-insensitively,
so other model years of the same format read the same way. See inputs/epa/PROVENANCE.md.
"""
from __future__ import annotations

from pathlib import Path

import pandas as pd

from fleetrun.errors import InputError

# EPA header -> fleetrun name. REQUIRED: without them no vehicle can be built or measured.
REQUIRED_COLUMNS = {
    "Model Year": "model_year",
    "Vehicle Manufacturer Name": "manufacturer",
    "Represented Test Veh Make": "make",
    "Represented Test Veh Model": "model",
    "Test Vehicle ID": "test_vehicle_id",
    "Test Veh Configuration #": "configuration_number",
    "Test Veh Displacement (L)": "displacement_L",
    "Rated Horsepower": "rated_hp",
    "Tested Transmission Type Code": "transmission_code",
    "# of Gears": "gears",
    "Drive System Code": "drive_code",
    "Equivalent Test Weight (lbs.)": "test_weight_lb",
    "Axle Ratio": "axle_ratio",
    "N/V Ratio": "nv_ratio",
    "Target Coef A (lbf)": "coef_A_lbf",
    "Target Coef B (lbf/mph)": "coef_B_lbf_per_mph",
    "Target Coef C (lbf/mph**2)": "coef_C_lbf_per_mph2",
    "Test Procedure Description": "procedure",
    "Test Fuel Type Description": "fuel_description",
    "RND_ADJ_FE": "fe_mpg",
}
# Used when present; a file without them still imports (blank cells).
OPTIONAL_COLUMNS = {
    "Vehicle Type": "vehicle_type",
    "# of Cylinders and Rotors": "cylinders",
    "Transmission Lockup?": "lockup",
    "Test Number": "test_number",
    "FE_UNIT": "fe_unit",
    "FE Bag 1": "fe_bag1",
    "FE Bag 2": "fe_bag2",
    "FE Bag 3": "fe_bag3",
    "Analytically Derived FE?": "analytically_derived",
}
NUMERIC = ("model_year", "configuration_number", "displacement_L", "rated_hp", "gears", "test_weight_lb",
           "axle_ratio", "nv_ratio", "coef_A_lbf", "coef_B_lbf_per_mph", "coef_C_lbf_per_mph2", "fe_mpg",
           "cylinders", "fe_bag1", "fe_bag2", "fe_bag3")
HINT = ("Give the CSV of EPA's Test Car List (\"Data on Cars used for Testing Fuel Economy\", "
        "e.g. inputs/epa/22-tstcar.csv) as downloaded")


def read_test_car_list(path) -> pd.DataFrame:
    """The list in ``path`` with fleetrun column names (REQUIRED_COLUMNS, OPTIONAL_COLUMNS),
    numbers as floats (unreadable cells NaN), text stripped, plus ``csv_row`` (the file's line
    number of the row) and ``vehicle_id`` = ``<Test Vehicle ID>_c<Test Veh Configuration #>``
    (docs/interface.md). Raises :class:`InputError` naming the file for an empty file, a file that is
    not CSV text, or missing columns."""
    path = Path(path)
    table = _read_csv(path)
    table = _rename(table, path)
    if table.empty:
        raise InputError("has a header but no test rows", file=path, hint=HINT)
    for name in NUMERIC:
        if name in table:
            table[name] = pd.to_numeric(table[name], errors="coerce")
    for name in ("manufacturer", "make", "model", "test_vehicle_id", "transmission_code", "drive_code",
                 "procedure", "fuel_description", "vehicle_type", "lockup", "test_number", "fe_unit",
                 "analytically_derived"):
        if name in table:
            table[name] = table[name].fillna("").astype(str).str.strip()
    table["csv_row"] = table.index + 2          # header is line 1
    number = table["configuration_number"].map(lambda x: "" if pd.isna(x) else f"{int(x)}")
    table["vehicle_id"] = table["test_vehicle_id"] + "_c" + number
    return table


def _read_csv(path: Path) -> pd.DataFrame:
    if path.is_dir():
        raise InputError("is a folder, not a CSV file", file=path, hint=HINT)
    if path.stat().st_size == 0:
        raise InputError("is empty", file=path, hint=HINT)
    with open(path, "rb") as handle:
        head = handle.read(4096)
    if b"\x00" in head or head.startswith(b"PK\x03\x04"):
        raise InputError("is not a CSV text file (binary content; an Excel workbook?)", file=path,
                         hint=HINT + "; save a workbook as CSV (UTF-8) first")
    try:
        return pd.read_csv(path, encoding="utf-8-sig", dtype=str, keep_default_na=True)
    except UnicodeDecodeError:
        try:  # older lists were published in Windows-1252
            return pd.read_csv(path, encoding="cp1252", dtype=str, keep_default_na=True)
        except (UnicodeDecodeError, pd.errors.ParserError) as exc:
            raise InputError(f"cannot be read as CSV text ({type(exc).__name__})", file=path, hint=HINT) from None
    except pd.errors.EmptyDataError:
        raise InputError("is empty (no header row)", file=path, hint=HINT) from None
    except pd.errors.ParserError as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"cannot be read as CSV ({first})", file=path, hint=HINT) from None


def _rename(table: pd.DataFrame, path: Path) -> pd.DataFrame:
    by_key = {" ".join(str(c).split()).lower(): c for c in table.columns}
    mapping, missing = {}, []
    for epa, name in {**REQUIRED_COLUMNS, **OPTIONAL_COLUMNS}.items():
        found = by_key.get(epa.lower())
        if found is not None:
            mapping[found] = name
        elif epa in REQUIRED_COLUMNS:
            missing.append(epa)
    if missing:
        shown = ", ".join(f"'{m}'" for m in missing)
        noun = "column" if len(missing) == 1 else "columns"
        raise InputError(f"is not an EPA Test Car List in the expected format: missing {noun} {shown} "
                         f"({len(table.columns)} columns found)", file=path, hint=HINT)
    return table[list(mapping)].rename(columns=mapping)
