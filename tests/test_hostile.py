"""Regression suite of the hostile review (issue 9): each case a careless or hostile user hit.

Every test here failed on the code before the fixes (noted per test) and must keep passing:
data loss, silently wrong numbers, internal errors and hangs for input mistakes, denial of
service, formula injection, half-old/half-new output folders, diagnose's sidecar and header
handling, and the form of error messages (CONTRACT.md: the first stderr line starts with
``Error:`` and names file, sheet, row, column and value).
"""
from __future__ import annotations

import csv
import errno
import json
import os
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest
from click.testing import CliRunner

import test_fleet_fakes as fakes
from fleetrun.cli import cli
from test_fleet_fakes import scenario, small_fleet, vehicle, write_fleet

ROOT = Path(__file__).resolve().parents[1]
OUTPUTS = {"report.xlsx", "summary.html", "results.csv", "class_summary.csv", "fiscal_summary.csv", "revenue_memo.csv",
           "fiscal_periods.csv", "manifest.json"}


def invoke(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def first_line(result) -> str:
    return (result.stderr.splitlines() or [""])[0]


@pytest.fixture
def fake_simulation():
    """``fleetrun run`` below uses the stand-in simulation (test_fleet_fakes)."""
    return fakes.fake_simulate


def run_fake(*args):
    return fakes.invoke_run(*args)


# --- data loss --------------------------------------------------------------------------------

def test_out_never_overwrites_the_input_workbook(tmp_path, fake_simulation):
    """Before: `run d/report.xlsx --out d` replaced the input with the report (exit 0)."""
    folder = tmp_path / "d"
    folder.mkdir()
    workbook = small_fleet(folder / "report.xlsx")
    before = workbook.read_bytes()
    result = run_fake(workbook, "--out", folder, "-q", "--no-cache")
    assert result.exit_code == 1, result.output
    line = first_line(result)
    assert line.startswith("Error:") and "report.xlsx" in line and "--out" in line
    assert workbook.read_bytes() == before


@pytest.mark.parametrize("option", ["-o", "--measured-out"])
def test_import_epa_never_overwrites_its_input(tmp_path, option):
    """Before: `import-epa list.csv -o fleet.xlsx --measured-out list.csv` replaced the EPA list
    with the measured results (exit 0). Both outputs are checked against the input."""
    source = Path(__file__).resolve().parents[1] / "inputs" / "epa" / "22-tstcar.csv"
    listed = tmp_path / "list.xlsx" if option == "-o" else tmp_path / "list.csv"
    listed.write_bytes(source.read_bytes()[:200_000])
    before = listed.read_bytes()
    args = ["import-epa", str(listed), "-o", str(listed if option == "-o" else tmp_path / "fleet.xlsx")]
    if option == "--measured-out":
        args += ["--measured-out", str(listed)]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 1, result.output
    line = first_line(result)
    assert line.startswith("Error:") and str(listed) in line and option in line
    assert listed.read_bytes() == before


def test_simulate_trace_never_overwrites_the_fleet(tmp_path):
    """Before: `simulate fleet.xlsx --vehicle ID --cycle UDDS -o fleet.xlsx` replaced the
    workbook with the trace CSV (exit 0)."""
    workbook = small_fleet(tmp_path / "fleet.xlsx")
    before = workbook.read_bytes()
    result = CliRunner().invoke(cli, ["simulate", str(workbook), "--vehicle", "CAR-1", "--cycle", "UDDS",
                                      "-o", str(workbook)])
    assert result.exit_code == 1, result.output
    line = first_line(result)
    assert line.startswith("Error:") and "fleet.xlsx" in line and "-o" in line
    assert workbook.read_bytes() == before


def test_out_keeps_other_files_of_the_folder(tmp_path, fake_simulation):
    """An input (or any other file) in the output folder that is not an output name stays."""
    folder = tmp_path / "d"
    folder.mkdir()
    workbook = small_fleet(folder / "fleet.xlsx")
    (folder / "notes.txt").write_text("mine")
    before = workbook.read_bytes()
    result = run_fake(workbook, "--out", folder, "-q", "--no-cache")
    assert result.exit_code == 0, result.stderr
    assert workbook.read_bytes() == before and (folder / "notes.txt").read_text() == "mine"
    assert OUTPUTS <= {p.name for p in folder.iterdir()}


# --- silently wrong numbers, internal errors, hangs --------------------------------------------

VEHICLE_CASES = [  # (column, value, cell): before, each validated with 0 warnings or a mere warning
    ("count", 1e308, "E2"),                      # inf totals, exit 0
    ("annual_miles", 1e308, "F2"),               # inf totals, exit 0
    ("peak_engine_torque_Nm", 1e308, "H2"),      # infinite fuel, NaN efficiency, exit 0
    ("rated_speed_rpm", 0.5, "U2"),              # mpg 0, exit 0
    ("rated_speed_rpm", 10, "U2"),               # mpg 0, exit 0
    ("rated_power_kW", 1e-9, "T2"),              # mpg 0, exit 0
    ("test_weight_kg", 1e308, "L2"),             # exit 4 IndexError
]


@pytest.mark.parametrize("column,value,cell", VEHICLE_CASES)
def test_out_of_range_vehicle_values_refused_by_validate_and_run(tmp_path, column, value, cell):
    path = write_fleet(tmp_path / "f.xlsx", [vehicle(**{column: value})], [scenario()])
    checked = invoke("validate", path)
    assert checked.exit_code == 1, checked.output
    line = first_line(checked)
    assert line.startswith(f"Error: {path}: Vehicles!{cell} {column}:"), line
    ran = invoke("run", path, "--out", tmp_path / "out", "-q", "--no-cache")
    assert ran.exit_code == 1 and first_line(ran) == line
    assert not (tmp_path / "out").exists()


SCENARIO_CASES = [
    ("budget_years", 1e9, "E2"),        # exit 4 OverflowError
    ("budget_years", 1e6, "E2"),        # minutes and > 2 GB
    ("ambient_temp_C", -300, "C2"),     # validate passed; run failed without a cell
]


@pytest.mark.parametrize("column,value,cell", SCENARIO_CASES)
def test_out_of_range_scenario_values_refused_first_by_validate(tmp_path, column, value, cell):
    path = write_fleet(tmp_path / "f.xlsx", [vehicle()], [scenario(**{column: value})])
    started = time.perf_counter()
    checked = invoke("validate", path)
    ran = invoke("run", path, "--out", tmp_path / "out", "-q", "--no-cache")
    assert time.perf_counter() - started < 30
    assert checked.exit_code == 1 and ran.exit_code == 1
    assert first_line(checked).startswith(f"Error: {path}: Scenarios!{cell} {column}:")
    assert first_line(ran) == first_line(checked)


def test_unreadable_cycle_file_refused_by_validate(tmp_path):
    """Before: validate checked only that a cycle CSV exists; run then failed on its content."""
    (tmp_path / "mine.csv").write_text("time_s,speed\n0,abc\n")
    path = write_fleet(tmp_path / "f.xlsx", [vehicle()], [scenario(cycle_mix="mine.csv:1")])
    checked = invoke("validate", path)
    assert checked.exit_code == 1
    assert first_line(checked).startswith(f"Error: {path}: Scenarios!D2 cycle_mix:")
    assert "mine.csv" in first_line(checked)


# --- denial of service ------------------------------------------------------------------------

def _giant_reference_workbook(tmp_path) -> Path:
    """The template with one cell reference of the Vehicles sheet turned into ZZZZZZZZZZ2."""
    source = write_fleet(tmp_path / "ok.xlsx", [vehicle()], [scenario()])
    target = tmp_path / "giant.xlsx"
    with zipfile.ZipFile(source) as zin, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename.startswith("xl/worksheets/") and b'r="B2"' in data:
                data = data.replace(b'r="B2"', b'r="ZZZZZZZZZZ2"', 1)
            zout.writestr(item, data)
    return target


MEASURE = """
import resource, subprocess, sys
child = subprocess.run([sys.executable, "-m", "fleetrun", *sys.argv[1:]], stdout=subprocess.DEVNULL,
                       stderr=subprocess.PIPE)
usage = resource.getrusage(resource.RUSAGE_CHILDREN)
sys.stdout.write(f"{child.returncode} {usage.ru_maxrss} {usage.ru_utime + usage.ru_stime}\\n")
sys.stderr.buffer.write(child.stderr)
"""


def _measure(args, timeout=20) -> tuple[int, float, float, str]:
    """(exit code, CPU seconds, peak resident MB, stderr) of ``python -m fleetrun ARGS`` (CPU
    time and peak measured by a wrapper process whose only child it is). CPU time, not wall
    time: on a loaded 2-core CI machine the wall clock of a 1.5 s job varied from 1.5 to 4 s,
    while an unbounded read (the defect) burns CPU for minutes either way."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    try:
        done = subprocess.run([sys.executable, "-c", MEASURE, *map(str, args)], env=env,
                              capture_output=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return -1, timeout, 0.0, "timeout"
    code, peak_kb, cpu_seconds = done.stdout.split()
    return int(code), float(cpu_seconds), int(peak_kb) / 1024, done.stderr.decode(errors="replace")


_STARTUP: list[float] = []


def _startup_s() -> float:
    """CPU seconds `fleetrun run --help` takes here (interpreter and imports): the 2 s bound of
    issue 9 is about the work after start-up."""
    if not _STARTUP:
        code, seconds, _, _ = _measure(["run", "--help"])
        _STARTUP.append(seconds)
    return _STARTUP[0]


@pytest.mark.parametrize("command", ["validate", "run"])
def test_giant_cell_reference_refused_quickly(tmp_path, command):
    """Before: validate grew to 5 GB and died with a traceback."""
    path = _giant_reference_workbook(tmp_path)
    assert path.stat().st_size < 30_000
    args = [command, path] + (["--out", tmp_path / "out", "-q", "--no-cache"] if command == "run" else [])
    code, seconds, peak_mb, stderr = _measure(args)
    assert code == 1, stderr
    assert stderr.startswith("Error:") and "ZZZZZZZZZZ2" in stderr.splitlines()[0]
    assert seconds - _startup_s() < 2 and peak_mb < 200, (seconds, _startup_s(), peak_mb)


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
@pytest.mark.parametrize("command", ["validate", "run"])
def test_dev_zero_refused_quickly(tmp_path, command):
    """Before: `validate /dev/zero` read without bound."""
    args = [command, "/dev/zero"] + (["--out", tmp_path / "out", "-q", "--no-cache"] if command == "run" else [])
    code, seconds, peak_mb, stderr = _measure(args)
    assert code == 1, stderr
    assert stderr.startswith("Error: /dev/zero:")
    assert seconds - _startup_s() < 2 and peak_mb < 200, (seconds, _startup_s(), peak_mb)


# --- formula injection ------------------------------------------------------------------------

def test_csv_outputs_neutralise_formula_text(tmp_path, fake_simulation):
    """Before: results.csv and class_summary.csv carried =cmd|... and =HYPERLINK(...) verbatim."""
    labels = ["=cmd|'/C calc'!A0", '=HYPERLINK("http://x","y")', "+1+1", "-2+3", "@SUM(A1)",
              "\tTAB", "\rCR"]
    rows = [vehicle(f"V{i}", vehicle_class=label) for i, label in enumerate(labels)]
    rows[0]["vehicle_id"] = '=HYPERLINK("http://evil")'
    path = write_fleet(tmp_path / "f.xlsx", rows, [scenario("=1+1")])
    result = run_fake(path, "--out", tmp_path / "out", "-q", "--no-cache")
    assert result.exit_code == 0, result.stderr
    for name in ("results.csv", "class_summary.csv", "fiscal_summary.csv"):
        with open(tmp_path / "out" / name, newline="", encoding="utf-8") as handle:
            table = list(csv.reader(handle))
        for row in table[1:]:
            for cell in row:
                assert not cell or cell[0] not in "=+-@\t\r" or _is_number(cell), (name, cell)
        texts = {cell for row in table[1:] for cell in row}
        assert "'=cmd|'/C calc'!A0" in texts and "'-2+3" in texts and "'=1+1" in texts
    results = fakes.read_csv(tmp_path / "out" / "results.csv")
    assert results["fuel_gal_total"].dtype.kind == "f"     # numbers stay numbers


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


# --- half-old, half-new outputs ---------------------------------------------------------------

def _outputs_consistent(folder: Path) -> bool:
    from fleetrun.workbook.reader import file_sha256

    manifest = json.loads((folder / "manifest.json").read_text())
    return all(file_sha256(folder / name) == digest for name, digest in manifest["outputs"].items())


def test_locked_output_file_leaves_the_previous_run_whole(tmp_path, fake_simulation, monkeypatch):
    """Before: results.csv locked (Excel on Windows) -> exit 4, 3 new and 2 old files."""
    fleet = small_fleet(tmp_path / "fleet.xlsx")
    out = tmp_path / "out"
    assert run_fake(fleet, "--out", out, "-q", "--no-cache").exit_code == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    real_replace, real_rename = os.replace, os.rename

    def locked(source, target, *args, **kwargs):
        if Path(target).name == "results.csv" or Path(source) == out:
            raise PermissionError(errno.EACCES, "The process cannot access the file", str(source))
        return real_replace(source, target, *args, **kwargs)

    def locked_rename(source, target, *args, **kwargs):
        if Path(source) == out:
            raise PermissionError(errno.EACCES, "The process cannot access the file", str(source))
        return real_rename(source, target, *args, **kwargs)

    monkeypatch.setattr(os, "replace", locked)
    monkeypatch.setattr(os, "rename", locked_rename)
    scenario_changed = write_fleet(tmp_path / "fleet.xlsx", None, [scenario("other")])
    result = run_fake(scenario_changed, "--out", out, "-q", "--no-cache")
    monkeypatch.undo()
    assert result.exit_code == 1, result.stderr
    assert first_line(result).startswith("Error:") and str(out) in first_line(result)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert _outputs_consistent(out)


def test_leftover_staging_folders_cleaned_by_the_next_run(tmp_path, fake_simulation):
    """Before: a SIGKILL mid-run left .out-staging-* folders that later runs never cleaned."""
    fleet = small_fleet(tmp_path / "fleet.xlsx")
    leftover = tmp_path / ".out-staging-k1ll3d"
    leftover.mkdir()
    (leftover / "results.csv").write_text("partial")
    assert run_fake(fleet, "--out", tmp_path / "out", "-q", "--no-cache").exit_code == 0
    assert not leftover.exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


KILLER = """
import os, sys
import test_fleet_fakes as fakes
folder, when = sys.argv[1], int(sys.argv[2])
moves = [0]
def dying(name):
    real = getattr(os, name)
    def move(source, target, *args, **kwargs):
        if os.path.abspath(target).startswith(folder + os.sep):
            moves[0] += 1
            if moves[0] == when:
                os._exit(9)          # as SIGKILL: no cleanup, no finally
        return real(source, target, *args, **kwargs)
    return move
os.replace, os.rename = dying("replace"), dying("rename")
from fleetrun.cli import cli
cli.main(sys.argv[3:], prog_name="fleetrun", obj=fakes.injected())
"""


def test_killed_between_moves_never_mixes_runs(tmp_path):
    """Before: a kill between the per-file moves left a new manifest beside old results."""
    fleet = small_fleet(tmp_path / "fleet.xlsx")
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{ROOT / 'tests'}", "OMP_NUM_THREADS": "1"}
    run = ["run", str(fleet), "--out", str(out), "-q", "--no-cache"]
    assert subprocess.run([sys.executable, "-c", KILLER, str(tmp_path), "0", *run], env=env).returncode == 0
    first = json.loads((out / "manifest.json").read_text())["created_utc"]
    # kill at every move into the folder (files into staging, the two folder renames) in turn,
    # until a run has fewer moves than ``when`` and completes
    for when in range(1, 10):
        time.sleep(1.1)      # a new run has a new created_utc
        code = subprocess.run([sys.executable, "-c", KILLER, str(tmp_path), str(when), *run], env=env).returncode
        if code == 0:
            break
        assert code == 9
        if out.exists():
            assert _outputs_consistent(out)
        code = subprocess.run([sys.executable, "-c", KILLER, str(tmp_path), "0", *run], env=env).returncode
        assert code == 0 and _outputs_consistent(out)
        assert json.loads((out / "manifest.json").read_text())["created_utc"] != first
        assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    assert code == 0 and when >= 3, when     # the two folder renames at least were kill points


def test_disk_full_is_an_input_error_naming_the_output(tmp_path, fake_simulation, monkeypatch):
    """Before: disk full -> exit 4 naming the input file."""
    from fleetrun.reports import html as report_html

    fleet = small_fleet(tmp_path / "fleet.xlsx")

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(report_html, "write_summary_html", full)
    result = run_fake(fleet, "--out", tmp_path / "out", "-q", "--no-cache")
    assert result.exit_code == 1, result.stderr
    line = first_line(result)
    assert line.startswith("Error:") and "No space left" in line and str(tmp_path / "out") in line
    assert not (tmp_path / "out").exists()


def test_unwritable_output_parent_exit_1_with_path(tmp_path, fake_simulation):
    if os.geteuid() == 0:
        pytest.skip("root writes anywhere")
    fleet = small_fleet(tmp_path / "fleet.xlsx")
    parent = tmp_path / "ro"
    parent.mkdir()
    parent.chmod(0o500)
    try:
        result = run_fake(fleet, "--out", parent / "out", "-q", "--no-cache")
    finally:
        parent.chmod(0o700)
    assert result.exit_code == 1
    assert first_line(result).startswith("Error:") and str(parent / "out") in first_line(result)


# --- diagnose ---------------------------------------------------------------------------------

def _rig_recording(folder: Path, sidecar: bytes, header_extra: str = "") -> Path:
    import numpy as np

    t = np.arange(0, 60, 0.5)
    rows = "\n".join(f"{x:g},{100 + 10 * np.sin(x):.4f},{1500 + x:.1f},{350 + 30 * np.sin(x):.4f}" for x in t)
    path = folder / "rig.csv"
    path.write_text("time_s,diff_input_torque_Nm,diff_input_speed_rpm,diff_output_torque_Nm"
                    + header_extra + "\n" + rows + "\n")
    (folder / "rig.toml").write_bytes(sidecar)
    return path


GOOD_SIDECAR = (b'configuration = "LD_RWD"\ngear_ratio = 3.73\npeak_engine_torque_Nm = 400\n'
                b"torque_converter_ratio = 3.0\nmax_transmission_gear_ratio = 4.0\n")


def test_diagnose_sidecar_not_utf8(tmp_path):
    """Before: a traceback (UnicodeDecodeError)."""
    path = _rig_recording(tmp_path, GOOD_SIDECAR + b'lubricant = "75W\xe990"\n')
    result = invoke("diagnose", path, "--out", tmp_path / "d")
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith(f"Error: {tmp_path / 'rig.toml'}:") and "UTF-8" in first_line(result)


def test_diagnose_huge_header_line_is_truncated_in_the_message(tmp_path):
    """Before: a 30 MB header line was echoed whole into the error."""
    path = tmp_path / "rig.csv"
    path.write_text("time_s," + "x" * 30_000_000 + "\n" + "".join(f"{t},1\n" for t in range(40)))
    (tmp_path / "rig.toml").write_bytes(GOOD_SIDECAR)
    result = invoke("diagnose", path, "--out", tmp_path / "d")
    assert result.exit_code == 1
    assert first_line(result).startswith("Error:") and len(result.stderr) < 2000


def test_diagnose_unknown_lubricant_names_file_and_key(tmp_path):
    path = _rig_recording(tmp_path, GOOD_SIDECAR + b'lubricant = "snake oil"\n')
    result = invoke("diagnose", path, "--out", tmp_path / "d")
    assert result.exit_code == 1, result.output
    line = first_line(result)
    assert line.startswith(f"Error: {tmp_path / 'rig.toml'}: key lubricant:") and "snake oil" in line


# --- form -------------------------------------------------------------------------------------

def test_cell_error_first_line_names_file_sheet_cell_and_value(tmp_path):
    """Before: two lines, the first naming only the file."""
    path = write_fleet(tmp_path / "f.xlsx", [vehicle(peak_engine_torque_Nm="abc"), vehicle("B", count=-1)],
                       [scenario()])
    for command in (["validate", path], ["run", path, "--out", tmp_path / "o", "-q", "--no-cache"]):
        result = invoke(*command)
        assert result.exit_code == 1
        line = first_line(result)
        assert line.startswith(f"Error: {path}: Vehicles!H2 peak_engine_torque_Nm: 'abc' is not a number")
        assert "Vehicles!E3 count" in result.stderr      # the other problems follow


def test_map_gear_ratio_not_a_number_is_a_usage_error():
    """Before: exit 1."""
    result = invoke("map", "LD_RWD", "--gear-ratio", "abc")
    assert result.exit_code == 2
    assert "abc" in result.output


def test_mix_of_thirds_is_normalised_with_a_warning(tmp_path):
    """Before: 0.33,0.33,0.33 was refused though the code's comment says it is normalised."""
    path = write_fleet(tmp_path / "f.xlsx", [vehicle()], [scenario(cycle_mix="UDDS:0.33,HWFET:0.33,US06:0.33")])
    result = invoke("validate", path)
    assert result.exit_code == 0, result.stderr
    assert "Scenarios!D2 cycle_mix: shares add up to 0.99; scaled to 1" in result.stderr


def test_quiet_says_what_it_silences_and_silences_it(tmp_path, fake_simulation):
    """Before: the help said -q silences stderr, while log lines went to stdout when piped."""
    help_text = run_fake("--help").output
    assert "stdout" in help_text.split("--quiet", 1)[1].split("\n  -", 1)[0]
    result = run_fake(small_fleet(tmp_path / "f.xlsx"), "--out", tmp_path / "o", "-q", "--no-cache")
    assert result.exit_code == 0 and result.stdout == "" and result.stderr == ""
