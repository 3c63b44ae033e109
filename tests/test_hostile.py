"""Regression suite of the hostile review (issue 9): each case a careless or hostile user hit.

Every test here failed on the code before the fixes (noted per test) and must keep passing:
data loss, silently wrong numbers, internal errors and hangs for input mistakes, denial of
service, formula injection, half-old/half-new output folders, diagnose's sidecar and header
handling, and the form of error messages (docs/interface.md: the first stderr line starts with
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
    from fleetrun.run import outputs

    fleet = small_fleet(tmp_path / "fleet.xlsx")

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(outputs, "write_summary_html", full)
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


# === round two (issue 18) ======================================================================
# --- data lost --------------------------------------------------------------------------------

RUNNER = """
import sys
import test_fleet_fakes as fakes
from fleetrun.cli import cli
cli.main(sys.argv[1:], prog_name="fleetrun", obj=fakes.injected())
"""


def _kept_fleets(out: Path) -> list[str]:
    """The fleet workbook of every run the folder holds: its own and those in earlier-runs/."""
    manifests = [out / "manifest.json", *sorted((out / "earlier-runs").glob("*/manifest.json"))]
    return sorted(json.loads(m.read_text())["inputs"][0]["path"] for m in manifests if m.is_file())


def _concurrent_runs(tmp_path: Path, n: int) -> None:
    out = tmp_path / "out"
    fleets = [write_fleet(tmp_path / f"fleet{i}.xlsx", [vehicle(f"CAR-{i}")], [scenario(f"s{i}")])
              for i in range(n)]
    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{ROOT / 'tests'}", "OMP_NUM_THREADS": "1"}
    runs = [subprocess.Popen([sys.executable, "-c", RUNNER, "run", str(f), "--out", str(out), "-q",
                              "--no-cache"], env=env, stderr=subprocess.PIPE) for f in fleets]
    codes = [(r.wait(timeout=600), r.stderr.read().decode()) for r in runs]
    assert all(code == 0 for code, _ in codes), codes
    assert _kept_fleets(out) == sorted(str(f) for f in fleets)
    assert _outputs_consistent(out)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_two_concurrent_runs_into_one_folder_lose_nothing(tmp_path):
    """Before: of two runs into one --out at the same time, both exit 0 and the outputs of one
    were nowhere (6 of 12 in 6 rounds). Now the second waits for the first's lock."""
    _concurrent_runs(tmp_path, 2)


@pytest.mark.slow
def test_eight_concurrent_runs_into_one_folder_lose_nothing(tmp_path):
    _concurrent_runs(tmp_path, 8)


def test_a_held_folder_lock_is_an_error_naming_the_holder(tmp_path, fake_simulation, monkeypatch):
    """A run that cannot get the folder's lock in $FLEETRUN_LOCK_WAIT_S exits 1 naming the holder."""
    import fcntl

    out = tmp_path / "out"
    lock = tmp_path / ".out.fleetrun-lock"
    with open(lock, "w") as handle:
        handle.write("pid 4242 since now")
        handle.flush()
        fcntl.flock(handle, fcntl.LOCK_EX)
        monkeypatch.setenv("FLEETRUN_LOCK_WAIT_S", "0.3")
        result = run_fake(small_fleet(tmp_path / "f.xlsx"), "--out", out, "-q", "--no-cache")
    assert result.exit_code == 1, result.output
    line = first_line(result)
    assert line.startswith(f"Error: {out}: another fleetrun run") and "pid 4242" in line
    assert not out.exists()


def _batch(tmp_path: Path, text: str) -> Path:
    config = tmp_path / "batch.toml"
    config.write_text(text)
    return config


@pytest.mark.parametrize("replace", [False, True])
def test_batch_inputs_with_one_file_name_never_collide(tmp_path, fake_simulation, replace):
    """Before: north/fleet.xlsx and south/fleet.xlsx both went to results/fleet/; north only
    in earlier-runs/, with --replace gone."""
    for name in ("north", "south"):
        (tmp_path / name).mkdir()
        write_fleet(tmp_path / name / "fleet.xlsx", [vehicle(f"{name.upper()}-1")], [scenario(name)])
    config = _batch(tmp_path, 'inputs = ["north/fleet.xlsx", "south/fleet.xlsx"]\nout = "results"\n')
    result = run_fake("--config", config, "-q", "--no-cache", *(["--replace"] if replace else []))
    assert result.exit_code == 0, result.stderr
    for name in ("north", "south"):
        folder = tmp_path / "results" / f"{name}-fleet"
        assert _kept_fleets(folder) == [str(tmp_path / name / "fleet.xlsx")]


def test_files_another_program_writes_during_a_run_survive(tmp_path, fake_simulation, monkeypatch):
    """Before: files written into --out while the run assembled its folder were deleted with
    the old folder (4 of 412)."""
    from fleetrun import output_folder

    out = tmp_path / "out"
    out.mkdir()
    (out / "theirs-0.txt").write_text("0")
    real = output_folder._carry_over

    def meanwhile(old, new, replaced):
        real(old, new, replaced)
        for i in range(1, 50):       # the other program keeps writing
            (old / f"theirs-{i}.txt").write_text(str(i))
        (old / "theirs-0.txt").unlink()
        (old / "theirs-0.txt").write_text("rewritten")

    monkeypatch.setattr(output_folder, "_carry_over", meanwhile)
    result = run_fake(small_fleet(tmp_path / "f.xlsx"), "--out", out, "-q", "--no-cache")
    assert result.exit_code == 0, result.stderr
    assert sorted(p.name for p in out.glob("theirs-*")) == sorted(f"theirs-{i}.txt" for i in range(50))
    assert (out / "theirs-0.txt").read_text() == "rewritten"


def test_log_naming_the_input_workbook_is_refused(tmp_path, fake_simulation):
    """Before: `run fleet.xlsx --log fleet.xlsx` appended log lines to the input."""
    fleet = small_fleet(tmp_path / "fleet.xlsx")
    before = fleet.read_bytes()
    result = run_fake(fleet, "--log", fleet, "--out", tmp_path / "out", "--no-cache")
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith(f"Error: {fleet}: is an input") and "--log" in first_line(result)
    assert fleet.read_bytes() == before and not (tmp_path / "out").exists()


def test_config_log_naming_a_folder_is_exit_1(tmp_path, fake_simulation):
    """Before: `log = "logs"` (a folder) in batch.toml: exit 4 (IsADirectoryError)."""
    small_fleet(tmp_path / "fleet.xlsx")
    (tmp_path / "logs").mkdir()
    config = _batch(tmp_path, 'inputs = ["fleet.xlsx"]\nlog = "logs"\n')
    result = run_fake("--config", config, "-q", "--no-cache")
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith(f"Error: {config}: key log: {tmp_path / 'logs'} is a folder")


@pytest.mark.parametrize("command", ["diagnose-fleet", "diagnose"])
def test_diagnosis_never_overwrites_its_input(tmp_path, command):
    """Before: `diagnose-fleet --measured out/diagnosis.json --out out` overwrote the input."""
    out = tmp_path / "out"
    out.mkdir()
    measured = out / "diagnosis.json"
    measured.write_text("vehicle_id,test,mpg,manufacturer\nCAR-1,FTP,30,A\n")
    fleet = small_fleet(tmp_path / "fleet.xlsx")
    args = ([command, fleet, "--measured", measured, "--out", out] if command == "diagnose-fleet"
            else [command, measured, "--out", out])
    result = invoke(*args)
    assert result.exit_code == 1, result.output
    line = first_line(result)
    assert line.startswith(f"Error: {measured}: is an input") and "--out" in line
    assert measured.read_text().startswith("vehicle_id")


def test_out_dotdot_writes_the_parent_and_nothing_recursive(tmp_path, fake_simulation, monkeypatch):
    """Before: `--out ..` from a subfolder put the staging folder inside the copied parent."""
    sub = tmp_path / "parent" / "sub"
    sub.mkdir(parents=True)
    fleet = small_fleet(sub / "fleet.xlsx")
    before = fleet.read_bytes()
    monkeypatch.chdir(sub)
    result = run_fake("fleet.xlsx", "--out", "..", "-q", "--no-cache")
    assert result.exit_code == 0, result.stderr
    parent = tmp_path / "parent"
    assert OUTPUTS <= {p.name for p in parent.iterdir()}
    assert sorted(p.name for p in sub.iterdir()) == ["fleet.xlsx"] and fleet.read_bytes() == before
    assert [p.name for p in tmp_path.rglob(".*")] == []


def test_read_only_out_is_refused_and_left_alone(tmp_path, fake_simulation, monkeypatch):
    """Before: a read-only --out (non-root user) was replaced by a writable one. (As root
    every folder is writable, so the test tells the check that it is not.)"""
    from fleetrun import output_folder

    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("mine")
    if os.geteuid() == 0:
        real = output_folder._writable
        monkeypatch.setattr(output_folder, "_writable", lambda folder: folder != out and real(folder))
    out.chmod(0o555)
    try:
        result = run_fake(small_fleet(tmp_path / "f.xlsx"), "--out", out, "-q", "--no-cache")
        inode = out.stat().st_ino
    finally:
        out.chmod(0o755)
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith(f"Error: {out}: the output folder is read-only")
    assert sorted(p.name for p in out.iterdir()) == ["mine.txt"] and inode == out.stat().st_ino


@pytest.mark.skipif(os.geteuid() == 0, reason="root removes read-only folders anyway")
def test_no_old_folders_pile_up_beside_out(tmp_path, fake_simulation):
    """Before: an --out holding a read-only subfolder left one .out-old-* per run."""
    out = tmp_path / "out"
    (out / "frozen").mkdir(parents=True)
    (out / "frozen" / "a.txt").write_text("a")
    (out / "frozen").chmod(0o555)
    fleet = small_fleet(tmp_path / "f.xlsx")
    try:
        for _ in range(3):
            assert run_fake(fleet, "--out", out, "-q", "--no-cache").exit_code == 0
        assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
        assert (out / "frozen" / "a.txt").read_text() == "a"
    finally:
        for folder in tmp_path.rglob("frozen"):
            folder.chmod(0o755)


def test_foreign_manifest_in_out_is_exit_1_and_kept(tmp_path, fake_simulation):
    """Before: a manifest.json of another program in --out: exit 4 (or replaced)."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "manifest.json").write_text('{"inputs": "not fleetrun", "totals": [1]}')
    (out / "results.csv").write_text("theirs\n")
    result = run_fake(small_fleet(tmp_path / "f.xlsx"), "--out", out, "-q", "--no-cache")
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith(f"Error: {out}: holds results.csv, manifest.json that fleetrun did not write")
    assert (out / "results.csv").read_text() == "theirs\n"


def test_batch_config_without_out_writes_beside_the_config(tmp_path, fake_simulation, monkeypatch):
    """Before: results/ in the working folder, though docs/batch.md says paths are relative
    to the config file."""
    jobs = tmp_path / "jobs"
    jobs.mkdir()
    small_fleet(jobs / "fleet.xlsx")
    config = _batch(jobs, 'inputs = ["fleet.xlsx"]\n')
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    result = run_fake("--config", config, "-q", "--no-cache")
    assert result.exit_code == 0, result.stderr
    assert (jobs / "results" / "fleet" / "manifest.json").is_file() and list(elsewhere.iterdir()) == []


def test_batch_config_values_are_option_defaults(tmp_path, fake_simulation):
    """The config's keys are the options' defaults (click's default_map); the command line wins."""
    small_fleet(tmp_path / "fleet.xlsx")
    config = _batch(tmp_path, 'inputs = ["fleet.xlsx"]\nout = "r"\nscenarios = ["hot"]\n')
    result = run_fake("--config", config, "-q", "--no-cache", "--scenario", "urban")
    assert result.exit_code == 0, result.stderr
    assert json.loads((tmp_path / "r" / "fleet" / "manifest.json").read_text())["scenarios"] == ["urban"]


# --- hostile files ----------------------------------------------------------------------------

def _far_cell_workbook(tmp_path: Path, name: str, ref: bytes, upper=False, strict=False) -> Path:
    """The template with cell B2 of Vehicles moved to ``ref``; ``upper``: the workbook's
    relationship names the sheet /XL/worksheets/...; ``strict``: Strict OOXML namespaces."""
    source = write_fleet(tmp_path / "ok.xlsx", [vehicle()], [scenario()])
    target = tmp_path / name
    with zipfile.ZipFile(source) as zin, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename.startswith("xl/worksheets/") and b'r="B2"' in data:
                data = data.replace(b'r="B2"', b'r="' + ref + b'"', 1)
            if upper and item.filename == "xl/_rels/workbook.xml.rels":
                data = data.replace(b'Target="/xl/worksheets/', b'Target="/XL/worksheets/')
            if strict and item.filename == "xl/workbook.xml":
                data = (data.replace(b"http://schemas.openxmlformats.org/officeDocument/2006/relationships",
                                     b"http://purl.oclc.org/ooxml/officeDocument/relationships")
                        .replace(b"http://schemas.openxmlformats.org/spreadsheetml/2006/main",
                                 b"http://purl.oclc.org/ooxml/spreadsheetml/main"))
            zout.writestr(item, data)
    return target


@pytest.mark.parametrize("upper,strict", [(True, False), (False, True)])
def test_prescan_reads_relationships_as_the_reader_does(tmp_path, upper, strict):
    """Before: an upper-case target (/XL/worksheets/...) or Strict OOXML namespaces bypassed
    the pre-scan; a 1-cell XFD1048576 workbook aborted the reader (exit 134, a Rust backtrace)."""
    path = _far_cell_workbook(tmp_path, "far.xlsx", b"XFD1048576", upper=upper, strict=strict)
    code, seconds, peak_mb, stderr = _measure(["validate", path])
    assert code == 1, stderr[:500]
    assert stderr.startswith(f"Error: {path}: sheet Vehicles spans 1,048,576 rows x 16,384 columns")
    assert seconds - _startup_s() < 2 and peak_mb < 500, (seconds, peak_mb)


def test_a_stray_far_cell_within_the_cell_budget_is_located(tmp_path):
    """Before (with the bypass): a workbook sized to allocate took 58 s and 8.1 GB. A used range
    inside the budget that the cells do not fill is a stray cell, named."""
    # Z64000: a reach of 26 x 64,000 = 1.7 M cells (beyond the 1 M floor) that one cell fills
    path = _far_cell_workbook(tmp_path, "stray.xlsx", b"Z64000", upper=True)
    code, seconds, peak_mb, stderr = _measure(["validate", path])
    assert code == 1, stderr[:500]
    assert stderr.startswith(f"Error: {path}: Vehicles!Z64000: a cell far from the table")
    assert seconds - _startup_s() < 2 and peak_mb < 500, (seconds, peak_mb)


def _cycle(tmp_path: Path, text: str, name: str = "mine.csv") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _trace(n: int, time_scale: float = 1.0, speed_scale: float = 1.0, grade: float | None = None) -> str:
    head = "time_s,speed_mps" + (",grade_pct" if grade is not None else "")
    rows = [f"{i * time_scale:g},{speed_scale * 10 * (1 - abs(1 - i / (n / 2))):g}"
            + (f",{grade:g}" if grade is not None else "") for i in range(n)]
    return head + "\n" + "\n".join(rows) + "\n"


CYCLE_CASES = [   # before: each accepted, numbers silently wrong
    (_trace(60, speed_scale=1000), "row 3, column speed_mps: speed 333.333 m/s"),
    (_trace(60, grade=5000), "row 2, column grade_pct: grade 5,000 %"),
    (_trace(60, time_scale=1000), "row 3, column time_s: the usual time step is 1,000 s"),
    ("time_s,speed_mps\n" + "".join(f"{i},0\n" for i in range(60)), "column speed_mps: every speed is 0"),
]


@pytest.mark.parametrize("text,message", CYCLE_CASES, ids=["speed_x1000", "grade_5000", "time_ms", "all_zero"])
def test_implausible_cycles_refused_by_validate_and_run(tmp_path, text, message):
    """Before: speeds x1000, a 5000 % grade, milliseconds in time_s accepted; an all-zero-speed
    cycle passed validate and failed run with exit 4."""
    cycle = _cycle(tmp_path, text)
    assert invoke("cycles", cycle).exit_code == 1
    assert message in first_line(invoke("cycles", cycle))
    text = message.split(": ", 1)[1]
    path = write_fleet(tmp_path / "f.xlsx", [vehicle()], [scenario(cycle_mix="mine.csv:1")])
    for args in (["validate", path], ["run", path, "--out", tmp_path / "out", "-q", "--no-cache"]):
        result = invoke(*args)
        assert result.exit_code == 1, result.output
        assert first_line(result).startswith(f"Error: {path}: Scenarios!D2 cycle_mix:"), first_line(result)
        assert text in first_line(result)


def test_ten_million_row_cycle_refused_within_bounds(tmp_path):
    """Before: a 10-million-row cycle CSV took 3.2 GB."""
    path = tmp_path / "long.csv"
    with open(path, "w") as handle:
        handle.write("time_s,speed_mps\n")
        handle.write("0,1\n" * 10_000_000)
    code, seconds, peak_mb, stderr = _measure(["cycles", path])
    assert code == 1, stderr[:500]
    assert stderr.startswith(f"Error: {path}: row 500,002") or stderr.startswith(f"Error: {path}: row 500002"), stderr
    assert "500,000 rows" in stderr
    assert seconds - _startup_s() < 2 and peak_mb < 500, (seconds, peak_mb)


ESCAPE_XML = b"_x001B_]0pwned_x0007__x001B_[2J"    # ESC ] 0 pwned BEL ESC [ 2 J, as OOXML escapes them


def _with_escapes(source: Path, target: Path) -> Path:
    """``source`` with every text ``ESC`` replaced by terminal escape sequences (openpyxl
    refuses to write them; Excel stores them as _xHHHH_)."""
    with zipfile.ZipFile(source) as zin, zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            zout.writestr(item, zin.read(item.filename).replace(b"ESC", ESCAPE_XML))
    return target


def test_escape_sequences_in_cells_never_reach_the_terminal(tmp_path):
    """Before: a cell holding ESC ] 0 ; ... (retitles a terminal) was echoed raw to stderr."""
    import openpyxl

    source = write_fleet(tmp_path / "plain.xlsx", [vehicle(vehicle_class="CarESC")],
                         [scenario("baseESC"), scenario("badESC", cycle_mix="NOPEESC:1")])
    book = openpyxl.load_workbook(source)
    book["Vehicles"].cell(row=1, column=40, value="noteESC")     # a header fleetrun does not know
    book.create_sheet("SheetESC")
    book.save(source)
    path = _with_escapes(source, tmp_path / "f.xlsx")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-m", "fleetrun", "validate", str(path)], env=env,
                          capture_output=True, timeout=120)
    assert done.returncode == 1, done.stderr
    assert done.stderr.startswith(b"Error:") and b"\\x1b]0pwned\\x07" in done.stderr, done.stderr
    assert b"\x1b" not in done.stderr and b"\x07" not in done.stderr and b"\x1b" not in done.stdout


def test_ctrl_c_is_an_error_line_and_exit_1(tmp_path, fake_simulation, monkeypatch):
    """Before: Ctrl-C printed "Aborted!" and no Error: line."""
    from fleetrun.run import batch

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(batch, "read_fleet", interrupted)   # where the run looks it up
    result = run_fake(small_fleet(tmp_path / "f.xlsx"), "--out", tmp_path / "out", "-q", "--no-cache")
    assert result.exit_code == 1
    assert first_line(result).startswith("Error: interrupted (Ctrl-C)") and "Aborted" not in result.stderr
    assert not (tmp_path / "out").exists()


def test_four_hundred_temperatures_refused_within_bounds(tmp_path):
    """Before: a 40 KB workbook with 400 scenarios at 400 temperatures peaked at 3.4 GB."""
    path = write_fleet(tmp_path / "f.xlsx", [vehicle()],
                       [scenario(f"s{i}", ambient_temp_C=-40 + i * 0.25) for i in range(400)])
    code, seconds, peak_mb, stderr = _measure(["run", path, "--out", tmp_path / "out", "-q", "--no-cache"])
    assert code == 1, stderr[:500]
    assert stderr.startswith(f"Error: {path}: Scenarios!C26 ambient_temp_C: -34 is distinct ambient temperature number 25")
    assert seconds - _startup_s() < 2 and peak_mb < 500, (seconds, peak_mb)


def test_map_grid_budget_before_allocation():
    """Before: `map` with 15,000 x 15,000 points from two 90 KB arguments took 10.3 GB."""
    speeds = ",".join(str(i) for i in range(15_000))
    fractions = ",".join(f"{i / 15_000:.5f}" for i in range(15_000))
    code, seconds, peak_mb, stderr = _measure(["map", "LD_RWD", "--gear-ratio", "3.2", "--speeds-rpm", speeds,
                                               "--torque-fractions", fractions])
    assert code == 1, stderr[:500]
    assert stderr.startswith("Error: --torque-fractions x --speeds-rpm grid points: 225,000,000")
    assert seconds - _startup_s() < 2 and peak_mb < 500, (seconds, peak_mb)


def test_map_gear_ratio_out_of_range_is_exit_1():
    """Before: `map --gear-ratio 1e308` exit 4."""
    result = invoke("map", "LD_RWD", "--gear-ratio", "1e308")
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith("Error: --gear-ratio '1e308' must be at most 12")


def test_boolean_chunk_size_refused(tmp_path):
    """Before: `chunk_size = true` was taken as 1."""
    small_fleet(tmp_path / "fleet.xlsx")
    config = _batch(tmp_path, 'inputs = ["fleet.xlsx"]\nchunk_size = true\n')
    result = invoke("run", "--config", config, "-q", "--no-cache")
    assert result.exit_code == 1
    assert first_line(result).startswith(f"Error: {config}: 'chunk_size' must be a positive whole number")


# --- silently wrong numbers -------------------------------------------------------------------

def _edit(path: Path, edit) -> Path:
    import openpyxl

    book = openpyxl.load_workbook(path)
    edit(book)
    book.save(path)
    return path


def _validate_first_line(path: Path) -> str:
    result = invoke("validate", path)
    assert result.exit_code == 1, result.output
    return first_line(result)


def test_percent_formatted_growth_is_the_percentage_shown(tmp_path, fake_simulation):
    """Before: 1.2% in a percent-formatted cell was read as 0.012 % growth (revenue 5.2 % low
    over ten years)."""
    def percent(book):
        cell = book["Scenarios"]["F2"]
        cell.value, cell.number_format = 0.012, "0.0%"

    typed = write_fleet(tmp_path / "typed.xlsx", [vehicle()], [scenario(vmt_growth_pct_per_year=1.2)])
    shown = _edit(write_fleet(tmp_path / "shown.xlsx", [vehicle()], [scenario()]), percent)
    from fleetrun.workbook import read_fleet

    assert read_fleet(shown).scenarios[0].vmt_growth_pct_per_year == pytest.approx(1.2)
    totals = []
    for path in (typed, shown):
        assert run_fake(path, "--out", tmp_path / path.stem, "-q", "--no-cache").exit_code == 0
        totals.append(fakes.read_csv(tmp_path / path.stem / "fiscal_summary.csv")["state_tax_usd"].sum())
    assert totals[1] == pytest.approx(totals[0], rel=1e-12)


def test_decimal_commas_in_gear_ratios_refused(tmp_path):
    """Before: 4,2;2,5;1,6;1,2 was read as eight gears."""
    path = write_fleet(tmp_path / "f.xlsx", [vehicle(transmission_gear_ratios="4,2;2,5;1,6;1,2")], [scenario()])
    line = _validate_first_line(path)
    assert line.startswith(f"Error: {path}: Vehicles!J2 transmission_gear_ratios: '4,2;2,5;1,6;1,2'")
    assert "decimal commas" in line


def test_zero_width_space_in_an_id_refused(tmp_path):
    """Before: CAR-1 and CAR-1 with a zero-width space were two vehicle types."""
    path = write_fleet(tmp_path / "f.xlsx", [vehicle("CAR-1"), vehicle("CAR-1\u200b")], [scenario()])
    line = _validate_first_line(path)
    assert line.startswith(f"Error: {path}: Vehicles!A3 vehicle_id: 'CAR-1\\u200b' holds an invisible character "
                           "(ZERO WIDTH SPACE, U+200B)")


def test_lookalike_letters_in_ids_headers_and_choices_named(tmp_path):
    """Before: a header with a Cyrillic letter was "not a fleetrun column" plus "missing
    vehicle_id"; an id in mixed scripts was a second vehicle."""
    path = write_fleet(tmp_path / "f.xlsx", [vehicle("CAR-1"), vehicle("\u0421AR-1"), vehicle("B", fuel="gas\u043eline")],
                       [scenario()])
    _edit(path, lambda book: setattr(book["Scenarios"]["A1"], "value", "scenario_\u0456d"))
    result = invoke("validate", path)
    assert result.exit_code == 1
    text = result.stderr
    assert f"Error: {path}: Scenarios!A1: header 'scenario_\u0456d' looks like scenario_id" in first_line(result)
    assert "CYRILLIC SMALL LETTER BYELORUSSIAN-UKRAINIAN I" in first_line(result)
    assert "Vehicles!A3 vehicle_id: '\u0421AR-1' mixes Latin letters with look-alike letters" in text
    assert "Vehicles!G4 fuel: 'gas\u043eline' looks like gasoline" in text


def test_two_sheets_named_alike_refused(tmp_path):
    """Before: sheets Vehicles and vehicles: one read, the other silently ignored."""
    def second(book):
        copy = book.copy_worksheet(book["Vehicles"])
        copy.title = "vehicles"

    source = _edit(write_fleet(tmp_path / "one.xlsx", [vehicle()], [scenario()]), second)
    path = tmp_path / "f.xlsx"     # openpyxl (as Excel) refuses names differing in case only
    with zipfile.ZipFile(source) as zin, zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            zout.writestr(item, data.replace(b'name="vehicles1"', b'name="vehicles"'))
    line = _validate_first_line(path)
    assert line.startswith(f"Error: {path}: Vehicles: the workbook has 2 sheets named like it ('Vehicles', 'vehicles')")


@pytest.mark.parametrize("cell,column,error", [("M2", "first_fiscal_year", "#REF!"),
                                               ("M2", "first_fiscal_year", "#N/A"),
                                               ("E2", "budget_years", "#DIV/0!"),
                                               ("C2", "ambient_temp_C", "#N/A")])
def test_excel_error_cells_named_as_errors(tmp_path, cell, column, error):
    """Before: #REF!/#N/A in optional columns read as blank (fiscal years 1, 2 instead of 2027,
    2028, no warning); #DIV/0! and #N/A in required columns reported as "empty"."""
    path = _edit(write_fleet(tmp_path / "f.xlsx", [vehicle()], [scenario(first_fiscal_year=2027)]),
                 lambda book: setattr(book["Scenarios"][cell], "value", error))
    line = _validate_first_line(path)
    assert line.startswith(f"Error: {path}: Scenarios!{cell} {column}: holds the Excel error '{error}'"), line


def test_import_epa_never_writes_what_its_validate_refuses(tmp_path):
    """Before: import-epa wrote a workbook its own validate refused (axle 0, negative weight,
    B -500), and a make beginning @SUM( reached measured.csv un-neutralised."""
    from test_epa_import import epa_row, write_list

    rows = [epa_row(), epa_row(**{"Test Vehicle ID": "AX0", "Axle Ratio": 0}),
            epa_row(**{"Test Vehicle ID": "NEGW", "Equivalent Test Weight (lbs.)": -3625}),
            epa_row(**{"Test Vehicle ID": "B500", "Target Coef B (lbf/mph)": -500}),
            epa_row(**{"Test Vehicle ID": "FORM", "Represented Test Veh Make": "@SUM(1+1)",
                       "Vehicle Manufacturer Name": "=HYPERLINK(\"http://x\")"})]
    listed = write_list(tmp_path / "list.csv", rows)
    fleet, measured = tmp_path / "fleet.xlsx", tmp_path / "measured.csv"
    result = invoke("import-epa", listed, "-o", fleet, "--measured-out", measured)
    assert result.exit_code == 0, result.output
    checked = invoke("validate", fleet)
    assert checked.exit_code == 0, checked.stderr
    from fleetrun.workbook import read_fleet

    assert {v.vehicle_id.split("_")[0] for v in read_fleet(fleet).vehicles} == {"18-AV3A", "FORM"}
    with open(measured, newline="", encoding="utf-8") as handle:
        cells = [cell for row in list(csv.reader(handle))[1:] for cell in row]
    assert "'@SUM(1+1)" in cells and any(cell.lower() == "'=hyperlink(\"http://x\")" for cell in cells), cells
    assert not any(cell[:1] in ("=", "+", "@") for cell in cells)


# --- diagnose inputs --------------------------------------------------------------------------

def test_diagnose_time_in_milliseconds_refused(tmp_path):
    """Before: a recording with time_s in milliseconds was accepted."""
    path = _rig_recording(tmp_path, GOOD_SIDECAR)
    lines = path.read_text().splitlines()
    body = [",".join([f"{float(line.split(',')[0]) * 1000:g}", *line.split(",")[1:]]) for line in lines[1:]]
    path.write_text("\n".join([lines[0], *body]) + "\n")
    result = invoke("diagnose", path, "--out", tmp_path / "d")
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith(f"Error: {path}: row 3, column time_s: the usual time step is 500 s")


def test_diagnose_torque_times_1e300_is_exit_1(tmp_path):
    """Before: input torque x 1e300 exit 4."""
    path = _rig_recording(tmp_path, GOOD_SIDECAR)
    lines = path.read_text().splitlines()
    body = [",".join([line.split(",")[0], f"{float(line.split(',')[1]) * 1e300:g}", *line.split(",")[2:]])
            for line in lines[1:]]
    path.write_text("\n".join([lines[0], *body]) + "\n")
    result = invoke("diagnose", path, "--out", tmp_path / "d")
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith(f"Error: {path}: row 2, column diff_input_torque_Nm: torque 1e+302 N m")


def _measured(path: Path, rows: list[str]) -> Path:
    path.write_text("vehicle_id,test,mpg,manufacturer\n" + "\n".join(rows) + "\n")
    return path


def test_measured_conflicting_duplicates_refused(tmp_path):
    """Before: 200 conflicting duplicate rows in a measured CSV: the last won, silently."""
    fleet = small_fleet(tmp_path / "fleet.xlsx")
    rows = [f"CAR-1,FTP,{30 + i % 7},acme" for i in range(200)]
    measured = _measured(tmp_path / "measured.csv", rows)
    result = invoke("diagnose-fleet", fleet, "--measured", measured, "--out", tmp_path / "d")
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith(f"Error: {measured}: row 3, column mpg: CAR-1 FTP again, with mpg 31")


def test_measured_mpg_off_by_units_refused(tmp_path):
    """L/100 km or a placeholder under mpg: outside any vehicle's fuel economy."""
    fleet = small_fleet(tmp_path / "fleet.xlsx")
    measured = _measured(tmp_path / "measured.csv", ["CAR-1,FTP,30,acme", "CAR-2,FTP,9999,zeta"])
    result = invoke("diagnose-fleet", fleet, "--measured", measured, "--out", tmp_path / "d")
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith(f"Error: {measured}: row 3, column mpg: 9,999 mpg is outside 3 to 200 mpg")


def test_one_manufacturer_fleet_refused_not_nan(tmp_path):
    """Before: a one-manufacturer fleet wrote NaN into diagnosis.json and "nan" into the HTML."""
    fleet = small_fleet(tmp_path / "fleet.xlsx")
    measured = _measured(tmp_path / "measured.csv", ["CAR-1,FTP,30,acme", "CAR-2,FTP,28,acme"])
    result = invoke("diagnose-fleet", fleet, "--measured", measured, "--out", tmp_path / "d")
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith(f"Error: {measured}: column manufacturer: every measured result is of one "
                                         "manufacturer (acme)")
    assert not (tmp_path / "d").exists()


# --- Dask -------------------------------------------------------------------------------------

def _dask_run(tmp_path, scheduler, monkeypatch):
    monkeypatch.setenv("FLEETRUN_DASK_TIMEOUT_S", "2")
    started = time.perf_counter()
    result = run_fake(small_fleet(tmp_path / "f.xlsx"), "--out", tmp_path / "out", "-q", "--no-cache",
                      "--engine", "dask", "--scheduler", scheduler)
    return result, time.perf_counter() - started


@pytest.mark.parametrize("address", ["garbage!!", "tcp://localhost:notaport", "tcp://:8786"])
def test_dask_garbage_scheduler_is_exit_1_at_once(tmp_path, fake_simulation, monkeypatch, address):
    """Before: --scheduler garbage: exit 4 with a traceback after 20 s."""
    pytest.importorskip("distributed")
    result, seconds = _dask_run(tmp_path, address, monkeypatch)
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith(f"Error: '{address}' is not a Dask scheduler address") and seconds < 10


def test_dask_silent_port_is_exit_1_within_the_timeout(tmp_path, fake_simulation, monkeypatch):
    """Before: a port where something else (not a Dask scheduler) listens: a hang of 600 s."""
    pytest.importorskip("distributed")
    import socket

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(5)
    try:
        address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
        result, seconds = _dask_run(tmp_path, address, monkeypatch)
    finally:
        server.close()
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith(f"Error: cannot reach the Dask scheduler at '{address}' within 2 s")
    assert seconds < 30, seconds


def test_dask_scheduler_without_workers_is_exit_1_within_the_timeout(tmp_path, fake_simulation, monkeypatch):
    """Before: a scheduler with no workers: a hang of 150 s."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster:
        result, seconds = _dask_run(tmp_path, cluster.scheduler_address, monkeypatch)
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith(f"Error: the Dask scheduler at '{cluster.scheduler_address}' has no workers")
    assert seconds < 30, seconds


def test_disk_full_writing_a_file_is_exit_1(tmp_path, monkeypatch):
    """Before: disk full while writing `map -o FILE`: exit 4 (a traceback)."""
    import pathlib

    def full(self, *args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(self))

    monkeypatch.setattr(pathlib.Path, "write_text", full)
    target = tmp_path / "map.csv"
    result = invoke("map", "LD_RWD", "--gear-ratio", "3.2", "-o", target)
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith(f"Error: {target}: cannot write it (No space left on device)")
    assert list(tmp_path.iterdir()) == []


def test_measured_km_per_litre_under_mpg_refused(tmp_path):
    """Before: a measured file in km/L under `mpg` was accepted (the fitted fuel scale absorbed
    the factor 2.35)."""
    fleet = small_fleet(tmp_path / "fleet.xlsx")
    rows = [f"{vid},{test},{mpg / 2.352:.2f},{maker}" for vid, maker, base in
            (("CAR-1", "acme", 30), ("CAR-2", "zeta", 27), ("PICKUP-1", "acme", 20))
            for test, mpg in (("FTP", base), ("HWFET", base * 1.4), ("US06", base * 0.9))]
    measured = _measured(tmp_path / "measured.csv", rows)
    result = invoke("diagnose-fleet", fleet, "--measured", measured, "--out", tmp_path / "d")
    assert result.exit_code == 1, result.output
    assert first_line(result).startswith(f"Error: {measured}: column mpg: the measured fuel economies are a median")
    assert "not miles per US gallon" in first_line(result)
