"""What the third hostile review ("nothing lost") found and left, each failing before its fix
(noted per test): import-epa replacing a workbook, line numbers of a registration extract, a
damaged manifest.json, earlier-runs/ growing without bound, the report's two ranges, a
signal between the two renames of the output folder's swap.

Every user mistake is exit 1 with one ``Error:`` line saying what is wrong and what to do, no
traceback (docs/interface.md).
"""
from __future__ import annotations

import json
import threading
from pathlib import Path

import pytest
from click.testing import CliRunner

import test_fleet_fakes as fakes
from fleetrun.cli import cli
from test_epa_import import epa_row, write_list
from test_fleet_fakes import small_fleet
from test_hostile_round3 import assert_import_keeps_the_workbook_it_replaces, signals_as_from_a_terminal  # noqa: F401 (a fixture)


def invoke(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def assert_user_error(result, *fragments) -> str:
    """Exit 1, the first stderr line an ``Error:`` holding every fragment, no traceback."""
    assert result.exit_code == 1, result.output
    line = (result.stderr.splitlines() or [""])[0]
    assert line.startswith("Error: "), result.stderr
    for fragment in fragments:
        assert fragment in line, line
    assert "Traceback" not in result.output
    return line


@pytest.fixture
def fake_simulation():
    """``fleetrun run`` below uses the stand-in simulation (test_fleet_fakes)."""
    return fakes.fake_simulate


# --- import-epa -o over an existing workbook -----------------------------------------------------

def test_import_epa_keeps_the_workbook_it_replaces(tmp_path):
    """Before: a second `import-epa list.csv -o fleet.xlsx` silently replaced fleet.xlsx (and
    the tax rates and VMT the analyst had typed into its Scenarios sheet). Now the earlier
    workbook is kept in earlier-imports/ beside it and the message says where; the command still
    writes the workbook and exits 0 (docs/interface.md); --force keeps nothing; a failed import
    leaves the workbook and keeps nothing."""
    listed = write_list(tmp_path / "list.csv", [epa_row()])
    assert_import_keeps_the_workbook_it_replaces("import-epa", listed, tmp_path / "fleet.xlsx")
    workbook = tmp_path / "fleet.xlsx"
    before = workbook.read_bytes()
    assert invoke("import-epa", listed, "-o", workbook, "--make", "NoSuchMake").exit_code == 1
    assert workbook.read_bytes() == before and len(list((tmp_path / "earlier-imports").iterdir())) == 1


# --- import-registrations: the file's line, not the data row -------------------------------------

@pytest.mark.parametrize("text, line, value", [
    ("vehicle_class,count\n\nautomobile,1\n\n\nbus,2\nlorry,3\n", 7, "'lorry'"),
    ("vehicle_class,count\nautomobile,1\n   \nautomobile,x\n", 4, "'x'"),
    ("\nvehicle_class,count\nautomobile,1\n\nautomobile,2\nautomobile,-1\n", 6, "'-1'"),
    ('vehicle_class,count,model\nautomobile,1,"two\nlines"\nbus,two,x\n', 4, "'two'"),
])
def test_import_registrations_error_names_the_files_line(tmp_path, text, line, value):
    """Before: after blank lines (pandas skips them) "line N" counted data rows: the first case
    said line 4 for the file's line 7."""
    extract = tmp_path / "dmv.csv"
    extract.write_text(text, encoding="utf-8")
    assert_user_error(invoke("import-registrations", extract, "-o", tmp_path / "f.xlsx"),
                      f"{extract}: line {line}: ", value)


def test_import_registrations_line_is_the_files_across_chunks(tmp_path):
    """The line is counted from the file's start whichever chunk holds the bad value."""
    from fleetrun.errors import InputError
    from fleetrun.registrations.extract import read_extract

    extract = tmp_path / "dmv.csv"
    extract.write_text("vehicle_class\n" + "automobile\n\n" * 5 + "lorry\n", encoding="utf-8")
    with pytest.raises(InputError, match="line 12: vehicle_class 'lorry'"):
        read_extract(extract, chunk_rows=2)


# --- a damaged manifest.json -----------------------------------------------------------------------

@pytest.mark.parametrize("content, damage", [
    (b"", "is damaged (empty)"),
    (b'{"schema": "fleetrun.run/1", "outputs": {"results.csv": "ab', "is damaged (not JSON: "),
    (b"[1, 2]", "is damaged (not a JSON object)"),
    (b'{"schema": "fleetrun.run/1", "created_utc": "x"}', "is damaged (has no list of the outputs)"),
    (b"\xff\xfe{}", "is damaged (not UTF-8 text)"),
])
def test_damaged_manifest_is_said_to_be_damaged(tmp_path, fake_simulation, content, damage):
    """Before: a truncated manifest.json (a full disk, a crash, a hand edit) made the folder's
    outputs read as someone else's files: "holds results.csv, manifest.json that fleetrun did
    not write ... Move them away"."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "manifest.json").write_bytes(content)
    (out / "results.csv").write_text("ours, once\n")
    result = fakes.invoke_run(small_fleet(tmp_path / "f.xlsx"), "--out", out, "-q", "--no-cache")
    line = assert_user_error(result, f"{out / 'manifest.json'}: {damage}", "results.csv beside it")
    assert "did not write" not in line
    assert "delete manifest.json" in result.stderr and "--out" in result.stderr
    assert (out / "results.csv").read_text() == "ours, once\n" and (out / "manifest.json").read_bytes() == content


def test_foreign_manifest_still_names_the_foreign_files(tmp_path, fake_simulation):
    """A well-formed manifest of another program is not 'damaged': its files are someone else's."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "manifest.json").write_text(json.dumps({"name": "a web app"}))
    (out / "results.csv").write_text("theirs\n")
    result = fakes.invoke_run(small_fleet(tmp_path / "f.xlsx"), "--out", out, "-q", "--no-cache")
    assert_user_error(result, "holds results.csv, manifest.json that fleetrun did not write")


# --- earlier-runs/ bounded -------------------------------------------------------------------------

def _run_dated(fleet: Path, out: Path, day: int, *options) -> None:
    """One run into ``out``, its manifest then dated 2026-01-<day> (runs of one second apart
    would otherwise share a creation time)."""
    result = fakes.invoke_run(fleet, "--out", out, "-q", "--no-cache", *options)
    assert result.exit_code == 0, result.output
    manifest = out / "manifest.json"
    data = json.loads(manifest.read_text(encoding="utf-8"))
    data["created_utc"] = f"2026-01-{day:02d}T02:00:00+00:00"
    manifest.write_text(json.dumps(data), encoding="utf-8")


def test_earlier_runs_keep_the_newest_n_and_nothing_else_is_removed(tmp_path, fake_simulation):
    """Before: a nightly run kept every earlier run in earlier-runs/ forever (one folder a night).
    With --keep-runs 2 the two newest stay; a user's folder and a user's file inside a removed
    run's folder stay."""
    fleet, out = small_fleet(tmp_path / "f.xlsx"), tmp_path / "out"
    for day in (1, 2, 3):
        _run_dated(fleet, out, day, "--keep-runs", "2")
    kept = sorted(p.name for p in (out / "earlier-runs").iterdir())
    assert [name[:10] for name in kept] == ["2026-01-01", "2026-01-02"], kept
    notes = out / "earlier-runs" / "my-notes"
    notes.mkdir()
    (notes / "a.txt").write_text("mine")
    (out / "earlier-runs" / kept[0] / "why.txt").write_text("mine too")
    _run_dated(fleet, out, 4, "--keep-runs", "2")
    now = sorted(p.name for p in (out / "earlier-runs").iterdir())
    assert [name[:10] for name in now] == ["2026-01-01", "2026-01-02", "2026-01-03", "my-notes"], now
    assert sorted(p.name for p in (out / "earlier-runs" / kept[0]).iterdir()) == ["why.txt"]
    assert (notes / "a.txt").read_text() == "mine"


def test_earlier_runs_default_bound_and_batch_setting(tmp_path, fake_simulation):
    """The default keeps KEEP_RUNS runs; the batch config's keep_runs sets it; a bad value is exit 1."""
    from fleetrun.reports.changes import KEEP_RUNS

    assert KEEP_RUNS == 30
    fleet = small_fleet(tmp_path / "fleet.xlsx")
    config = tmp_path / "batch.toml"
    config.write_text('inputs = ["fleet.xlsx"]\nkeep_runs = 1\n')
    out = tmp_path / "results" / "fleet"
    for day in (1, 2, 3):
        result = fakes.invoke_run("--config", config, "-q", "--no-cache")
        assert result.exit_code == 0, result.output
        data = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
        data["created_utc"] = f"2026-01-{day:02d}T02:00:00+00:00"
        (out / "manifest.json").write_text(json.dumps(data), encoding="utf-8")
    assert [p.name[:10] for p in (out / "earlier-runs").iterdir()] == ["2026-01-02"]
    config.write_text('inputs = ["fleet.xlsx"]\nkeep_runs = -1\n')
    assert_user_error(fakes.invoke_run("--config", config, "-q"), "'keep_runs' must be a whole number")
    assert fleet.is_file()


# --- report.xlsx / summary.html: which 90 % range is which -----------------------------------------

def test_summary_shows_one_range_per_total_and_says_what_the_row_ranges_are(tmp_path, fake_simulation):
    """Before: the Summary sheet's table gave fuel_gal_low_total / _high_total (the sum of each
    fuel's and year's 5th / 95th percentile: the example baseline 5.14 to 6.11 billion gal) and
    the headline below it the range of the total (5.24 to 6.01 billion), neither saying which
    it was. Now the Summary gives each total one range, the headline's, and both reports say
    in the same words (fleetrun.reports.text) what the rows' ranges are."""
    import html

    import openpyxl
    import pandas as pd

    from fleetrun.reports import text

    out = fakes.run_small_fleet_with_fake(tmp_path)
    sheet = openpyxl.load_workbook(out / "report.xlsx")["Summary"]
    cells = [c.value for row in sheet.iter_rows() for c in row if isinstance(c.value, str)]
    header = next(row for row in sheet.iter_rows(values_only=True) if row[0] == "scenario_id")
    assert "fuel_gal_total" in header and not {"fuel_gal_low_total", "fuel_gal_high_total"} & set(header)
    for words in (text.HEADLINE_HEADING, text.TOTAL_RANGE, text.ROW_RANGES):
        assert words in cells
    page = html.unescape((out / "summary.html").read_text(encoding="utf-8"))
    assert text.TOTAL_RANGE in page and text.ROW_RANGES in page
    # what the words claim, on this run: per fiscal year the all-fuels range lies inside the
    # fuels' summed ends, strictly somewhere (ranges do not add)
    memo = pd.read_csv(out / "revenue_memo.csv")
    fuels = memo[memo.fuel != "all fuels"].groupby(["scenario_id", "fiscal_year"])[["fuel_gal_low", "fuel_gal_high"]].sum()
    total = memo[memo.fuel == "all fuels"].set_index(["scenario_id", "fiscal_year"])[["fuel_gal_low", "fuel_gal_high"]]
    assert len(total) and (memo.fuel != "all fuels").sum() > len(total)
    assert (total.fuel_gal_low >= fuels.fuel_gal_low * (1 - 1e-12)).all()
    assert (total.fuel_gal_high <= fuels.fuel_gal_high * (1 + 1e-12)).all()
    assert (total.fuel_gal_low > fuels.fuel_gal_low * (1 + 1e-6)).any()


# --- a signal between the two renames of the output folder's swap ---------------------------------

def _signal_at_first_rename(monkeypatch, signum, send=None):
    """os.rename sends ``signum`` to this process (or calls ``send(signum)``) right after its
    first call (target -> old)."""
    import os

    from fleetrun import output_folder

    real, calls = os.rename, []

    def rename(source, destination):
        real(source, destination)
        calls.append(Path(destination).name)
        if len(calls) == 1:
            (send or (lambda number: os.kill(os.getpid(), number)))(signum)

    monkeypatch.setattr(output_folder.os, "rename", rename)
    return calls


@pytest.mark.skipif(not hasattr(__import__("signal"), "SIGHUP"), reason="POSIX signals")
@pytest.mark.parametrize("name", ["SIGTERM", "SIGINT", "SIGHUP"])
def test_signal_within_the_swap_waits_until_the_folder_is_in_place(tmp_path, monkeypatch, name):
    """Before: a signal arriving between `out -> .out-old-*` and `staging -> out` stopped the run
    there: no `out` at all until the next run put the old folder back. Now the signal is held
    until both renames are done (and the user's late files rescued), then delivered."""
    import signal

    from fleetrun.output_folder import swap_in

    signum = getattr(signal, name)
    target, staging = tmp_path / "out", tmp_path / ".out-staging-1-ab"
    target.mkdir()
    (target / "results.csv").write_text("old\n")
    (target / "notes.txt").write_text("mine\n")
    staging.mkdir()
    (staging / "results.csv").write_text("new\n")
    # a second thread, as pyarrow's workers in a run: the system may hand the process's signal
    # to it, and Python then runs the handler in the main thread at once (a signal mask of the
    # main thread alone let it run between the renames); here the signal goes to that thread
    release = threading.Event()
    worker = threading.Thread(target=release.wait)
    worker.start()
    calls = _signal_at_first_rename(monkeypatch, signum, lambda number: signal.pthread_kill(worker.ident, number))

    def stop(number, frame):
        raise KeyboardInterrupt(number)

    previous = signal.signal(signum, stop)
    try:
        with pytest.raises(KeyboardInterrupt):
            swap_in(staging, target, replaces=["results.csv"])
        after = signal.getsignal(signum)
    finally:
        signal.signal(signum, previous)
        release.set()
        worker.join()
    assert len(calls) == 2 and calls[1] == "out"          # both renames ran before the signal's handler
    assert (target / "results.csv").read_text() == "new\n" and (target / "notes.txt").read_text() == "mine\n"
    assert after is stop                                  # the caller's handler is back


@pytest.mark.skipif(not hasattr(__import__("signal"), "SIGHUP"), reason="POSIX signals")
@pytest.mark.usefixtures("signals_as_from_a_terminal")   # SIGTERM ignored by the caller stays ignored
def test_sigterm_within_the_swap_of_a_run_leaves_the_output_folder(tmp_path, monkeypatch, fake_simulation):
    """The same through `fleetrun run`: SIGTERM during the swap is exit 1 `stopped by SIGTERM`
    saying the folder holds this run's outputs (not "as it was"), and the folder is there,
    holding the new run (its manifest lists its outputs)."""
    import signal

    fleet, out = small_fleet(tmp_path / "f.xlsx"), tmp_path / "out"
    assert fakes.invoke_run(fleet, "--out", out, "-q", "--no-cache").exit_code == 0
    first = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    _signal_at_first_rename(monkeypatch, signal.SIGTERM)
    result = fakes.invoke_run(fleet, "--out", out, "-q", "--no-cache")
    line = assert_user_error(result, "stopped by SIGTERM", f"{out} holds this run's complete outputs")
    assert "is as it was" not in line
    assert (out / "manifest.json").is_file() and (out / "report.xlsx").is_file()
    now = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
    assert now["outputs"].keys() == first["outputs"].keys() and (out / "earlier-runs").is_dir()


@pytest.mark.skipif(not hasattr(__import__("signal"), "SIGHUP"), reason="POSIX signals")
def test_a_signal_another_thread_receives_is_held_as_well():
    """The system hands a process's signal to any thread that does not block it (a pyarrow
    worker in a run), and Python runs the handler in the main thread soon after: holding the
    signals must not rest on the main thread's signal mask alone."""
    import signal
    import time

    from fleetrun.output_folder import _signals_held

    seen = []
    release = threading.Event()
    worker = threading.Thread(target=release.wait)
    worker.start()
    previous = signal.signal(signal.SIGTERM, lambda number, frame: seen.append(number))
    try:
        with _signals_held():
            signal.pthread_kill(worker.ident, signal.SIGTERM)
            time.sleep(0.3)        # time enough for Python to run a handler it was given
            held = list(seen)
        after = list(seen)
    finally:
        signal.signal(signal.SIGTERM, previous)
        release.set()
        worker.join()
    assert held == [] and after == [signal.SIGTERM]


def _swap_folders(tmp_path):
    target, staging = tmp_path / "out", tmp_path / ".out-staging-1-ab"
    target.mkdir()
    (target / "results.csv").write_text("old\n")
    staging.mkdir()
    (staging / "results.csv").write_text("new\n")
    return target, staging


@pytest.mark.skipif(not hasattr(__import__("signal"), "SIGHUP"), reason="POSIX signals")
def test_a_held_signal_after_a_failed_swap_does_not_claim_the_new_outputs(tmp_path, monkeypatch):
    """Review: a signal held over the swap whose second rename failed (and was undone) said
    "<out> holds this run's complete outputs", while <out> held the earlier run's: only a swap
    that ended puts the outputs in place (output_folder._signals_held)."""
    import os
    import signal

    from fleetrun import output_folder

    target, staging = _swap_folders(tmp_path)
    real, calls = os.rename, []

    def rename(source, destination):
        calls.append(Path(destination).name)
        if len(calls) == 2:       # staging -> out fails (a full disk, a virus scanner)
            raise OSError(28, "No space left on device")
        real(source, destination)
        if len(calls) == 1:
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(output_folder.os, "rename", rename)
    previous = signal.signal(signal.SIGTERM, lambda number, frame: (_ for _ in ()).throw(KeyboardInterrupt()))
    try:
        with pytest.raises(KeyboardInterrupt) as stopped:
            output_folder.swap_in(staging, target, replaces=["results.csv"])
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert getattr(stopped.value, "outputs_in_place", None) is None
    assert (target / "results.csv").read_text() == "old\n"      # the rename undone: as it was


@pytest.mark.skipif(not hasattr(__import__("signal"), "SIGHUP"), reason="POSIX signals")
def test_a_held_signal_while_outputs_move_into_the_working_folder_says_they_are_in(tmp_path, monkeypatch):
    """Review: `--out .` moves each output in by one rename (output_folder._replace_in_place),
    with the signals held as for a swap; a signal then said "is as it was", though the new
    outputs were in place."""
    import os
    import signal

    from fleetrun import output_folder

    target, staging = _swap_folders(tmp_path)
    monkeypatch.chdir(target)
    real = os.replace

    def replace(source, destination):
        real(source, destination)
        os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(output_folder.os, "replace", replace)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt) as stopped:
            output_folder.swap_in(staging, target, replaces=["results.csv"])
    finally:
        signal.signal(signal.SIGINT, previous)
    assert stopped.value.outputs_in_place == str(target.resolve())
    assert (target / "results.csv").read_text() == "new\n"


def test_a_failed_import_write_keeps_no_copy(tmp_path):
    """The earlier workbook is linked aside before the import writes; if the write fails the
    workbook is as it was (atomic write) and the link is removed, so earlier-imports/ holds only
    workbooks that were replaced."""
    from fleetrun.fileio import replacing_import

    workbook = tmp_path / "fleet.xlsx"
    workbook.write_bytes(b"the analyst's workbook")
    with pytest.raises(RuntimeError), replacing_import(workbook, force=False) as kept:
        assert kept.read_bytes() == b"the analyst's workbook"
        raise RuntimeError("disk full")
    assert not kept.exists() and workbook.read_bytes() == b"the analyst's workbook"


def test_a_batch_glob_skips_the_workbooks_an_import_kept(tmp_path):
    """inputs = ["regions/*/*.xlsx"] with an import re-run in regions/north: the kept
    regions/north/earlier-imports/fleet-<time>.xlsx is no fleet of tonight's batch."""
    from fleetrun.run.batch import read_config

    for region in ("north", "south"):
        (tmp_path / "regions" / region).mkdir(parents=True)
        small_fleet(tmp_path / "regions" / region / "fleet.xlsx")
    (tmp_path / "regions" / "earlier-imports").mkdir()
    small_fleet(tmp_path / "regions" / "earlier-imports" / "fleet-20261125T160000Z.xlsx")
    config = tmp_path / "batch.toml"
    config.write_text('inputs = ["regions/*/*.xlsx"]\nout = "out"\n', encoding="utf-8")
    assert [p.parent.name for p in read_config(config).inputs] == ["north", "south"]
