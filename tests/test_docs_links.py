"""The documentation points at things that exist.

- every relative link in README.md and docs/*.md resolves to a file or folder of the checkout;
- every module or object named as ``fleetrun.x.y`` and every path ``fleetrun/x/y.py`` mentioned
  in README.md, docs/*.md, CHANGELOG.md and the package's own source (docstrings and comments
  included) exists: a newcomer following a reference never lands nowhere;
- the interface the code cites is docs/interface.md, in the repository (no reference to a
  contract file outside it).
"""
from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md", ROOT / "CHANGELOG.md"]
SOURCES = sorted((ROOT / "fleetrun").rglob("*.py"))
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
DOTTED = re.compile(r"(?<![\w/.\"'])fleetrun(?:\.[A-Za-z_]\w*)+(?![\w/-])")
PATH = re.compile(r"(?<![\w/.])fleetrun/[\w/]+(?:\.py)?")


def _relative_links(path: Path):
    for target in LINK.findall(path.read_text(encoding="utf-8")):
        if re.match(r"^[a-z]+:", target) or target.startswith("#"):
            continue
        yield target.split("#", 1)[0]


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_relative_links_resolve(doc):
    missing = [t for t in _relative_links(doc) if t and not (doc.parent / t).exists()]
    assert not missing, f"{doc.name}: links to nothing: {missing}"


def _resolves(dotted: str) -> bool:
    """``fleetrun.a.b.c``: the longest importable module prefix, then attributes."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ModuleNotFoundError:
            continue
        for name in parts[cut:]:
            if not hasattr(obj, name):
                return False
            obj = getattr(obj, name)
        return True
    return False


def _mentions(pattern):
    found = {}
    for path in DOCS + SOURCES:
        for match in pattern.findall(path.read_text(encoding="utf-8")):
            found.setdefault(match.rstrip("."), path.relative_to(ROOT).as_posix())
    return found


def test_every_module_named_exists():
    broken = {m: where for m, where in _mentions(DOTTED).items() if not _resolves(m)}
    assert not broken, "named but not there (name: where):\n" + "\n".join(f"  {m}: {w}" for m, w in broken.items())


def test_every_path_named_exists():
    broken = {}
    for mention, where in _mentions(PATH).items():
        path = ROOT / mention
        if mention.startswith("fleetrun/_data/"):   # copies made when the package is built (pyproject.toml)
            continue
        if not (path.exists() or path.with_suffix(".py").exists()):
            broken[mention] = where
    assert not broken, "paths named but not there:\n" + "\n".join(f"  {m}: {w}" for m, w in broken.items())


def test_the_interface_is_cited_from_the_repository():
    """Code, tests and docs cite docs/interface.md, not a contract file outside the checkout."""
    cited = []
    for path in DOCS + SOURCES + sorted((ROOT / "tests").glob("*.py")):
        if path.name in ("test_docs_links.py", "CHANGELOG.md"):
            continue
        if "CONTRACT.md" in path.read_text(encoding="utf-8"):
            cited.append(path.relative_to(ROOT).as_posix())
    assert not cited, f"cite docs/interface.md instead of CONTRACT.md: {cited}"
    assert (ROOT / "docs" / "interface.md").exists()
