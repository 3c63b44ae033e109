"""Reference differentials as data: load ``models/differentials/*.toml`` and resolve geometry.

A model file holds ``[model]`` (id, kind, lubricant, capacity, reference gear ratio),
``[geometry]`` (measured quantities with unit, source and an optional gear-ratio scaling
rule), ``[derived]`` (quantities computed from the scaled geometry) and an ordered list of
``[[stage]]`` components (thesis Eqs 5.23-5.29). Resolution follows Appendix B: geometry
expressions first (unscaled, in file order), then the scaling rules (``x`` = the unscaled
value, ``g`` = the gear ratio asked for, ``G`` = the reference ratio), then derived values.
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from fleetrun.differential.expressions import evaluate
from fleetrun.errors import InputError, unknown_name_error
from fleetrun.physics.lubricant import THESIS_OPERATING_TEMP_C, fluid_properties
from fleetrun.resources import model_file, models_dir


@dataclass(frozen=True)
class ReferenceModel:
    """One measured reference differential (or transfer case / two-speed box)."""

    id: str
    name: str
    source: str
    kind: str                       # "stage_chain", "fixed_efficiency" or "two_speed_box"
    path: Path
    lubricant: str | None = None
    capacity_torque_Nm: float | None = None
    reference_gear_ratio: float | None = None
    output_shafts: int = 1
    efficiency: float | None = None
    geometry: dict = field(default_factory=dict)
    derived: dict = field(default_factory=dict)
    stages: tuple = ()

    def resolve(self, gear_ratio: float, oil_temp_C: float = THESIS_OPERATING_TEMP_C) -> dict:
        """All named quantities for one gear ratio and lubricant temperature."""
        return _resolve(self, float(gear_ratio), float(oil_temp_C))


def _where(model, section, key):
    return f"{model.path.name} [{section}] {key}"


def _resolve(model: ReferenceModel, g: float, oil_temp_C: float) -> dict:
    G = model.reference_gear_ratio
    base = {"g": g, "G": G}
    for key, spec in model.geometry.items():
        base[key] = evaluate(spec["expr"], base, where=_where(model, "geometry", key))
    scaled = dict(base)
    for key, spec in model.geometry.items():
        if "scale" in spec:
            scaled[key] = evaluate(spec["scale"], {**base, "x": base[key]},
                                   where=_where(model, "geometry", f"{key}.scale"))
    for key, spec in model.derived.items():
        scaled[key] = evaluate(spec["expr"], scaled, where=_where(model, "derived", key))
    air = fluid_properties("air", oil_temp_C)
    scaled.update(mu_air=air.mu_Pa_s, rho_air=air.rho_kg_m3, nu_air=air.nu_m2_s)
    if model.lubricant:
        oil = fluid_properties(model.lubricant, oil_temp_C)
        scaled.update(mu_oil=oil.mu_Pa_s, rho_oil=oil.rho_kg_m3, nu_oil=oil.nu_m2_s)
    return scaled


def _load(path: Path) -> ReferenceModel:
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML ({exc})") from None
    head = data.get("model", {})
    for key in ("id", "kind"):
        if key not in head:
            raise InputError(f"{path}: [model] needs '{key}'")
    where = f"{path.name} [model]"
    num = (lambda k: evaluate(head[k], {}, where=f"{where} {k}") if k in head else None)
    return ReferenceModel(
        id=head["id"], name=head.get("name", head["id"]), source=head.get("source", ""),
        kind=head["kind"], path=path, lubricant=head.get("lubricant"),
        capacity_torque_Nm=num("capacity_torque_Nm"), reference_gear_ratio=num("reference_gear_ratio"),
        output_shafts=int(head.get("output_shafts", 1)), efficiency=num("efficiency"),
        geometry=data.get("geometry", {}), derived=data.get("derived", {}),
        stages=tuple(data.get("stage", ())),
    )


@lru_cache(maxsize=None)
def reference_models() -> dict[str, ReferenceModel]:
    """Every model in ``models/differentials/``, keyed by id.

    Returns
    -------
    dict of ReferenceModel, by id.
    """
    out = {}
    for path in sorted((models_dir() / "differentials").glob("*.toml")):
        model = _load(path)
        out[model.id] = model
    return out


def reference_model(model_id: str) -> ReferenceModel:
    """The reference differential ``model_id`` (a file of ``models/differentials/``).

    Parameters
    ----------
    model_id : str, a reference differential id

    Returns
    -------
    ReferenceModel; an unknown id raises the registry's unknown-name error.
    """
    models = reference_models()
    if model_id not in models:
        raise unknown_name_error("reference differential", model_id, models)
    return models[model_id]


@lru_cache(maxsize=None)
def configuration_table() -> dict[str, dict]:
    """``models/configurations.toml``: configuration id -> description, equation, factors.

    Returns
    -------
    dict of dict, the ``configuration`` table by id.
    """
    return model_file("configurations.toml")["configuration"]
