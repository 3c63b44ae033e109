"""No string-keyed dict crosses a module boundary in the simulation, diagnose and run results.

Results travel between modules as typed, frozen records (dataclasses) that both sides import
from one module (fleetrun/simulation/records.py, fleetrun/budget/result.py): a field renamed
is one edit that every reader sees, and a typo is an AttributeError, not a silent None.

Two checks:
- static: the annotations of every public function (parameters and return) and every public
  class field of fleetrun.simulation, fleetrun.diagnose, fleetrun.run and
  fleetrun.budget.result are read with ``ast``; a bare ``dict`` / ``Mapping``, a
  ``dict[str, dict | Any | object]`` or a ``list[dict]`` fails. A dict keyed by a name whose
  values are a record or an array (``dict[str, PhaseResult]``) is a lookup table, not a record,
  and passes; so does ``JsonDocument`` (fleetrun.fileio), a JSON file's content.
- at run time: what ``simulate`` and ``run_fleet`` return holds records, never dicts of dicts.

KNOWN lists what is still string-keyed, each with the reason (empty now); it may only shrink
(an entry that no longer is a dict fails, so that it is taken off). JSON_DOCUMENTS lists where
a ``JsonDocument`` may appear (the diagnosis.json documents, the sidecar being read): a third
check fails on any other, so the exemption cannot hide a record-dict.
"""
from __future__ import annotations

import ast
import dataclasses
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("fleetrun/simulation", "fleetrun/diagnose", "fleetrun/run")
MODULES = ("fleetrun/budget/result.py",)

# a dict used as a record: bare, or keyed by str with untyped / dict values; lists of them
_RECORD_DICT = re.compile(r"^(dict|Dict|Mapping|MutableMapping)$"
                          r"|^(dict|Dict|Mapping|MutableMapping)\[str,\s*(dict|Dict|Any|object|Mapping|list\[dict)"
                          r"|^(list|tuple|Sequence)\[(dict|Dict|Mapping)(\]|,)")

# (module file, qualified name[, parameter]) -> why it is still a dict. Empty: every dict that
# crossed a module boundary is a record now; a new one needs its reason here (or a record).
KNOWN: dict[str, str] = {}

# A JsonDocument (a file's content) passes the scan above, so where one may appear is listed
# too: the documents that ARE a file (diagnosis.json, built once from the records by
# ``analyse``/``analyse_fleet``, rendered by the report beside it, returned to the caller) and
# the part of it a diagnose level adds. ``as_json``/``summary``/``from_toml`` methods of records
# (a record's own file form) need no entry.
_DIAGNOSIS_JSON = "diagnosis.json's document (docs/interface.md): the file itself, and the report rendered beside it"
_FLEET_JSON = "the fleet diagnosis.json's document (docs/interface.md), and the report rendered beside it"
JSON_DOCUMENTS = {
    "fleetrun/diagnose/__init__.py:analyse": _DIAGNOSIS_JSON,
    "fleetrun/diagnose/__init__.py:Diagnosis.result": _DIAGNOSIS_JSON,
    "fleetrun/diagnose/__init__.py:diagnose": _DIAGNOSIS_JSON,
    "fleetrun/diagnose/joint.py:JointDiagnosis.result": _DIAGNOSIS_JSON,
    "fleetrun/diagnose/report.py:figures(result)": _DIAGNOSIS_JSON,
    "fleetrun/diagnose/report.py:summary_sentence(result)": _DIAGNOSIS_JSON,
    "fleetrun/diagnose/report.py:render_html(result)": _DIAGNOSIS_JSON,
    "fleetrun/diagnose/fleet.py:analyse_fleet": _FLEET_JSON,
    "fleetrun/diagnose/fleet.py:diagnose_fleet": _FLEET_JSON,
    "fleetrun/diagnose/fleet_report.py:fleet_figures(result)": _FLEET_JSON,
    "fleetrun/diagnose/fleet_report.py:summary_words(result)": _FLEET_JSON,
    "fleetrun/diagnose/fleet_report.py:render_fleet_html(result)": _FLEET_JSON,
    "fleetrun/diagnose/engine.py:Problem.baseline_info": "the part of diagnosis.json's 'baseline' a level adds",
}
_OWN_JSON = {"as_json", "to_json", "summary", "from_toml", "from_json"}


def _is_record_dict(annotation: ast.expr | None) -> bool:
    if annotation is None:
        return False
    text = ast.unparse(annotation).strip("\"'")
    for part in (p.strip() for p in re.split(r"\|", text)):
        if part.startswith("tuple["):   # a tuple of results: each member
            members = re.split(r",\s*(?![^\[]*\])", part[len("tuple["):-1])
            if any(_RECORD_DICT.search(m.strip()) for m in members):
                return True
        if _RECORD_DICT.search(part):
            return True
    return False


def _files():
    for package in PACKAGES:
        yield from sorted((ROOT / package).glob("*.py"))
    for module in MODULES:
        yield ROOT / module


def _function_findings(where: str, func: ast.FunctionDef, flagged):
    for arg in func.args.posonlyargs + func.args.args + func.args.kwonlyargs:
        if flagged(arg.annotation):
            yield f"{where}({arg.arg})"
    if flagged(func.returns):
        yield where


def _is_json_document(annotation: ast.expr | None) -> bool:
    return annotation is not None and "JsonDocument" in ast.unparse(annotation)


def findings(flagged=_is_record_dict, skip_methods=frozenset()) -> set[str]:
    """Every public annotation in the scanned modules that ``flagged`` (default: a dict used
    as a record)."""
    found = set()
    for path in _files():
        rel = path.relative_to(ROOT).as_posix()
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if node.name.startswith("_") if hasattr(node, "name") else True:
                continue
            if isinstance(node, ast.FunctionDef):
                found.update(_function_findings(f"{rel}:{node.name}", node, flagged))
            elif isinstance(node, ast.ClassDef):
                for item in node.body:
                    if isinstance(item, ast.AnnAssign) and flagged(item.annotation):
                        found.add(f"{rel}:{node.name}.{ast.unparse(item.target)}")
                    elif (isinstance(item, ast.FunctionDef) and not item.name.startswith("_")
                          and item.name not in skip_methods):
                        found.update(_function_findings(f"{rel}:{node.name}.{item.name}", item, flagged))
    return found


def test_the_scan_sees_a_record_dict():
    """The pattern catches the forms a record-dict takes, and lets lookup tables pass."""
    parse = lambda text: ast.parse(text, mode="eval").body  # noqa: E731
    for bad in ("dict", "dict[str, dict]", "dict[str, dict[str, np.ndarray]]", "dict[str, Any]", "list[dict]",
                "dict | None", "tuple[dict, np.ndarray]", "Mapping", "tuple[list[dict], bool]"):
        assert _is_record_dict(parse(bad)), bad
    for good in ("dict[str, PhaseResult]", "dict[str, float]", "dict[str, np.ndarray]", "JsonDocument",
                 "list[EfficiencyMap]", "RunResult", "dict[str, tuple[float, float]]"):
        assert not _is_record_dict(parse(good)), good


def test_no_new_string_keyed_dict_crosses_a_module_boundary():
    now = findings()
    new = sorted(now - set(KNOWN))
    assert not new, ("string-keyed dicts cross a module boundary (make them a frozen dataclass in the "
                     "module's records module, see docs/architecture.md):\n  " + "\n  ".join(new))
    gone = sorted(set(KNOWN) - now)
    assert not gone, "typed now, take them off KNOWN in tests/test_records.py:\n  " + "\n  ".join(gone)


def test_json_documents_only_where_a_file_is_meant():
    """``JsonDocument`` (a file's content) in a public signature only where it is that file."""
    now = findings(_is_json_document, skip_methods=_OWN_JSON)
    new = sorted(now - set(JSON_DOCUMENTS))
    assert not new, ("a JSON document crosses a module boundary where no file is meant (make it a record, "
                     "with as_json for its file form):\n  " + "\n  ".join(new))
    gone = sorted(set(JSON_DOCUMENTS) - now)
    assert not gone, "take them off JSON_DOCUMENTS in tests/test_records.py:\n  " + "\n  ".join(gone)


def _assert_records(value, where: str) -> None:
    """``value`` (a field of a result) holds records, arrays and scalars, no dict of dicts."""
    if isinstance(value, dict):
        for key, item in value.items():
            assert not isinstance(item, (dict, list)) or isinstance(item, list) and not any(
                isinstance(x, dict) for x in item), f"{where}[{key!r}] is a {type(item).__name__}"
            _assert_records(item, f"{where}[{key!r}]")
    elif isinstance(value, (list, tuple)):
        assert not any(isinstance(x, dict) for x in value), f"{where} holds dicts"
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            if f.name != "parameters":   # an effect's parameters: name -> value
                _assert_records(getattr(value, f.name), f"{where}.{f.name}")


def test_simulate_returns_records():
    from fleetrun.simulation import FleetCycleResult, PhaseResult, Trace, simulate
    from fleetrun.testing.vehicles import CAMRY

    r = simulate([CAMRY], "FTP", trace=True, effects="warmup")
    assert isinstance(r, FleetCycleResult) and isinstance(r.trace, Trace)
    assert all(isinstance(p, PhaseResult) for p in r.phases.values()) and set(r.phases) == {"bag1", "bag2", "bag3"}
    _assert_records(r, "FleetCycleResult")
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.miles = np.zeros(1)
    # the internals of the backward pass are not in the public trace
    assert not [f.name for f in dataclasses.fields(Trace) if f.name.startswith("_")]


def test_run_result_holds_records(tmp_path):
    from fleetrun.budget.result import CycleInfo, EfficiencyMap, EngineInfo, RunResult
    from fleetrun.run.runner import run_fleet
    from fleetrun.workbook.reader import read_fleet
    from test_fleet_fakes import fake_simulate, vehicle, write_fleet

    fleet = read_fleet(write_fleet(tmp_path / "f.xlsx", [vehicle("CAR-1")]))
    result = run_fleet(fleet, simulate=fake_simulate, error_model=None)
    assert isinstance(result, RunResult) and isinstance(result.engine, EngineInfo)
    assert all(isinstance(c, CycleInfo) for c in result.cycles.values()) and result.cycles
    assert all(isinstance(m, EfficiencyMap) for m in result.maps) and result.maps
    for f in dataclasses.fields(result):
        value = getattr(result, f.name)
        if not isinstance(value, pd.DataFrame):
            _assert_records(value, f"RunResult.{f.name}")
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.warnings = []
