"""What changed since the run already in the output folder: inputs (sha256) and totals.

A run into a folder that holds an earlier run reads the earlier ``manifest.json`` (its
inputs' sha256 and, from this version on, its totals by scenario; older manifests: the totals
are summed from its ``class_summary.csv``) and compares. The comparison goes into the log,
``summary.html``, the ``What changed`` sheet and ``manifest.json``. The earlier run's files
are kept in ``earlier-runs/<its creation time>-<manifest hash>/`` of the new folder unless
``--replace``; beyond the newest ``--keep-runs`` (``KEEP_RUNS``) the oldest are removed
(:func:`prune_earlier_runs`: only folders and files fleetrun wrote there).
"""
from __future__ import annotations

import hashlib
import json
import math
import re
import shutil
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from fleetrun.budget.result import ChangeCause, InputChange, RunChanges, TotalChange
from fleetrun.fileio import JsonDocument, link_or_copy

EARLIER_DIR = "earlier-runs"
KEEP_RUNS = 30      # earlier runs kept by default: a month of nightly runs (docs/batch.md)
KEPT_NAME = re.compile(r"[0-9A-Za-z_.TZ-]+-[0-9a-f]{8}")   # keep_earlier_run's folder names
TOTAL_COLUMNS = ("fuel_gal_total", "state_tax_usd", "federal_tax_usd", "kwh_total", "ev_fee_usd")


def scenario_totals_dict(classes: pd.DataFrame) -> dict[str, dict[str, float]]:
    """Per scenario the totals the comparison looks at (exact sums of the class rows)."""
    out: dict[str, dict[str, float]] = {}
    for scenario_id, group in classes.groupby("scenario_id", sort=False):
        out[str(scenario_id)] = {c: math.fsum(group[c]) for c in TOTAL_COLUMNS if c in group}
    return out


BY_FUEL = ("raw_gal", "fuel_gal", "state_tax_usd", "federal_tax_usd")
TAX_FIELDS = ("state_tax", "federal_tax")
CALIBRATION_FIELDS = ("observed_base_gallons", "calibrate_to_observed")


def model_files() -> list[dict]:
    """Every file of the models folder the package reads its constants from (models/**), with
    its sha256: the numbers of a run come from these and the code."""
    import hashlib

    from fleetrun.resources import models_dir

    root = models_dir()
    out = []
    for path in sorted(p for p in root.rglob("*") if p.is_file() and "__pycache__" not in p.parts):
        out.append({"path": path.relative_to(root).as_posix(), "sha256": hashlib.sha256(path.read_bytes()).hexdigest()})
    return out


def _sha(text: str) -> str:
    import hashlib

    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def fingerprints(result, models: list[dict] | None = None) -> dict:
    """What each total depends on, as sha256 of its inputs: the vehicles (every Vehicles row),
    each scenario without its tax and calibration columns (those are attributed apart), the
    model files (``models``: :func:`model_files`, read when not given) and the fleetrun version."""
    from dataclasses import fields

    from fleetrun import __version__

    vehicles = _sha(repr(sorted(repr(v) for v in result.fleet.vehicles)))
    scenarios = {}
    for s in result.scenarios:
        kept = {f.name: getattr(s, f.name) for f in fields(s) if f.name not in ("scenario_id", "description", "extra")
                and not f.name.startswith(TAX_FIELDS + CALIBRATION_FIELDS)}
        scenarios[s.scenario_id] = _sha(repr(sorted(kept.items(), key=lambda kv: kv[0])))
    models = model_files() if models is None else models
    version = _sha(repr(sorted((m["path"], m["sha256"]) for m in models)) + __version__)
    return {"vehicles": vehicles, "scenarios": scenarios, "model version": version}


def attribution_inputs(result, models: list[dict] | None = None) -> dict:
    """Per scenario and fuel the factors of each total: model gallons (before calibration),
    calibrated gallons and the taxes; and the fingerprints (stored in manifest.json; ``models``
    as :func:`fingerprints` takes it)."""
    by_fuel: dict = {}
    frame = result.results
    for (scenario_id, fuel), group in frame.groupby(["scenario_id", "fuel"], sort=False):
        by_fuel.setdefault(str(scenario_id), {})[str(fuel)] = {
            "raw_gal": math.fsum(group["fuel_gal_uncalibrated_total"]), "fuel_gal": math.fsum(group["fuel_gal_total"]),
            "state_tax_usd": math.fsum(group["state_tax_usd"]), "federal_tax_usd": math.fsum(group["federal_tax_usd"])}
    return {"by_fuel": by_fuel, "fingerprints": fingerprints(result, models)}


def _factor_logs(old: dict, new: dict, total: str) -> dict[str, float] | None:
    """ln of each factor's ratio, new / old, for one fuel: total = raw x calibration [x rate]."""
    values = [old.get(k) for k in BY_FUEL] + [new.get(k) for k in BY_FUEL]
    if any(not isinstance(v, (int, float)) or v <= 0 for v in values):
        return None
    logs = {"raw": math.log(new["raw_gal"] / old["raw_gal"]),
            "calibration": math.log((new["fuel_gal"] / new["raw_gal"]) / (old["fuel_gal"] / old["raw_gal"]))}
    if total != "fuel_gal_total":
        logs["tax rates"] = math.log((new[total] / new["fuel_gal"]) / (old[total] / old["fuel_gal"]))
    return logs


def _raw_cause(earlier: dict, now: dict, scenario_id: str) -> str:
    """Which input moved the model's gallons: the fingerprints that differ."""
    a, b = earlier.get("fingerprints") or {}, now.get("fingerprints") or {}
    if not a:
        return "inputs or model (the earlier run recorded no fingerprints)"
    moved = [name for name in ("vehicles", "model version") if a.get(name) != b.get(name)]
    if (a.get("scenarios") or {}).get(scenario_id) != (b.get("scenarios") or {}).get(scenario_id):
        moved.insert(1 if moved[:1] == ["vehicles"] else 0, "scenario")
    if not moved:
        return "other (same inputs and model)"
    return " + ".join(moved) + (" (together)" if len(moved) > 1 else "")


def attribute(earlier: dict, now: dict) -> tuple[ChangeCause, ...]:
    """Each scenario total's change split into its causes: per fuel, total = model gallons x
    calibration factor (x tax rate), so ln(change) is the sum of the factors' ln ratios; the
    change in US$ or gallons is shared in proportion to them and added over fuels. The model
    gallons' part goes to the inputs whose fingerprint changed (vehicles, scenario, model
    version; several at once are named together, not split)."""
    old_all, new_all = (earlier.get("attribution") or {}).get("by_fuel") or {}, now.get("by_fuel") or {}
    causes = []
    for scenario_id in new_all:
        if scenario_id not in old_all:
            continue
        for total in ("fuel_gal_total", "state_tax_usd", "federal_tax_usd"):
            key = "fuel_gal" if total == "fuel_gal_total" else total
            amounts: dict[str, float] = {}
            for fuel in set(old_all[scenario_id]) | set(new_all[scenario_id]):
                old, new = old_all[scenario_id].get(fuel, {}), new_all[scenario_id].get(fuel, {})
                change = new.get(key, 0.0) - old.get(key, 0.0)
                logs = _factor_logs(old, new, key)
                if not change:
                    continue
                if logs is None or not sum(logs.values()):
                    amounts["vehicles (fuel added or removed)"] = amounts.get("vehicles (fuel added or removed)", 0) + change
                    continue
                whole = sum(logs.values())
                for factor, value in logs.items():
                    name = _raw_cause(earlier.get("attribution") or {}, now, scenario_id) if factor == "raw" else factor
                    amounts[name] = amounts.get(name, 0.0) + change * value / whole
            causes += [ChangeCause(scenario_id, total, name, amount) for name, amount in amounts.items()
                       if abs(amount) > 1e-9]
    return tuple(causes)


@dataclass(frozen=True)
class EarlierRun:
    """The run already in an output folder: its ``manifest.json`` as read (docs/interface.md),
    ``totals`` filled in from its ``class_summary.csv`` for a manifest written before the
    manifest carried them."""
    manifest: JsonDocument

    def folder_name(self) -> str:
        """A folder name for the kept earlier run: its creation time, file-name safe."""
        return earlier_run_name(self.manifest)


def read_manifest(manifest: Path) -> tuple[object, str]:
    """``manifest.json``'s data (None when there is none) and what is wrong with it ('' if
    nothing)."""
    if not manifest.is_file():
        return None, ""
    try:
        data = json.loads(manifest.read_text(encoding="utf-8"))
    except OSError as exc:
        return None, f"cannot be read: {exc.strerror or exc}"
    except UnicodeDecodeError:
        return None, "not UTF-8 text"
    except ValueError as exc:
        return None, "empty" if not manifest.stat().st_size else f"not JSON: {exc}"
    return data, "" if isinstance(data, dict) else "not a JSON object"


def same_schema(data, schema: str) -> bool:
    """Whether ``data`` (a manifest read by :func:`read_manifest`) is a document of ``schema``'s
    kind, any version (``fleetrun.run/1`` and a later ``fleetrun.run/2`` are one kind)."""
    return isinstance(data, dict) and str(data.get("schema", "")).split("/")[0] == schema.split("/")[0]


def read_earlier(out_dir: Path) -> EarlierRun | None:
    """The earlier run in ``out_dir``: its manifest with ``totals`` filled in; None if none
    (or its manifest cannot be read: then there is nothing to compare, said in the log)."""
    data, damage = read_manifest(Path(out_dir) / "manifest.json")
    if damage or data is None:
        return None
    if not isinstance(data.get("totals"), dict):
        classes = Path(out_dir) / "class_summary.csv"
        try:
            data["totals"] = scenario_totals_dict(pd.read_csv(classes)) if classes.is_file() else {}
        except (OSError, ValueError, KeyError):
            data["totals"] = {}
    return EarlierRun(manifest=data)


WORKBOOK_ROLE = "fleet workbook"


def _compare_inputs(earlier_inputs: list, inputs: list[dict]) -> list[InputChange]:
    """Inputs added, removed, changed or the same (by sha256); the fleet workbook is followed
    by its role, so a renamed workbook is ``renamed`` (or ``renamed and changed``), not
    removed + added."""
    earlier_inputs = [item for item in earlier_inputs if isinstance(item, dict)]
    old_book = next((i for i in earlier_inputs if i.get("role") == WORKBOOK_ROLE), None)
    new_book = next((i for i in inputs if i.get("role") == WORKBOOK_ROLE), None)
    out = []
    if old_book and new_book and old_book.get("path") != new_book["path"]:
        same = old_book.get("sha256") == new_book["sha256"]
        out.append(InputChange(path=f"{old_book.get('path')} -> {new_book['path']}",
                               status="renamed" if same else "renamed and changed",
                               earlier_sha256=old_book.get("sha256"), sha256=new_book["sha256"]))
        earlier_inputs = [i for i in earlier_inputs if i is not old_book]
        inputs = [i for i in inputs if i is not new_book]
    before = {item.get("path"): item.get("sha256") for item in earlier_inputs}
    now = {item["path"]: item["sha256"] for item in inputs}
    for path in sorted(set(before) | set(now), key=str):
        status = ("added" if path not in before else "removed" if path not in now
                  else "changed" if before[path] != now[path] else "same")
        out.append(InputChange(path=path, status=status, earlier_sha256=before.get(path), sha256=now.get(path)))
    return out


def compare(earlier_run: EarlierRun, inputs: list[dict], totals: dict[str, dict[str, float]],
            attribution: dict | None = None) -> RunChanges:
    """Inputs added, removed, renamed or changed (by sha256), totals by scenario earlier vs now,
    and each total's change attributed to its causes (``attribution``: this run's
    :func:`attribution_inputs`)."""
    earlier = earlier_run.manifest
    changed_inputs = _compare_inputs(earlier.get("inputs", []), inputs)
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
                      totals=tuple(rows), causes=attribute(earlier, attribution or {}))


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
            parts = [f"{c.cause} {c.amount:+,.0f}" for c in changes.causes
                     if c.scenario_id == row.scenario_id and c.total == row.total]
            if parts:
                lines.append("  of which: " + "; ".join(parts))
    return lines


def earlier_run_name(earlier: dict) -> str:
    """A folder name for the kept earlier run: its creation time, file-name safe."""
    stamp = str(earlier.get("created_utc") or "unknown").replace(":", "").replace("+0000", "Z")
    return "".join(ch if ch.isalnum() or ch in "-_.TZ" else "_" for ch in stamp) or "unknown"


def keep_earlier_run(out_dir: Path, staging: Path, earlier: EarlierRun, files) -> Path:
    """Copy the earlier run's ``files`` into ``staging/earlier-runs/<its time>/`` and carry over
    the runs it kept itself, so the new folder holds every earlier run; the kept folder."""
    out_dir, staging = Path(out_dir), Path(staging)
    digest = hashlib.sha256((out_dir / "manifest.json").read_bytes()).hexdigest()[:8]
    kept = staging / EARLIER_DIR / f"{earlier.folder_name()}-{digest}"
    kept.mkdir(parents=True, exist_ok=True)
    # hard links: every night's run kept its predecessors by copying them all, so the write
    # time and the disk grew with every run kept (fileio.link_or_copy: outputs are replaced,
    # never written in place, so a link keeps the earlier bytes)
    for name in files:
        if (out_dir / name).is_file():
            link_or_copy(out_dir / name, kept / name)
    older = out_dir / EARLIER_DIR
    if older.is_dir():
        for item in sorted(older.iterdir()):
            if item.is_dir() and not (staging / EARLIER_DIR / item.name).exists():
                shutil.copytree(item, staging / EARLIER_DIR / item.name, symlinks=True, copy_function=link_or_copy)
    return kept


def _kept_run(folder: Path, schema: str) -> dict | None:
    """The manifest of an earlier run fleetrun kept in ``folder`` (its name as
    :func:`keep_earlier_run` gives it, a manifest of ``schema``'s kind inside); None for
    anything else."""
    if folder.is_symlink() or not folder.is_dir() or not KEPT_NAME.fullmatch(folder.name):
        return None
    data, _ = read_manifest(folder / "manifest.json")
    return data if same_schema(data, schema) else None


def prune_earlier_runs(out_dir: Path, keep: int, schema: str) -> list[Path]:
    """Remove the oldest runs of ``out_dir/earlier-runs/`` beyond the newest ``keep`` (by the
    manifest's creation time; ``schema``: the run manifest's, fleetrun.reports.manifest.SCHEMA);
    the folders removed. Only runs fleetrun kept there are counted
    and only the files their manifest lists are deleted (``manifest.json`` last, so a removal
    cut short is finished by the next run); a folder left with other files stays."""
    root = Path(out_dir) / EARLIER_DIR
    if not root.is_dir():
        return []
    runs = [(str(data.get("created_utc") or ""), entry.name, entry, data)
            for entry in root.iterdir() if (data := _kept_run(entry, schema)) is not None]
    runs.sort(key=lambda run: run[:2], reverse=True)
    removed = []
    for *_, folder, data in runs[keep:]:
        outputs = data.get("outputs") if isinstance(data.get("outputs"), dict) else {}
        for name in [*outputs, "manifest.json"]:
            path = folder / str(name)
            if path.parent == folder and path.is_file() and not path.is_symlink():
                path.unlink()
        if not any(folder.iterdir()):
            folder.rmdir()
        removed.append(folder)
    return removed
