"""``manifest.json``: what produced a run's outputs (version, inputs' sha256, physics, timings,
warnings), so a number in a budget document can be traced back and reproduced."""
from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

from fleetrun import __version__
from fleetrun.reports.changes import attribution_inputs, model_files, scenario_totals_dict

SCHEMA = "fleetrun.run/1"


def run_header(result) -> dict:
    """manifest.json's description of the run (schema to warnings): what the report's RunInfo
    and summary.html show; quick to make, unlike the totals and fingerprints that follow it."""
    inputs = [{"role": "fleet workbook", "path": str(result.fleet.path), "sha256": result.fleet.sha256}]
    inputs += [{"role": "drive cycle", "path": path, "sha256": sha}
               for path, sha in sorted(result.cycle_inputs.items())]
    return {
        "schema": SCHEMA,
        "fleetrun_version": __version__,
        "created_utc": result.created_utc,
        "inputs": inputs,
        "physics": result.physics,
        # the --with effects (docs/effects.md) and their parameters: part of the physics used
        "with": [asdict(e) for e in result.effects],
        "mode": result.mode,
        "engine": result.engine.as_json(),
        "scenarios": [s.scenario_id for s in result.scenarios],
        "vehicle_types": len(result.fleet.vehicles),
        "distinct_vehicles_simulated": result.distinct_vehicles,
        "cycles": {name: info.as_json() for name, info in result.cycles.items()},
        "timings_s": {k: round(v, 6) for k, v in result.timings_s.items()},
        "warnings": list(result.warnings),
    }


def manifest_dict(result, outputs: dict[str, str] | None = None) -> dict:
    """manifest.json (docs/interface.md): the run header, the model files, the totals and the
    fingerprints the next run compares with, the comparison with the earlier run, the outputs."""
    models = model_files()   # read and hashed once: listed, and part of the fingerprints
    return {
        **run_header(result),
        "model_files": models,                                    # models/**: constants the numbers come from
        "totals": scenario_totals_dict(result.classes),          # what the next run compares with
        "attribution": attribution_inputs(result, models),        # per fuel factors + input fingerprints
        "changes": result.changes.as_json() if result.changes else None,   # vs the run that was in the folder
        "outputs": outputs or {},
    }


def write_manifest(result, path: Path, outputs: dict[str, str]) -> None:
    Path(path).write_text(json.dumps(manifest_dict(result, outputs), indent=2, default=str) + "\n",
                          encoding="utf-8")


def physics_label(info: dict) -> str:
    """"thesis", or "thesis with bearing_preload (drag_torque_Nm=2)" when --with was used."""
    effects = info.get("with") or []
    if not effects:
        return str(info["physics"])
    parts = [f"{e['effect']} (" + ", ".join(f"{k}={v:g}" for k, v in e["parameters"].items()) + ")"
             for e in effects]
    return f"{info['physics']} with " + "; ".join(parts)
