"""Rebuild the shipped drive-cycle CSVs from the unzipped source wheels (run once; kept for
reproducibility, see PROVENANCE.md).

    pip download --no-deps fastsim==2.1.5 -d /tmp/wheels
    pip download --no-deps zahner_potentiostat==1.1.2 -d /tmp/wheels
    (cd /tmp/fastsim_whl && unzip -q /tmp/wheels/fastsim-2.1.5-*.whl)
    (cd /tmp/zahner_whl && unzip -q /tmp/wheels/zahner_potentiostat-1.1.2-*.whl)
    python inputs/cycles/extract.py /tmp/fastsim_whl /tmp/zahner_whl

Output columns: ``time_s`` [s], ``speed_mps`` [m/s], and ``grade_pct`` [%] where the source
carries a grade column. fastsim stores speed in m/s (``cycMps``) and grade as a fraction
(``cycGrade``, converted here to percent); the EPA text schedules embedded in
zahner_potentiostat are in mph and are converted with 1 mph = 0.44704 m/s (exact).
Neither package is imported: the zahner schedules are read from the module source with ``ast``.
"""
from __future__ import annotations

import ast
import csv
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
MPH_TO_MPS = 0.44704  # exact by definition of the international mile and hour

# shipped name -> path inside the fastsim 2.1.5 wheel
FASTSIM = {
    "UDDS": "fastsim/resources/cycles/udds.csv",
    "HWFET": "fastsim/resources/cycles/hwfet.csv",
    "US06": "fastsim/resources/cycles/us06.csv",
    "WLTC": "fastsim/resources/cycles/wltc_3b.csv",
}
# shipped name -> (path inside the zahner_potentiostat 1.1.2 wheel, variable holding the text)
ZAHNER = {
    "NYCC": ("zahner_potentiostat/drivecycle/NYCCCOL.py", "NYCCCO_profile"),
    "HD-UDDS": ("zahner_potentiostat/drivecycle/HUDDSCOL.py", "HUDDSCOL_profile"),
}


def _fmt(x: float) -> str:
    """Shortest text that round-trips, with integral values written without '.0'."""
    return str(int(x)) if float(x).is_integer() else repr(float(x))


def from_fastsim(src: Path) -> list[tuple[str, ...]]:
    with open(src, newline="", encoding="utf-8-sig") as fh:
        rows = list(csv.DictReader(fh))
    out = []
    for r in rows:
        grade_pct = float(r["cycGrade"]) * 100.0
        # speed text is kept exactly as fastsim wrote it (already m/s)
        out.append((r["cycSecs"].strip(), r["cycMps"].strip(), _fmt(grade_pct)))
    return out


def from_zahner(src: Path, variable: str) -> list[tuple[str, ...]]:
    tree = ast.parse(src.read_text(encoding="utf-8"))
    text = None
    for node in tree.body:
        target = node.target if isinstance(node, ast.AnnAssign) else (
            node.targets[0] if isinstance(node, ast.Assign) else None)
        if getattr(target, "id", None) == variable:
            text = node.value.value
    if text is None:
        raise SystemExit(f"{src}: variable {variable} not found")
    out = []
    for line in text.strip().splitlines():
        t, mph = line.split("\t")
        out.append((_fmt(float(t)), _fmt(round(float(mph) * MPH_TO_MPS, 9))))
    return out


def write(name: str, rows, with_grade: bool) -> None:
    header = ["time_s", "speed_mps"] + (["grade_pct"] if with_grade else [])
    with open(HERE / f"{name}.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)
        w.writerows(rows)


def main(fastsim_root: str, zahner_root: str) -> None:
    for name, rel in FASTSIM.items():
        write(name, from_fastsim(Path(fastsim_root) / rel), with_grade=True)
    for name, (rel, var) in ZAHNER.items():
        write(name, from_zahner(Path(zahner_root) / rel, var), with_grade=False)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    main(sys.argv[1], sys.argv[2])
