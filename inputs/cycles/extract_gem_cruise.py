"""Write CRUISE-55-GRADE.csv and CRUISE-65-GRADE.csv (GEM's Phase 2 cruise cycles over the
regulatory grade profile) from NREL T3CO's copies (see PROVENANCE.md).

    git clone https://github.com/NREL/T3CO /tmp/T3CO     # commit 85017ca6783bbf837b211da88f2ff9130e707342
    python inputs/cycles/extract_gem_cruise.py /tmp/T3CO/t3co/resources/cycles

The sources are fastsim-format CSVs (``cycSecs`` [s], ``cycMps`` [m/s], ``cycGrade``
[fraction], ``cycRoadType``): 55 and 65 mph held over the grade profile of Appendix IV to
40 CFR part 1037, sampled at 1 Hz. Conversion as for ``extract_gem_transient.py``: columns
renamed, speed text copied unchanged, grade x 100 -> ``grade_pct``, road type dropped.
"""
from __future__ import annotations

import csv
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
SOURCES = {"CRUISE-55-GRADE": "EPA_Ph2_urban_highway_55mph.csv",
           "CRUISE-65-GRADE": "EPA_Ph2_rural_interstate_65mph.csv"}


def _fmt(x: float) -> str:
    return f"{x:.10g}"


def convert(folder: Path) -> list[Path]:
    written = []
    for name, source in SOURCES.items():
        with open(folder / source, newline="", encoding="utf-8-sig") as f:
            rows = list(csv.DictReader(f))
        lines = ["time_s,speed_mps,grade_pct"]
        lines += [f"{r['cycSecs']},{r['cycMps']},{_fmt(100.0 * float(r['cycGrade']))}" for r in rows]
        out = HERE / f"{name}.csv"
        out.write_text("\n".join(lines) + "\n")
        written.append(out)
    return written


if __name__ == "__main__":
    print(*convert(Path(sys.argv[1])), sep="\n")
