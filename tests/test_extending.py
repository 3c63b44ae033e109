"""docs/extending.md's worked example is true.

The page adds a column to the class summary in steps, each a ``before`` block (lines as they
are in a named file) and an ``after`` block. Checked here: every ``before`` is in its file
exactly once (the page follows the code), and following the steps on a copy of the package
puts the new column, with the value the page defines (fuel_gal_total / vehicles), into
class_summary.csv, report.xlsx's ByClass sheet and summary.html's class table. The copy runs
``fleetrun run`` in a fresh process on the small fleet of ``test_fleet_fakes`` with its fast
stand-in simulation; nothing outside the repository is used.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import openpyxl
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "extending.md"
BLOCK = re.compile(r"```python (before|after) (\S+)\n(.*?)```", re.S)
COLUMN = "gal_per_vehicle"


def steps() -> list[tuple[str, str, str]]:
    """(file, before, after) of each step, in the page's order."""
    blocks = BLOCK.findall(DOC.read_text(encoding="utf-8"))
    assert len(blocks) % 2 == 0, "every before block needs its after block"
    out = []
    for (kind_a, file_a, before), (kind_b, file_b, after) in zip(blocks[::2], blocks[1::2]):
        assert (kind_a, kind_b) == ("before", "after") and file_a == file_b, (file_a, file_b)
        out.append((file_a, before, after))
    return out


def test_the_page_has_its_steps():
    files = [f for f, _, _ in steps()]
    assert len(files) >= 4 and {"fleetrun/budget/totals.py", "fleetrun/reports/html.py"} <= set(files)


def test_every_before_is_in_its_file_once():
    for file, before, after in steps():
        text = (ROOT / file).read_text(encoding="utf-8")
        assert text.count(before) == 1, f"docs/extending.md: this 'before' of {file} is not in it once:\n{before}"
        assert COLUMN not in text, f"{file} already has {COLUMN}: the worked example needs another name"
        assert before != after


def _copy_with_steps(base: Path) -> Path:
    copy = base / "checkout"
    shutil.copytree(ROOT / "fleetrun", copy / "fleetrun", ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("models", "templates", "inputs"):
        (copy / name).symlink_to(ROOT / name, target_is_directory=True)
    for file, before, after in steps():
        path = copy / file
        path.write_text(path.read_text(encoding="utf-8").replace(before, after, 1), encoding="utf-8")
    return copy


def test_following_the_steps_adds_the_column_to_every_report(tmp_path):
    copy = _copy_with_steps(tmp_path)
    script = ("import sys, fleetrun, test_fleet_fakes; from pathlib import Path; "
              "assert Path(fleetrun.__file__).is_relative_to(Path(sys.argv[1])), fleetrun.__file__; "
              "print(test_fleet_fakes.run_small_fleet_with_fake(Path(sys.argv[2])))")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(copy), str(ROOT / "tests")]))
    work = tmp_path / "work"
    work.mkdir()
    proc = subprocess.run([sys.executable, "-c", script, str(copy), str(work)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    out = Path(proc.stdout.strip().splitlines()[-1])

    classes = pd.read_csv(out / "class_summary.csv")
    assert list(classes.columns)[-1] == COLUMN
    # the page's definition, computed here independently of the copy's arithmetic
    np.testing.assert_allclose(classes[COLUMN], classes["fuel_gal_total"] / classes["vehicles"], rtol=1e-12)

    sheet = openpyxl.load_workbook(out / "report.xlsx", read_only=True)["ByClass"]
    header = [c.value for c in next(sheet.iter_rows(min_row=1, max_row=1))]
    assert COLUMN in header

    html = (out / "summary.html").read_text(encoding="utf-8")
    assert "gal_<wbr>per_<wbr>vehicle" in html   # the class table's header cell
