"""The package's import structure (docs/architecture.md, "Layers").

Every ``import`` of a fleetrun module in ``fleetrun/`` (module level or inside a function: a
lazy import is still a dependency) is read with ``ast``. The tests fail on any import circle
between modules and on any arrow from a lower layer to a higher one, so the layering cannot
erode one convenient import at a time.
"""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "fleetrun"

#: Layers from the bottom up. A module may import its own layer and the layers below it.
#: A module belongs to the first entry whose name is the module or a package containing it.
#: Keep in step with docs/architecture.md.
LAYERS = (
    ("base", ("fleetrun", "fleetrun.errors", "fleetrun.registry", "fleetrun.resources", "fleetrun.units",
              "fleetrun.fileio", "fleetrun.output_folder")),
    ("physics", ("fleetrun.physics",)),
    ("differential", ("fleetrun.differential",)),
    ("effects", ("fleetrun.effects",)),
    ("simulation", ("fleetrun.vehicle", "fleetrun.cycles", "fleetrun.simulation")),
    ("workbook", ("fleetrun.workbook",)),
    ("epa", ("fleetrun.epa", "fleetrun.plots")),
    ("registrations", ("fleetrun.registrations",)),
    ("budget", ("fleetrun.budget",)),
    ("reports", ("fleetrun.reports",)),
    ("run", ("fleetrun.run",)),
    ("diagnose", ("fleetrun.diagnose",)),
    ("commands", ("fleetrun.commands", "fleetrun.cli", "fleetrun.__main__")),
    ("testing", ("fleetrun.testing",)),  # fixtures for tests and scripts: nothing imports them
)


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def imports(name: str, path: Path, known) -> set[str]:
    """The fleetrun modules ``name`` imports (``from a.b import c``: a.b.c if that is a module)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        else:
            continue
        found.update(t for t in targets if t == "fleetrun" or t.startswith("fleetrun."))
    return found


def layer_of(name: str) -> int:
    best = None
    for i, (_, members) in enumerate(LAYERS):
        for m in members:
            if (name == m or name.startswith(m + ".")) and (best is None or len(m) > len(best[1])):
                best = (i, m)
    if best is None:
        raise AssertionError(f"{name} is in no layer: add it to LAYERS in tests/test_architecture.py "
                             "and to docs/architecture.md")
    return best[0]


def graph() -> dict[str, set[str]]:
    mods = modules()
    return {name: {t for t in imports(name, path, mods) if t in mods and t != name}
            for name, path in mods.items()}


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def test_every_module_has_a_layer():
    for name in modules():
        layer_of(name)


def test_no_import_circle():
    assert cycles(graph()) == []


def test_no_import_from_a_lower_layer_to_a_higher_one():
    upward = [f"{a} ({LAYERS[layer_of(a)][0]}) imports {b} ({LAYERS[layer_of(b)][0]})"
              for a, targets in graph().items() for b in sorted(targets) if layer_of(b) > layer_of(a)]
    assert upward == []


def test_the_checks_can_fail():
    """The circle finder and the layer order see a planted circle and an upward arrow."""
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert layer_of("fleetrun.physics.lubricant") < layer_of("fleetrun.simulation.core")
    assert layer_of("fleetrun.run.outputs") > layer_of("fleetrun.fileio")
    assert layer_of("fleetrun.commands.run") > layer_of("fleetrun.diagnose.engine")
