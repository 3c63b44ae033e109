"""`fleetrun map`: output formats, plots, and bad arguments (exit 1, one `Error:` line, no traceback)."""
import csv
import io
import json

import pytest
from click.testing import CliRunner

from fleetrun.cli import cli


def run(*args):
    return CliRunner().invoke(cli, list(args))


def test_default_grid_is_thesis_tables_6_1_and_6_2():
    result = run("map", "LD_RWD", "--gear-ratio", "3")
    assert result.exit_code == 0
    rows = list(csv.DictReader(io.StringIO(result.output)))
    assert [(float(r["torque_fraction"]), float(r["speed_rpm"])) for r in rows][:6] == [
        (0, 0), (0, 1000), (0, 2000), (0, 3000), (0, 4000), (0.25, 0)]
    assert len(rows) == 25


def test_configuration_names_are_case_and_dash_insensitive():
    a = run("map", "hd-tandem", "--gear-ratio", "4.1").output
    b = run("map", "HD_TANDEM", "--gear-ratio", "4.1").output
    assert a == b and a.startswith("torque_fraction,speed_rpm,efficiency")


def test_json_has_grid_and_points():
    result = run("map", "HD_DUAL", "--gear-ratio", "3.73", "--low-gear-ratio", "4.900735", "--axle-gear", "low",
                 "--format", "json", "--torque-fractions", "0.2,0.4", "--speeds-rpm", "500,1500,2500")
    assert result.exit_code == 0, result.output
    doc = json.loads(result.output)
    assert doc["configuration"] == "HD_DUAL" and doc["axle_gear"] == "low"
    assert len(doc["efficiency"]) == 2 and len(doc["efficiency"][0]) == 3 and len(doc["points"]) == 6


def test_output_file_and_plots(tmp_path):
    out = tmp_path / "map.csv"
    for name in ("map.png", "map.svg"):
        result = run("map", "LD_FWD", "--gear-ratio", "3", "-o", str(out), "--plot", str(tmp_path / name))
        assert result.exit_code == 0, result.output
        assert (tmp_path / name).stat().st_size > 1000
    assert out.read_text().startswith("torque_fraction,speed_rpm,efficiency")
    assert (tmp_path / "map.svg").read_text().lstrip().startswith("<?xml")


def test_vecto_baseline_is_selectable():
    thesis = run("map", "HD_RWD", "--gear-ratio", "3.9").output
    vecto = run("map", "HD_RWD", "--gear-ratio", "3.9", "--physics", "vecto-generic").output
    assert thesis != vecto and vecto.startswith("torque_fraction")


@pytest.mark.parametrize("args, expected", [
    (["map", "LD_RWDX", "--gear-ratio", "3"], ["unknown configuration 'LD_RWDX'", "did you mean 'LD_RWD'", "HD_TAG_DUAL"]),
    (["map", "LD_RWD", "--gear-ratio", "0"], ["gear ratio must be a positive number"]),
    (["map", "LD_RWD", "--gear-ratio", "-2.5"], ["gear ratio must be a positive number"]),
    (["map", "LD_RWD", "--gear-ratio", "3", "--speeds-rpm", "0,-100"], ["speed must be >= 0 rpm", "-100"]),
    (["map", "HD_DUAL", "--gear-ratio", "3"], ["needs its low gear ratio", "--low-gear-ratio"]),
    (["map", "HD_RWD", "--gear-ratio", "3", "--physics", "thesiss"], ["unknown physics 'thesiss'", "did you mean 'thesis'", "vecto-generic"]),
    (["map", "HD_RWD", "--gear-ratio", "3", "--plot", "map.pdf"], ["must end in .png or .svg"]),
])
def test_bad_arguments_exit_1_with_error_line(args, expected, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = run(*args)
    assert result.exit_code == 1, result.output
    assert result.output.startswith("Error: ")
    assert "Traceback" not in result.output
    for text in expected:
        assert text in result.output
    assert not (tmp_path / "map.pdf").exists()


def test_usage_error_exits_2():
    assert run("map", "LD_RWD").exit_code == 2  # --gear-ratio missing


@pytest.mark.parametrize("args,expected", [
    (["--gear-ratio", "abc"], "--gear-ratio: 'abc' is not a number"),
    (["--gear-ratio", "nan"], "--gear-ratio: 'nan' is not a finite number"),
    (["--gear-ratio", "3", "--torque-fractions", "0,0.5,x"], "--torque-fractions: item 3 'x' is not a number"),
    (["--gear-ratio", "3", "--torque-fractions", ""], "--torque-fractions: empty list"),
])
def test_unparsable_numbers_are_usage_errors(args, expected):
    """A value that is not a number is a usage error (exit 2), issue 9."""
    result = run("map", "LD_RWD", *args)
    assert result.exit_code == 2, result.output
    assert expected in result.output and "Traceback" not in result.output


def test_failed_run_keeps_previous_output(tmp_path):
    out = tmp_path / "map.csv"
    assert run("map", "LD_RWD", "--gear-ratio", "3", "-o", str(out)).exit_code == 0
    before = out.read_text()
    assert run("map", "LD_RWD", "--gear-ratio", "3", "--speeds-rpm", "-1", "-o", str(out)).exit_code == 1
    assert out.read_text() == before


def test_vecto_generic_refuses_light_duty():
    result = run("map", "LD_RWD", "--gear-ratio", "3", "--physics", "vecto-generic")
    assert result.exit_code == 1
    assert "heavy-duty axles only" in result.output and "--physics thesis" in result.output


@pytest.mark.parametrize("option", ["-o", "--plot"])
def test_unwritable_output_path_is_an_error_not_a_traceback(option, tmp_path):
    blocker = tmp_path / "m.csv"
    blocker.write_text("x")
    target = blocker / ("x.png" if option == "--plot" else "x.csv")
    result = run("map", "LD_RWD", "--gear-ratio", "3", option, str(target))
    assert result.exit_code == 1
    assert result.output.startswith("Error: ") and "cannot create the output folder" in result.output
    assert blocker.read_text() == "x"


def test_file_system_errors_become_error_lines(monkeypatch):
    """The CLI's last line of defence: an OSError from a user's path (here -o) is an Error line,
    exit 1 (an OSError on any other path is an internal error: tests/test_failures_visible.py)."""
    import fleetrun.commands.map as map_command

    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied", "/locked/map.csv")

    monkeypatch.setattr(map_command, "compute_map", refuse)
    result = run("map", "LD_RWD", "--gear-ratio", "3", "-o", "/locked/map.csv")
    assert result.exit_code == 1
    assert result.output.startswith("Error: /locked/map.csv: Permission denied")
