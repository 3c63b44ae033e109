"""Write ARB-TRANSIENT.csv (GEM's transient cycle) from NREL T3CO's copy (see PROVENANCE.md).

    git clone https://github.com/NREL/T3CO /tmp/T3CO     # commit 85017ca6783bbf837b211da88f2ff9130e707342
    python inputs/cycles/extract_gem_transient.py /tmp/T3CO/t3co/resources/cycles/EPA_Ph2_transient.csv

The source is a fastsim-format CSV (UTF-8 BOM; ``cycSecs`` [s], ``cycMps`` [m/s], ``cycGrade``
[fraction], ``cycRoadType``). Conversion as for the fastsim cycles of ``extract.py``: columns
renamed, speed text copied unchanged (already m/s), grade x 100 -> ``grade_pct``, road type
dropped.
"""
from __future__ import annotations

import csv
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
NAME = "ARB-TRANSIENT"


def _fmt(x: float) -> str:
    return f"{x:.10g}"


def convert(source: Path) -> Path:
    with open(source, newline="", encoding="utf-8-sig") as f:
        rows = list(csv.DictReader(f))
    lines = ["time_s,speed_mps,grade_pct"]
    lines += [f"{r['cycSecs']},{r['cycMps']},{_fmt(100.0 * float(r['cycGrade']))}" for r in rows]
    out = HERE / f"{NAME}.csv"
    out.write_text("\n".join(lines) + "\n")
    return out


if __name__ == "__main__":
    print(convert(Path(sys.argv[1])))
