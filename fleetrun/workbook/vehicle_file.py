"""A vehicle from a TOML file with the keys of one Vehicles row (like inputs/dyno/*.toml).

Values are parsed by the workbook's rules (:mod:`fleetrun.workbook.rows`, ranges included), so a
TOML vehicle and a workbook row mean the same thing; keys that are not Vehicles columns go to
``VehicleSpec.extra`` (simulation overrides such as ``eta_indicated``).
"""
from __future__ import annotations

import tomllib
from pathlib import Path

from fleetrun.errors import InputError
from fleetrun.workbook import rows
from fleetrun.workbook.schema import VEHICLE_COLUMNS
from fleetrun.vehicle import VehicleSpec


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
    return vehicle_from_mapping(data, path)


def vehicle_from_mapping(data: dict, path: Path) -> VehicleSpec:
    """The VehicleSpec of a Vehicles row given as a mapping (a vehicle TOML file), parsed by
    the workbook's rules (:mod:`fleetrun.workbook.rows`); InputError naming the file and the key
    of the first problem. Warnings (implausible values) are not reported here."""

    def report(name: str, text: str, warning: bool = False):
        if warning:
            return
        raise InputError(text, file=path, column=name, value=data.get(name),
                         hint="The keys are the Vehicles columns of docs/interface.md")

    parsed, _ = rows.parse_fields(VEHICLE_COLUMNS, lambda column: data.get(column.name), report)
    rows.check_vehicle(parsed, report)
    names = {c.name for c in VEHICLE_COLUMNS}
    return rows.vehicle_spec(parsed, {k: v for k, v in data.items() if k not in names})
