"""Failures stay visible (issue 8): an internal error always leaves its traceback in a log file
whose path the one ``Error:`` line names (exit 4); only a path the user gave is "check the
path" (exit 1); a damaged map-cache file is rebuilt, any other failure in the cache is not
swallowed."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from fleetrun.cli import cli
from fleetrun.commands import map as map_command
from fleetrun.simulation import diffmodes

MAP = ["map", "LD_RWD", "--gear-ratio", "3.55", "--speeds-rpm", "1000", "--torque-fractions", "0.5"]


def invoke(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def logged_traceback(stderr: str) -> str:
    """The log file the Error line names, read."""
    first = stderr.splitlines()[0]
    match = re.search(r"the traceback is in (\S+);", first)
    assert match, first
    return Path(match.group(1)).read_text()


def test_internal_error_leaves_its_traceback_in_the_named_log(monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("a bug in the map")

    monkeypatch.setattr(map_command, "compute_map", broken)
    result = invoke(*MAP)
    assert result.exit_code == 4
    assert result.stderr.startswith("Error: internal error (RuntimeError: a bug in the map)")
    assert len(result.stderr.strip().splitlines()) == 1           # one line, no traceback on screen
    text = logged_traceback(result.stderr)
    assert "Traceback" in text and "a bug in the map" in text and "broken" in text


def test_internal_oserror_is_not_a_path_mistake(monkeypatch):
    def broken(*args, **kwargs):
        raise PermissionError(13, "Permission denied", "/nonexistent-internal-folder/map.npz")

    monkeypatch.setattr(map_command, "compute_map", broken)
    result = invoke(*MAP)
    assert result.exit_code == 4
    assert "Check the path" not in result.stderr
    assert "PermissionError" in logged_traceback(result.stderr)


def test_oserror_on_the_users_path_is_a_user_mistake(monkeypatch, tmp_path):
    target = tmp_path / "map.csv"

    def refused(*args, **kwargs):
        raise PermissionError(13, "Permission denied", str(target))

    monkeypatch.setattr(map_command, "compute_map", refused)
    result = invoke(*MAP, "-o", target)
    assert result.exit_code == 1
    assert result.stderr.startswith(f"Error: {target}: Permission denied. Check the path")


def test_run_without_log_still_keeps_the_traceback(tmp_path, monkeypatch):
    from test_fleet_fakes import small_fleet

    from fleetrun.reports import html as report_html

    fleet = small_fleet(tmp_path / "fleet.xlsx")

    def broken(*args, **kwargs):
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(report_html, "render_summary", broken)
    result = invoke("run", fleet, "--out", tmp_path / "out", "--no-cache", "-q")
    assert result.exit_code == 4
    text = logged_traceback(result.stderr)
    assert "Traceback" in text and "disk on fire" in text


def test_damaged_cache_file_is_rebuilt_other_failures_are_not_swallowed(tmp_path, monkeypatch):
    gears, maps = diffmodes.map3d("LD_FWD", None, "thesis", 20.0, tmp_path)
    diffmodes._LOADED.clear()
    (cache_file,) = tmp_path.glob("map3d-LD_FWD-*.npz")
    cache_file.write_bytes(b"not a zip file")                      # damaged: rebuilt, same maps
    again = diffmodes.map3d("LD_FWD", None, "thesis", 20.0, tmp_path)[1]
    np.testing.assert_array_equal(again, maps)
    diffmodes._LOADED.clear()

    def bug(*args, **kwargs):
        raise TypeError("a bug, not a damaged file")

    monkeypatch.setattr(diffmodes.np, "load", bug)
    with pytest.raises(TypeError, match="a bug"):
        diffmodes.map3d("LD_FWD", None, "thesis", 20.0, tmp_path)
