"""What changed since the run already in the output folder: inputs (sha256) and totals.

A run into a folder that holds an earlier run reads the earlier ``manifest.json`` (its
inputs' sha256 and, from this version on, its totals by scenario; older manifests: the totals
are summed from its ``class_summary.csv``) and compares. The comparison goes into the log,
``summary.html``, the ``What changed`` sheet and ``manifest.json``. The earlier run's files
are kept in ``earlier-runs/<its creation time>/`` of the new folder unless ``--replace``.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import pandas as pd

from fleetrun.budget.result import InputChange, RunChanges, TotalChange

EARLIER_DIR = "earlier-runs"
TOTAL_COLUMNS = ("fuel_gal_total", "state_tax_usd", "federal_tax_usd", "kwh_total", "ev_fee_usd")


def scenario_totals_dict(classes: pd.DataFrame) -> dict[str, dict[str, float]]:
    """Per scenario the totals the comparison looks at (exact sums of the class rows)."""
    out: dict[str, dict[str, float]] = {}
    for scenario_id, group in classes.groupby("scenario_id", sort=False):
        out[str(scenario_id)] = {c: math.fsum(group[c]) for c in TOTAL_COLUMNS if c in group}
    return out


def read_earlier(out_dir: Path) -> dict | None:
    """The earlier run in ``out_dir``: its manifest with ``totals`` filled in; None if none
    (or its manifest cannot be read: then there is nothing to compare, said in the log)."""
    manifest = Path(out_dir) / "manifest.json"
    if not manifest.is_file():
        return None
    try:
        data = json.loads(manifest.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict):
        return None
    if not isinstance(data.get("totals"), dict):
        classes = Path(out_dir) / "class_summary.csv"
        try:
            data["totals"] = scenario_totals_dict(pd.read_csv(classes)) if classes.is_file() else {}
        except (OSError, ValueError, KeyError):
            data["totals"] = {}
    return data


def compare(earlier: dict, inputs: list[dict], totals: dict[str, dict[str, float]]) -> RunChanges:
    """Inputs added, removed or changed (by sha256) and totals by scenario, earlier vs now."""
    before = {item.get("path"): item.get("sha256") for item in earlier.get("inputs", []) if isinstance(item, dict)}
    now = {item["path"]: item["sha256"] for item in inputs}
    changed_inputs = []
    for path in sorted(set(before) | set(now), key=str):
        status = ("added" if path not in before else "removed" if path not in now
                  else "changed" if before[path] != now[path] else "same")
        changed_inputs.append(InputChange(path=path, status=status, earlier_sha256=before.get(path),
                                          sha256=now.get(path)))
    rows = []
    earlier_totals = earlier.get("totals") or {}
    for scenario_id in list(totals) + [s for s in earlier_totals if s not in totals]:
        for column in TOTAL_COLUMNS:
            old = (earlier_totals.get(scenario_id) or {}).get(column)
            new = (totals.get(scenario_id) or {}).get(column)
            if old is None and new is None:
                continue
            change = (new / old - 1.0) if (old and new is not None) else None
            rows.append(TotalChange(scenario_id=scenario_id, total=column, earlier=old, now=new, change_pct=change))
    return RunChanges(earlier_created_utc=earlier.get("created_utc", ""),
                      earlier_version=earlier.get("fleetrun_version", ""), inputs=tuple(changed_inputs),
                      totals=tuple(rows))


def describe(changes: RunChanges) -> list[str]:
    """Log lines: which inputs changed and how each scenario's totals moved."""
    lines = [f"compared with the earlier run of {changes.earlier_created_utc or 'unknown time'} in this folder"]
    for item in changes.inputs:
        if item.status != "same":
            lines.append(f"input {item.status}: {item.path}")
    if all(item.status == "same" for item in changes.inputs):
        lines.append("inputs unchanged (same sha256)")
    for row in changes.totals:
        if row.earlier is None or row.now is None:
            lines.append(f"{row.scenario_id} {row.total}: "
                         + ("new scenario" if row.earlier is None else "scenario no longer run"))
        elif row.earlier != row.now:
            change = f" ({row.change_pct:+.2%})" if row.change_pct is not None else ""
            lines.append(f"{row.scenario_id} {row.total}: {row.earlier:,.0f} -> {row.now:,.0f}{change}")
    return lines


def earlier_run_name(earlier: dict) -> str:
    """A folder name for the kept earlier run: its creation time, file-name safe."""
    stamp = str(earlier.get("created_utc") or "unknown").replace(":", "").replace("+0000", "Z")
    return "".join(ch if ch.isalnum() or ch in "-_.TZ" else "_" for ch in stamp) or "unknown"


def keep_earlier_run(out_dir: Path, staging: Path, earlier: dict, files) -> Path:
    """Copy the earlier run's ``files`` into ``staging/earlier-runs/<its time>/`` and carry over
    the runs it kept itself, so the new folder holds every earlier run; the kept folder."""
    import shutil

    import hashlib

    out_dir, staging = Path(out_dir), Path(staging)
    digest = hashlib.sha256((out_dir / "manifest.json").read_bytes()).hexdigest()[:8]
    kept = staging / EARLIER_DIR / f"{earlier_run_name(earlier)}-{digest}"
    kept.mkdir(parents=True, exist_ok=True)
    for name in files:
        if (out_dir / name).is_file():
            shutil.copy2(out_dir / name, kept / name)
    older = out_dir / EARLIER_DIR
    if older.is_dir():
        for item in sorted(older.iterdir()):
            if item.is_dir() and not (staging / EARLIER_DIR / item.name).exists():
                shutil.copytree(item, staging / EARLIER_DIR / item.name)
    return kept
