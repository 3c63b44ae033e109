"""The shipped vehicle library: which simulated vehicle stands for a registration row.

Data: ``models/vehicle_library/library.toml`` (light duty from the EPA 2022 Test Car List,
weighted by EPA OMEGA MY2022 segment sales; medium and heavy duty interim entries) and, when
present, ``models/heavy_duty/fhwa_classes.toml`` (one reference vehicle per FHWA class), which
replaces the interim entries of its classes and fuels. Rules (docs/registrations.md):

1. a row with ``vehicle_id``: that Vehicles row;
2. a row with ``make`` and ``model``: of the EPA 2022 Test Car List configurations of that make
   whose model starts with the given model (case, spaces and punctuation ignored; the row's
   fuel where there are such), the one of median test weight;
3. otherwise the class's default mix for the fuel (the library vehicles of that class and fuel,
   by their weights); a class or fuel without one borrows as listed in :data:`BORROW`.
"""
from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from fleetrun.resources import models_dir

LIBRARY_FILE = ("vehicle_library", "library.toml")
HEAVY_FILE = ("heavy_duty", "fhwa_classes.toml")
# (class, fuel) without library vehicles -> (class, fuel) whose vehicles stand in, and why
BORROW = {
    ("automobile", "diesel"): ("light_truck", "diesel", "no diesel car in the library: the diesel light truck"),
    ("motorcycle", "gasoline"): ("automobile", "gasoline",
                                 "no motorcycle in the library: the automobile mix (overstates fuel per mile)"),
    ("combination_truck", "gasoline"): ("single_unit_truck", "gasoline",
                                        "no gasoline tractor in the library: the gasoline single-unit truck"),
}


@dataclass(frozen=True)
class LibraryVehicle:
    library_id: str
    fhwa_class: str
    weight: float
    source: str
    interim: bool
    row: tuple          # (column, value) pairs of a Vehicles row (no id, class, count, miles)

    @property
    def fuel(self) -> str:
        return dict(self.row)["fuel"]

    @property
    def model_year(self) -> int | None:
        return dict(self.row).get("model_year")


def _load(parts) -> dict | None:
    path = Path(models_dir()).joinpath(*parts)
    if not path.is_file():
        return None
    with open(path, "rb") as fh:
        return tomllib.load(fh)


def _vehicle(entry: dict, library_id: str, fhwa_class: str, interim: bool) -> LibraryVehicle:
    meta = {"library_id", "fhwa_class", "weight", "source", "interim", "vehicle_id", "vehicle_class", "count",
            "annual_miles"}
    row = tuple(sorted((k, v) for k, v in entry.items() if k not in meta))
    return LibraryVehicle(library_id, fhwa_class, float(entry.get("weight", 1.0)), str(entry.get("source", "")),
                          interim, row)


@lru_cache(maxsize=1)
def library() -> tuple[LibraryVehicle, ...]:
    """Every library vehicle; the FHWA-class reference vehicles replace the interim ones."""
    own = [_vehicle(e, e["library_id"], e["fhwa_class"], bool(e.get("interim", False)))
           for e in _load(LIBRARY_FILE)["vehicle"]]
    heavy = _load(HEAVY_FILE) or {}
    replaced = {(name, entry.get("fuel")) for name, entry in heavy.items() if isinstance(entry, dict)}
    found = [v for v in own if not (v.interim and (v.fhwa_class, v.fuel) in replaced)]
    for name, entry in heavy.items():
        if isinstance(entry, dict):
            found.append(_vehicle(entry, f"FHWA-{name}", name, False))
    return tuple(found)


def class_mix(fhwa_class: str, fuel: str) -> tuple[list[tuple[LibraryVehicle, float]], str]:
    """The library vehicles (with shares summing to 1) that stand for ``fuel`` vehicles of
    ``fhwa_class``, and what was assumed ("" when the class has its own)."""
    assumed = ""
    members = [v for v in library() if v.fhwa_class == fhwa_class and v.fuel == fuel]
    if not members and (fhwa_class, fuel) in BORROW:
        other_class, other_fuel, assumed = BORROW[(fhwa_class, fuel)]
        members = [v for v in library() if v.fhwa_class == other_class and v.fuel == other_fuel]
    if not members:
        return [], f"no {fuel} vehicle of class {fhwa_class} in the library"
    total = sum(v.weight for v in members)
    return [(v, v.weight / total) for v in members], assumed


def _key(text) -> str:
    return re.sub(r"[^a-z0-9]", "", str(text).lower())


@lru_cache(maxsize=1)
def _epa_index() -> dict[str, list[dict]]:
    """EPA 2022 Test Car List configurations (as `import-epa` derives them) by make."""
    from fleetrun.epa import import_test_car_list
    from fleetrun.resources import inputs_dir

    index: dict[str, list[dict]] = {}
    for row in import_test_car_list(Path(inputs_dir()) / "epa" / "22-tstcar.csv").vehicles:
        index.setdefault(_key(row["make"]), []).append({**row, "_model_key": _key(row["model"])})
    return index


@lru_cache(maxsize=65536)
def match_make_model(make: str, model: str, fuel: str) -> tuple[tuple[LibraryVehicle, ...], str]:
    """The Test Car List configurations of ``make`` whose model starts with ``model`` (of
    ``fuel`` where any is), as library vehicles, and what they were matched on."""
    candidates = _epa_index().get(_key(make), [])
    wanted = _key(model)
    hits = [r for r in candidates if wanted and r["_model_key"].startswith(wanted)] if wanted else []
    if not hits:
        return (), ""
    same_fuel = [r for r in hits if r["fuel"] == fuel]
    chosen = sorted(same_fuel or hits, key=lambda r: (r["test_weight_kg"], r["vehicle_id"]))
    r = chosen[(len(chosen) - 1) // 2]
    note = (f"make + model: EPA 2022 test configuration {r['vehicle_id']} ({r['make']} {r['model']}), the median "
            f"test weight of {len(chosen)}")
    if not same_fuel:
        note += f"; none is {fuel}: used as {fuel}"
    return (_vehicle({**{k: v for k, v in r.items() if not k.startswith("_")}, "fuel": fuel},
                     f"EPA:{r['vehicle_id']}", "", False),), note
