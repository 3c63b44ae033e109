"""The public model functions say what goes in and what comes out, with units.

Every public function of ``fleetrun/physics/`` (the small pure physics functions of the house
style, docs/architecture.md), of the simulation's physics families (road load, tyre, engine,
transmission, electric, thermal, climate, technology, heavy-duty engine, shift and road load, GEM
composite) and its machinery (core, differential modes, parameters, measured-number calibration,
effects), of ``fleetrun/differential/`` and ``fleetrun/effects/``, and of the listed modules of
cycles, plausibility checks, EPA import rules, turnover and budget arithmetic has a numpydoc
``Parameters`` section naming every argument and a ``Returns`` section; every float parameter
gives its unit in brackets, e.g. ``speed_rpm : float or array, n [rpm]`` (``[-]`` for a ratio).
The examples in them run as doctests with the default suite (pyproject.toml ``testpaths``).
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PHYSICS = sorted((ROOT / "fleetrun" / "physics").glob("*.py")) + [
    ROOT / "fleetrun" / "simulation" / f"{name}.py" for name in ("road_load", "tyre", "engine", "transmission", "electric",
                                                           "thermal", "climate", "technology", "heavy_duty_engine",
                                                           "heavy_duty_shift")] + [
    ROOT / "fleetrun" / name for name in ("effects/__init__.py", "effects/differential.py", "effects/vehicle.py",
                                          "simulation/heavy_duty_gem.py", "simulation/heavy_duty_road_load.py",
                                          "simulation/effects.py", "simulation/diffmodes.py",
                                          "simulation/measured.py", "simulation/params.py", "simulation/core.py",
                                          "simulation/__init__.py", "cycles.py",
                                          "epa/rules.py", "registrations/turnover.py",
                                          "budget/arithmetic.py", "budget/drivers.py", "budget/uncertainty.py",
                                          "budget/totals.py", "plausible.py")] + sorted((ROOT / "fleetrun" / "differential").glob("*.py"))


def _public_functions(path: Path):
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
            yield node


def _section(doc: str, title: str) -> str | None:
    match = re.search(rf"^{title}\n-+\n(.*?)(?:\n\s*\n|\Z)", doc, re.S | re.M)
    return match.group(1) if match else None


@pytest.mark.parametrize("path", PHYSICS, ids=lambda p: p.name)
def test_every_physics_function_documents_its_parameters_and_units(path):
    for func in _public_functions(path):
        doc = ast.get_docstring(func) or ""
        where = f"{path.relative_to(ROOT)}:{func.name}"
        names = [a.arg for a in func.args.posonlyargs + func.args.args + func.args.kwonlyargs]
        if names:
            block = _section(doc, "Parameters")
            assert block, f"{where}: no numpydoc Parameters section"
            documented = {n.strip() for line in block.splitlines() if " : " in line
                          for n in line.split(" : ")[0].split(",")}
            assert set(names) <= documented, f"{where}: Parameters lacks {sorted(set(names) - documented)}"
            # numpydoc's two-line form ("name : float" and the description below) counts too
            lines = block.splitlines()
            unitless = [line for k, line in enumerate(lines) if " : " in line
                        and "float" in line.split(" : ")[1].split(",")[0]
                        and "[" not in line + (lines[k + 1] if k + 1 < len(lines) and " : " not in lines[k + 1] else "")]
            assert not unitless, f"{where}: a float parameter without its unit in brackets: {unitless}"
        assert _section(doc, "Returns"), f"{where}: no numpydoc Returns section"


def test_the_check_sees_a_missing_section():
    """The section reader finds a section that is there and misses one that is not."""
    doc = "Text.\n\nParameters\n----------\nx : float, x [m]\n\nReturns\n-------\ny [m].\n"
    assert _section(doc, "Parameters") == "x : float, x [m]" and _section(doc, "Returns").strip() == "y [m]."
    assert _section("Text only.", "Parameters") is None
