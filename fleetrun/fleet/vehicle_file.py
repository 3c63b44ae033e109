"""A vehicle from a TOML file with the keys of one Vehicles row (like inputs/dyno/*.toml).

Values are parsed with the workbook's cell rules (``fleetrun.fleet.cells``), so a TOML vehicle
and a workbook row mean the same thing; keys that are not Vehicles columns go to
``VehicleSpec.extra`` (simulation overrides such as ``eta_indicated``).
"""
from __future__ import annotations

import tomllib
from pathlib import Path

from fleetrun.errors import InputError
from fleetrun.fleet import cells
from fleetrun.fleet.cells import CellProblem
from fleetrun.fleet.schema import VEHICLE_COLUMNS
from fleetrun.vehicle import VehicleSpec


def _parse(column, raw):
    if column.kind == "number":
        return cells.parse_number(raw)
    if column.kind == "choice":
        if column.name == "configuration":
            from fleetrun.differential import canonical_configuration
            try:
                return canonical_configuration(cells.parse_text(raw))
            except InputError as exc:
                raise CellProblem(f"{cells.show(raw)} is not a configuration ({exc.message})") from None
        return cells.parse_choice(raw, column.choices)
    if column.kind == "ratios":
        return cells.parse_ratios(raw)
    if column.name == "tire_size":
        return cells.parse_tire_size(raw)
    return cells.parse_text(raw)


def read_vehicle_toml(path) -> VehicleSpec:
    """The VehicleSpec in ``path``; InputError naming the file and key on any problem."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError:
        raise InputError("vehicle file not found", file=path, hint="Give a TOML file with the keys of one Vehicles row") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"not a valid TOML file ({exc})", file=path) from None
    except OSError as exc:
        raise InputError(f"cannot read the vehicle file ({exc.strerror})", file=path) from None
    fields = {}
    for column in VEHICLE_COLUMNS:
        raw = data.get(column.name)
        if raw is None or cells.is_blank(raw):
            if column.required:
                what = "is missing" if raw is None else "is empty"
                raise InputError(f"key '{column.name}' {what} ({column.note})", file=path, column=column.name,
                                 hint="Give a value; the keys are the Vehicles columns of CONTRACT.md")
            fields[column.name] = None
            continue
        try:
            value = _parse(column, raw)
        except CellProblem as problem:
            raise InputError(f"{column.name}: {problem}", file=path, column=column.name, value=raw) from None
        if isinstance(value, float):
            if column.strictly_positive and value <= 0:
                raise InputError(f"{column.name}: {value:g} must be greater than 0", file=path, column=column.name)
            if column.minimum is not None and value < column.minimum:
                raise InputError(f"{column.name}: {value:g} must be at least {column.minimum:g}", file=path,
                                 column=column.name)
        fields[column.name] = value
    names = {c.name for c in VEHICLE_COLUMNS}
    extra = {k: v for k, v in data.items() if k not in names}
    return VehicleSpec(**fields, extra=extra)
