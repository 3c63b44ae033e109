"""Facts are imported from their owner, not re-typed (docs/architecture.md, "One owner per fact").

A re-typed number drifts from its owner the day one of them is corrected. The known
re-typings are searched for in the package, the validation scripts and the benchmarks (not
in tests/: a test may compute a reference value on its own, e.g. tests/thesis_oracle.py):

| fact | owner |
|---|---|
| rpm <-> rad/s | ``fleetrun.units.RAD_S_PER_RPM`` / ``RPM_PER_RAD_S`` |
| standard gravity | ``fleetrun.units.STANDARD_GRAVITY_M_S2`` |
| FTP bag 1 = the first 505 s of the UDDS | ``inputs/cycles/FTP.toml`` via ``fleetrun.cycles.ftp_bag1_end_s`` |
| FTP transient-phase weight 0.43 | ``fleetrun.cycles.FTP_TRANSIENT_WEIGHT`` |
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SEARCHED = ("fleetrun", "validation", "benchmarks")

# pattern -> (what it re-types, the files allowed to hold it: its owner)
RETYPINGS = {
    r"\b30(\.0)?\s*/\s*(np|math)\.pi\b": ("rpm per rad/s", ()),
    r"\b(np|math)\.pi\s*/\s*30\b": ("rad/s per rpm", ()),
    r"\b2(\.0)?\s*\*\s*(np|math)\.pi\s*/\s*60\b": ("rad/s per rpm", ("fleetrun/units.py",)),
    r"\b60(\.0)?\s*/\s*\(\s*2(\.0)?\s*\*\s*(np|math)\.pi\s*\)": ("rpm per rad/s", ("fleetrun/units.py",)),
    r"\b9\.8(0665|1)\b": ("standard gravity", ("fleetrun/units.py",)),
    r"(?<![\w.])505(\.0)?(?![\w.])(?!\s*s\b)(?!-s\b)": ("the end of FTP bag 1 [s]", ()),
    r"(?<![\w.:])0\.43(?![\w.])": ("the FTP transient-phase weight", ("fleetrun/cycles.py",)),
}


def _code_lines(path: Path):
    """(line number, code) of a Python file, comments and docstrings left out (they may
    cite the value and its source)."""
    in_doc = None
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        stripped = line.strip()
        if in_doc:
            if in_doc in stripped:
                in_doc = None
            continue
        for quote in ('"""', "'''"):
            if stripped.startswith(quote) or stripped.startswith("r" + quote):
                if stripped.count(quote) == 1:
                    in_doc = quote
                break
        else:
            code = line.split("#", 1)[0]
            if code.strip():
                yield number, code
            continue


def _findings():
    for folder in SEARCHED:
        for path in sorted((ROOT / folder).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            for number, code in _code_lines(path):
                for pattern, (fact, owners) in RETYPINGS.items():
                    if rel not in owners and re.search(pattern, code):
                        yield f"{rel}:{number}: {fact} re-typed: {code.strip()}"


def test_no_fact_is_retyped():
    found = list(_findings())
    assert not found, "import these from their owner (tests/test_one_owner.py):\n" + "\n".join(found)


@pytest.mark.parametrize("code, caught", [
    ("omega = n * 2 * np.pi / 60", True), ("rpm = w * 60 / (2 * np.pi)", True), ("g = 9.80665", True),
    ("keep = t <= 505.0", True), ("x = 0.43 * a", True), ("rpm = w * 30 / np.pi", True),
    ("omega = n * RAD_S_PER_RPM", False), ("t_end = ftp_bag1_end_s()", False), ("x = 0.435", False),
    ("name = 'bag 1 (0-505 s)'", False),
])
def test_the_search_sees_a_retyping(code, caught):
    hits = [p for p in RETYPINGS if re.search(p, code)]
    assert bool(hits) == caught, (code, hits)


def test_the_owners_hold_the_values():
    """The owners' values, from their sources: 2 pi / 60 rad/s per rpm; g_n = 9.80665 m/s^2
    (exact, CGPM 1901); FTP bag 1 = the first 505 s (40 CFR 86.135-12(a)), weight 0.43 (40 CFR
    86.144-94(a))."""
    import math

    from fleetrun.cycles import FTP_TRANSIENT_WEIGHT, ftp_bag1_end_s
    from fleetrun.units import RAD_S_PER_RPM, RPM_PER_RAD_S, STANDARD_GRAVITY_M_S2

    assert RAD_S_PER_RPM * RPM_PER_RAD_S == pytest.approx(1.0, rel=1e-15)
    assert 1000 * RAD_S_PER_RPM == pytest.approx(1000 * math.tau / 60, rel=1e-15)
    assert STANDARD_GRAVITY_M_S2 == 9.80665
    assert ftp_bag1_end_s() == 505.0 and FTP_TRANSIENT_WEIGHT == 0.43
