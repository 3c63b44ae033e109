"""One owner of what a sheet row means: a cell's typed value within its physical range, and the
rules of a Vehicles row (configuration vs duty class, two-speed axles, plausibility).

The fleet workbook (``workbook.py``), a vehicle TOML (``vehicle_file.py``) and a diagnose
sidecar all parse through here, so a value means the same wherever it is typed. Problems are
handed to a ``report(column_name, text, warning=False)`` callback, which the caller turns into
a cell reference (``Vehicles!H4 peak_engine_torque_Nm: ...``) or a TOML key.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from functools import lru_cache

from fleetrun.differential import canonical_configuration
from fleetrun.errors import InputError, closest_names
from fleetrun.physics.lubricant import lubricant_names
from fleetrun.vehicle import VehicleSpec, vehicle_from_fields
from fleetrun.workbook import cells
from fleetrun.workbook.cells import CellProblem
from fleetrun.workbook.schema import DUAL_CONFIGURATIONS, FHWA_CLASSES, PLAUSIBLE_VEHICLE, VEHICLE_COLUMNS, Column

MAX_GEARS = 20

Report = Callable[..., None]     # report(column_name, text, warning=False)


DEFAULT_MIX = "default"   # cycle_mix = default (docs/registrations.md)


def parse_value(column: Column, raw):
    """The typed value of a non-blank cell of ``column``, inside the column's physical range;
    CellProblem (quoting the value) otherwise."""
    if type(raw) is float and column.kind == "number":
        low, high = number_bounds(column)
        if low <= raw <= high:          # the common case: a number cell within its range
            return raw
    if type(raw) is str:
        return _parse_text_cached(column, raw)
    if column.kind == "number" and type(raw) in (int, float):
        value = cells.parse_number(raw)
    else:
        value = _parse(column, raw)
    check_range(column, value, raw)
    return value


@lru_cache(maxsize=65536)
def _parse_text_cached(column: Column, raw: str):
    """Text cells: ids differ, but choices, ratios and tyres repeat a lot."""
    value = _parse(column, raw)
    check_range(column, value, raw)
    return value


def _parse(column: Column, raw):
    kind = column.kind
    if kind == "number":
        if isinstance(raw, str) and raw.strip().endswith("%") and column.name.endswith(PERCENT_SUFFIXES):
            return cells.parse_number(raw.strip()[:-1])   # "1.2%" typed as text: the percentage shown
        return cells.parse_number(raw)
    if kind == "integer":
        return cells.parse_integer(raw)
    if kind == "choice":
        if column.name == "configuration":
            return _canonical_configuration(raw)
        return cells.parse_choice(raw, column.choices)
    if kind == "ratios":
        ratios = cells.parse_ratios(raw)
        if len(ratios) > MAX_GEARS:
            raise CellProblem(f"{cells.show(raw)} lists {len(ratios)} gears; at most {MAX_GEARS}")
        return ratios
    if kind == "cycle_mix":
        if isinstance(raw, str) and raw.strip().lower() == DEFAULT_MIX:
            return DEFAULT_MIX   # each duty class's documented mix (reader._default_mixes)
        return cells.parse_cycle_mix(raw)
    if kind == "onroad":
        return cells.parse_onroad(raw)
    if kind == "schedule":
        return cells.parse_schedule(raw)
    if kind == "class_shares":
        return cells.parse_class_shares(raw, FHWA_CLASSES)
    if column.name == "tire_size":
        return cells.parse_tire_size(raw)
    if column.name == "lubricant":
        return _lubricant(raw)
    if column.name.endswith("_id"):
        return cells.parse_id(raw)
    return cells.parse_text(raw)


def _lubricant(raw) -> str:
    text = cells.parse_text(raw)
    known = lubricant_names()
    if text.upper() not in known:
        near = closest_names(text, known)
        guess = f" (did you mean {near[0]}?)" if near else ""
        raise CellProblem(f"{cells.show(raw)} is not a lubricant fleetrun knows{guess}; known: "
                          f"{', '.join(known)} (models/lubricants.toml)")
    return text


def check_range(column: Column, value, raw) -> None:
    """CellProblem if a number of ``value`` (each ratio of a list) lies outside the column's
    physical range (schema.py)."""
    if not column.numeric or isinstance(value, str):
        return
    numbers = tuple(value.values()) if isinstance(value, dict) else value
    for number in (numbers if isinstance(numbers, tuple) else (numbers,)):
        problem = _out_of_range(column, number)
        if problem:
            shown = cells.show(raw) if number == value else f"{cells.show(raw)}: {number:g}"
            raise CellProblem(f"{shown} {problem} (the range of {column.name} is "
                              f"{column.range_text()}; check the units)")


@lru_cache(maxsize=None)
def number_bounds(column: Column) -> tuple[float, float]:
    """The closed interval of a number column's range (strictly positive: from the smallest
    positive float); NaN never lies inside."""
    low = -math.inf if column.minimum is None else float(column.minimum)
    if column.strictly_positive:
        low = max(low, math.nextafter(0.0, 1.0))
    return low, math.inf if column.maximum is None else float(column.maximum)


def _out_of_range(column: Column, number: float) -> str | None:
    if column.strictly_positive and number <= 0:
        return "must be greater than 0"
    if column.minimum is not None and number < column.minimum:
        return f"must be at least {column.minimum:g}"
    if column.maximum is not None and number > column.maximum:
        return f"must be at most {column.maximum:g}"
    return None


def comma_reading(column: Column, raw) -> str | None:
    """A warning for a text cell that :func:`parse_value` read with its comma as a thousands
    separator (``1,500`` as 1500) when the comma could as well be a decimal comma (1.5) giving
    a value the column takes as usual: within its range and its usual range, and whole for a
    count. None otherwise (``1,234,567``, ``1,234.5``, or a decimal reading out of place)."""
    if column.kind != "number" or type(raw) is not str or "," not in raw:
        return None
    decimal = cells.decimal_comma_reading(raw)
    if decimal is None or _out_of_range(column, decimal) or (column.name == "count" and not decimal.is_integer()):
        return None
    usual = column.plausible.values() if isinstance(column.plausible, dict) else [column.plausible or (decimal, decimal)]
    if not min(low for low, _ in usual) <= decimal <= max(high for _, high in usual):
        return None
    return (f"{cells.show(raw)} is read as {cells.parse_number(raw):g}, the comma a thousands separator; if it is a "
            f"decimal comma, type {decimal:g}")


def _canonical_configuration(raw) -> str:
    text = cells.parse_text(raw)
    try:
        return canonical_configuration(text)
    except InputError as exc:
        raise CellProblem(f"{cells.show(raw)} is not a configuration ({exc.message})") from None


def scanned_cell(column: Column, note: str, raw):
    """What the pre-scan (:mod:`fleetrun.workbook.xlsx_safety`) noted of a cell the reader sees
    as ``raw``: (the problem, None) for a formula without a saved result or an Excel error value
    (``#REF!``, ``#N/A``, ``#DIV/0!``: the reader sees them as blank); (None, the value) else,
    where a percent-formatted number in a percent column (``1.2%`` stored as 0.012) is taken as
    the percentage it shows."""
    from fleetrun.workbook.xlsx_safety import PERCENT

    if note == PERCENT:
        if column.name.endswith(PERCENT_SUFFIXES) and type(raw) in (int, float):
            return None, raw * 100.0
        return None, raw
    if note.startswith("#"):
        return (f"holds the Excel error {cells.show(note)} (a formula that fails, or a broken "
                "reference); fix the formula or type the value"), None
    return (f"formula {cells.show(note)} has no saved result; open and save the workbook in Excel or "
            "LibreOffice (or type the value)"), None


PERCENT_SUFFIXES = ("_pct", "_pct_per_year")   # columns in percent: a 1.2 % cell means 1.2


def parse_fields(columns, raw_of: Callable[[Column], object], report: Report) -> tuple[dict, bool]:
    """Every column's typed value (None when blank or bad) and whether all were good.
    ``raw_of(column)`` gives the raw cell (None when the column is absent)."""
    parsed: dict = {}
    ok = True
    for column in columns:
        raw = raw_of(column)
        if raw is None or cells.is_blank(raw):
            if column.required:
                report(column.name, "is empty (required)")
                ok = False
            parsed[column.name] = None
            continue
        try:
            parsed[column.name] = parse_value(column, raw)
        except CellProblem as problem:
            report(column.name, str(problem))
            parsed[column.name] = None
            ok = False
            continue
        if comma := comma_reading(column, raw):
            report(column.name, comma, warning=True)
    return parsed, ok


def check_vehicle(p: dict, report: Report) -> bool:
    """The rules across a Vehicles row's cells; warnings for implausible values. May clear
    ``low_gear_ratio`` (ignored on a one-speed axle). Returns whether the row is usable."""
    ok = True
    config, duty = p.get("configuration"), p.get("duty_class")
    if config is not None:
        if duty is not None and config.startswith("LD_") != (duty == "LD"):
            report("configuration", f"'{config}' does not fit duty_class {duty} (LD vehicles use LD_* "
                   "configurations, MD and HD vehicles HD_*)")
            ok = False
        if config in DUAL_CONFIGURATIONS and p.get("low_gear_ratio") is None:
            report("low_gear_ratio", f"is empty, but {config} (a two-speed axle) needs its low ratio")
            ok = False
        if config not in DUAL_CONFIGURATIONS and p.get("low_gear_ratio") is not None:
            report("low_gear_ratio", f"ignored: {config} has no two-speed axle", warning=True)
            p["low_gear_ratio"] = None
    ratios = p.get("transmission_gear_ratios") or ()
    if list(ratios) != sorted(ratios, reverse=True):   # some later gear above an earlier one
        report("transmission_gear_ratios", f"{', '.join(f'{r:g}' for r in ratios)} is not in falling "
               "order (first gear first?)", warning=True)
    _vehicle_plausible(p, report)
    _label_pair(p, report)
    return ok


def _label_pair(p: dict, report: Report) -> None:
    """A warning when one of the label's city and highway figures is given without the other:
    the pair is used only together (docs/workbook.md)."""
    city, highway = p.get("label_city_mpg"), p.get("label_highway_mpg")
    if (city is None) != (highway is None):
        given, missing = ("label_city_mpg", "label_highway_mpg") if highway is None else (
            "label_highway_mpg", "label_city_mpg")
        report(given, f"ignored: {missing} is empty (the label's city and highway figures are used together; "
               "give both, or the combined figure in label_combined_mpg)", warning=True)


def fractional_count(count) -> str | None:
    """The warning for a count of vehicles that is not a whole number (a Vehicles or
    Registrations row); None for a whole one. Three decimals may be a point typed as a
    thousands separator (2.524 for 2524 where the decimal mark is a comma)."""
    if count is None or count == int(count):
        return None
    thousandths = count * 1000
    grouped = 1 <= count < 1000 and abs(thousandths - round(thousandths)) < 1e-6 and round(thousandths) % 10 != 0
    return (f"{count:g} vehicles is not a whole number; totals use it as given"
            + (f" (if the point is a thousands separator, type {round(count * 1000)})" if grouped else ""))


def _vehicle_plausible(p: dict, report: Report) -> None:
    duty = p.get("duty_class")
    if duty is not None:
        for name, ranges in PLAUSIBLE_VEHICLE.items():
            if name == "final_drive_ratio" and p.get("fuel") == "electric":
                continue   # an electric drive's single reduction (7-10:1) is its final drive
            low, high = ranges[duty]
            value = p.get(name)
            if value is not None and not (low <= value <= high):
                report(name, f"{value:g} is unusual for a {duty} vehicle (expected {low:g} to "
                       f"{high:g}); check the units", warning=True)
    count, miles = p.get("count"), p.get("annual_miles")
    if note := fractional_count(count):
        report("count", note, warning=True)
    if count == 0:
        report("count", "0 vehicles: this row adds nothing", warning=True)
    if miles == 0:
        report("annual_miles", "0 miles: this row adds nothing", warning=True)


def check_temperature_budget(temperatures: list[tuple[int, float]], report_at) -> None:
    """At most :data:`fleetrun.plausible.MAX_AMBIENT_TEMPERATURES` distinct ambient
    temperatures (row, temperature) per workbook: ``report_at(row, text)`` at the first beyond."""
    from fleetrun.plausible import MAX_AMBIENT_TEMPERATURES

    seen: set[float] = set()
    for row, temperature in temperatures:
        seen.add(temperature)
        if len(seen) > MAX_AMBIENT_TEMPERATURES:
            report_at(row, f"{temperature:g} is distinct ambient temperature number {len(seen)}; a workbook "
                      f"runs at most {MAX_AMBIENT_TEMPERATURES} (each costs an efficiency map per axle); "
                      "round the temperatures, or split the scenarios over workbooks")
            return
_VEHICLE_NAMES = tuple(c.name for c in VEHICLE_COLUMNS)
_READER_KEYS = _VEHICLE_NAMES + ("_extra",)   # a parsed Vehicles row (workbook.reader._parse_row)


def vehicle_spec(parsed: dict, extra: dict) -> VehicleSpec:
    """The VehicleSpec of a checked row (``parsed`` keyed by Vehicles column)."""
    if tuple(parsed) == _READER_KEYS:    # the reader's row: these keys in this order, copied whole
        values = parsed.copy()
        del values["_extra"]
    else:
        get = parsed.get
        values = {name: get(name) for name in _VEHICLE_NAMES}
    values["extra"] = extra
    return vehicle_from_fields(values)
