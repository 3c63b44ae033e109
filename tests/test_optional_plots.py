"""matplotlib is the optional ``plots`` extra (pyproject.toml): without it `fleetrun map --plot`
says what to install (one ``Error:`` line, exit 1) and diagnosis.html is written without its
figures, saying why; everything else never imports it."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from fleetrun.cli import cli
from fleetrun.diagnose import report
from fleetrun.errors import MissingExtraError
from fleetrun.plots import pyplot

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def no_matplotlib(monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)   # `import matplotlib` raises ImportError


def test_map_plot_without_matplotlib_is_a_clear_error(no_matplotlib, tmp_path):
    result = CliRunner().invoke(cli, ["map", "LD_RWD", "--gear-ratio", "3.73", "--plot", str(tmp_path / "m.png")])
    assert result.exit_code == 1
    assert result.stderr.startswith("Error: --plot (an efficiency-map figure) needs matplotlib")
    assert 'pip install "fleetrun[plots]"' in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / "m.png").exists()


def test_diagnosis_figures_are_left_out_without_matplotlib(no_matplotlib):
    with pytest.raises(MissingExtraError):
        pyplot("x")
    assert report.figures(problem=None, result={}, fitted=None) == {}


def test_run_and_validate_never_import_matplotlib():
    code = ("import sys; from click.testing import CliRunner; from fleetrun.cli import cli; "
            "r = CliRunner().invoke(cli, ['validate', 'inputs/example_fleet.xlsx']); "
            "assert r.exit_code == 0, r.output; "
            "import fleetrun.run.runner, fleetrun.run.outputs, fleetrun.reports.xlsx, fleetrun.reports.html; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('matplotlib', 'scipy', 'dask')))")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"
