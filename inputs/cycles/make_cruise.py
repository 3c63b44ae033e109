"""Write the constant-speed cruise cycles CRUISE-55.csv and CRUISE-65.csv (see PROVENANCE.md).

    python inputs/cycles/make_cruise.py

1 Hz, 600 s at exactly 55 or 65 mph from t = 0 (the vehicle starts at speed, as GEM's cruise
cycles do), level road (grade_pct 0). 1 mph = 0.44704 m/s exactly.
"""
from __future__ import annotations

from pathlib import Path

HERE = Path(__file__).resolve().parent
MPH_TO_MPS = 0.44704
DURATION_S = 600


def write_cruise(mph: int) -> Path:
    path = HERE / f"CRUISE-{mph}.csv"
    speed = f"{mph * MPH_TO_MPS:.5f}"
    lines = ["time_s,speed_mps,grade_pct"] + [f"{t},{speed},0" for t in range(DURATION_S + 1)]
    path.write_text("\n".join(lines) + "\n")
    return path


if __name__ == "__main__":
    for mph in (55, 65):
        print(write_cruise(mph))
