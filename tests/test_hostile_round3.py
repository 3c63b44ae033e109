"""The third hostile review ("nothing lost"): a revenue analyst's spreadsheet, a cron job and a
manager's report, each case failing before its fix (noted per test) and kept as a regression.

Every user mistake is exit 1 with one ``Error:`` line naming the file, sheet, cell, column and
value and saying what to do, no traceback (docs/interface.md); an interrupted run says so, in
the log too, and leaves its output folder as it was (docs/batch.md).
"""
from __future__ import annotations

import json
import os
import signal
import time
from pathlib import Path

import openpyxl
import pytest
from click.testing import CliRunner

import test_fleet_fakes as fakes
from fleetrun.cli import cli
from fleetrun.workbook import xlsx_safety
from fleetrun.workbook.reader import read_fleet
from test_fleet_fakes import scenario, small_fleet, write_fleet

SCENARIO_HEADER = ["scenario_id", "ambient_temp_C", "cycle_mix", "budget_years", "vmt_growth_pct_per_year",
                   "state_tax_gasoline_usd_per_gal", "state_tax_diesel_usd_per_gal",
                   "federal_tax_gasoline_usd_per_gal", "federal_tax_diesel_usd_per_gal", "first_fiscal_year",
                   "base_year_vmt_million", "fiscal_year_start_month"]
SCENARIO_ROW = ["s", 20, "default", 2, 1.0, 0.2, 0.2, 0.184, 0.244, 2027, 60000, 9]


def invoke(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def first_line(result) -> str:
    return (result.stderr.splitlines() or [""])[0]


def registrations(path: Path, rows, header=("vehicle_class", "count"), scenario_changes=None) -> Path:
    """A registrations-only workbook (as `fleetrun template` leads an analyst to make one):
    ``rows`` under ``header``, one scenario (``scenario_changes``: column -> value)."""
    wb = openpyxl.Workbook()
    ws = wb.active
    ws.title = "Registrations"
    ws.append(list(header))
    for row in rows:
        ws.append(list(row))
    sc = wb.create_sheet("Scenarios")
    values = dict(zip(SCENARIO_HEADER, SCENARIO_ROW), **(scenario_changes or {}))
    sc.append(list(values))
    sc.append(list(values.values()))
    wb.save(path)
    return path


MV1 = [("automobile", 2524145), ("truck", 2721534), ("bus", 5397), ("motorcycle", 115768)]


def assert_user_error(result, *fragments):
    """Exit 1, the first stderr line an ``Error:`` holding every fragment, no traceback."""
    assert result.exit_code == 1, result.output
    line = first_line(result)
    assert line.startswith("Error: "), result.stderr
    for fragment in fragments:
        assert fragment in line, line
    assert "Traceback" not in result.output


# --- the workbook: what an analyst types ------------------------------------------------------

def test_thousands_separators_typed_as_text_are_the_number_shown(tmp_path):
    """Before: '2,524,145' (MV-1 pasted from FHWA's table) was "is not a number", exit 1."""
    typed = read_fleet(registrations(tmp_path / "t.xlsx", [("automobile", "2,524,145"), ("bus", "5,397")]))
    plain = read_fleet(registrations(tmp_path / "p.xlsx", [("automobile", 2524145), ("bus", 5397)]))
    assert [r["count"] for r in typed.registrations] == [r["count"] for r in plain.registrations] == [2524145, 5397]


def test_a_comma_that_could_be_a_decimal_comma_is_a_warning_naming_the_cell(tmp_path):
    """'150,250' is 150250 with a US thousands separator, 150.25 with a European decimal comma,
    and both lie in base_year_vmt_million's usual range (schema.py: 100 to 4 million): read as
    shown in the US, but said, naming the cell. An unambiguous grouping (2,524,145) or a count
    (never 5.397 vehicles) is no warning."""
    fleet = read_fleet(registrations(tmp_path / "t.xlsx", [("automobile", "2,524,145"), ("bus", "5,397")],
                                     scenario_changes={"base_year_vmt_million": "150,250"}))
    assert fleet.scenarios[0].base_year_vmt_million == 150250
    assert [w for w in fleet.warnings if "comma" in w] == [
        "Scenarios!K2 base_year_vmt_million: '150,250' is read as 150250, the comma a thousands separator; "
        "if it is a decimal comma, type 150.25"]
    result = invoke("validate", tmp_path / "t.xlsx")
    assert result.exit_code == 0 and "Scenarios!K2" in result.output, result.output


def test_a_registration_count_with_three_decimals_is_a_warning(tmp_path):
    """Review: '2.524' typed as text (a locale whose thousands separator is a point: 2524 vehicles)
    was read as 2.524 vehicles, silently; a Vehicles row's fractional count was already warned about."""
    fleet = read_fleet(registrations(tmp_path / "t.xlsx", [("automobile", "2.524"), ("bus", 12)]))
    assert fleet.registrations[0]["count"] == 2.524
    assert fleet.warnings == ["Registrations!B2 count: 2.524 vehicles is not a whole number; totals use it as given "
                              "(if the point is a thousands separator, type 2524)"]


@pytest.mark.parametrize("column, typed, where, hint", [
    ("fiscal_year_start_month", "Sept", "Scenarios!L2 fiscal_year_start_month: 'Sept'", "(September = 9)"),
    ("state_tax_gasoline_usd_per_gal", "$0.20", "Scenarios!F2 state_tax_gasoline_usd_per_gal: '$0.20'",
     "without the currency sign"),
    ("base_year_vmt_million", "60 000", "Scenarios!K2 base_year_vmt_million: '60 000'",
     "without thousands separators (60000)"),
    ("state_tax_gasoline_usd_per_gal", "0,20", "Scenarios!F2 state_tax_gasoline_usd_per_gal: '0,20'",
     "decimal point as a point (0.20)"),
    ("first_fiscal_year", "FY2027", "Scenarios!J2 first_fiscal_year: 'FY2027'", "type the number alone"),
    ("state_tax_gasoline_usd_per_gal", "-$0.20", "Scenarios!F2 state_tax_gasoline_usd_per_gal: '-$0.20'",
     "without the currency sign"),
    # review: a one-character text ('-' for none in a pasted table) was told to drop a currency sign
    ("vmt_growth_pct_per_year", "-", "Scenarios!E2 vmt_growth_pct_per_year: '-'", "; type a number"),
])
def test_a_cell_that_is_not_a_number_says_what_to_type(tmp_path, column, typed, where, hint):
    """Before: "'Sept' is not a number" and nothing on what to type instead."""
    path = registrations(tmp_path / "f.xlsx", MV1, scenario_changes={column: typed})
    for command in ("validate", "run"):
        assert_user_error(invoke(command, path, *(["--out", tmp_path / "out"] if command == "run" else [])),
                          str(path), where, "is not a number", hint)


def test_percent_typed_as_text_in_a_percent_column_is_the_percentage_shown(tmp_path):
    """Before: '1.5%' typed into vmt_growth_pct_per_year (a Text-formatted cell) was refused,
    while the same value formatted as Percentage was read as 1.5 (docs/workbook.md)."""
    fleet = read_fleet(registrations(tmp_path / "f.xlsx", MV1, scenario_changes={"vmt_growth_pct_per_year": "1.5%"}))
    assert fleet.scenarios[0].vmt_growth_pct_per_year == 1.5


@pytest.mark.parametrize("label", ["Total", "TOTAL", "Grand total", "All vehicles", "Total Vehicles"])
def test_a_total_row_is_named_as_such(tmp_path, label):
    """Before: "'Total' is not one of automobile, ..." without saying to delete the row (and,
    in review, 'All vehicles': the class cell's spaces became '_' before the total words, which
    held spaces, were looked up)."""
    path = registrations(tmp_path / "f.xlsx", MV1 + [(label, 5366844)])
    assert_user_error(invoke("validate", path), f"Registrations!A6 vehicle_class: '{label}' looks like a total row",
                      "delete the row")


def test_a_registration_row_pasted_twice_is_a_warning_naming_both_rows(tmp_path):
    """Before: the copy was counted silently (1.3 billion more gallons for an MV-1 pasted twice)."""
    result = invoke("validate", registrations(tmp_path / "f.xlsx", MV1 + MV1[:1]))
    assert result.exit_code == 0, result.output
    assert "Registrations!row 6: repeats row 2 exactly; both are counted" in result.stderr
    # Review: rows that differ in a column fleetrun does not read (two counties) are no copy
    counties = [("automobile", 500, "Ada"), ("automobile", 500, "Boise")]
    result = invoke("validate", registrations(tmp_path / "c.xlsx", counties, header=("vehicle_class", "count", "county")))
    assert result.exit_code == 0 and "repeats row" not in result.output, result.output


def test_a_header_typed_with_spaces_is_read_and_a_misspelt_one_is_named(tmp_path):
    """Before: 'Vehicle Class' was "missing required column(s) vehicle_class" (and ignored)."""
    fleet = read_fleet(registrations(tmp_path / "f.xlsx", MV1, header=("Vehicle Class", "Count")))
    assert fleet.registrations[0]["vehicle_class"] == "automobile"
    path = registrations(tmp_path / "g.xlsx", MV1, header=("vehicle_clas", "count"))
    assert_user_error(invoke("validate", path), "Registrations!row 1: missing required column(s) vehicle_class",
                      "(or rename 'vehicle_clas' for vehicle_class)")


# --- the input file ---------------------------------------------------------------------------

def test_an_unreadable_workbook_is_said_to_be_unreadable_not_corrupt(tmp_path, monkeypatch):
    """Before: no read permission (or a file another program locks) was reported as "not an
    .xlsx workbook (not a zip file; corrupt ...)": zipfile.is_zipfile swallows the error.
    (Tests run as root here, where chmod 000 still reads: the refusal is stood in.)"""
    path = small_fleet(tmp_path / "f.xlsx")

    def refused(name, *args, **kwargs):
        raise PermissionError(13, "Permission denied", str(name))

    monkeypatch.setattr(xlsx_safety, "open", refused, raising=False)
    assert_user_error(invoke("validate", path), f"{path}: cannot be read (Permission denied)", "permissions")


def test_an_empty_workbook_file_says_it_is_empty(tmp_path):
    """Before: a 0-byte file (a copy still in progress) was "not a zip file; corrupt, ..."."""
    path = tmp_path / "f.xlsx"
    path.write_bytes(b"")
    assert_user_error(invoke("run", path, "--out", tmp_path / "out"), f"{path}: is empty (0 bytes)")


def test_excel_lock_file_named_and_skipped_by_a_batch_glob(tmp_path):
    """Before: a nightly batch over fleets/*.xlsx exited 3 while an analyst had a workbook
    open in Excel: its lock file ~$fleet.xlsx matched the glob and failed as a corrupt workbook."""
    fleets = tmp_path / "fleets"
    fleets.mkdir()
    small_fleet(fleets / "fleet.xlsx")
    lock = fleets / "~$fleet.xlsx"
    lock.write_bytes(b"\x0bJ. Analyst" + b"\x00" * 150)
    assert_user_error(invoke("validate", lock), "is the lock file Excel keeps", "(fleet.xlsx)")
    config = tmp_path / "batch.toml"
    config.write_text('inputs = ["fleets/*.xlsx"]\nout = "results"\n', encoding="utf-8")
    result = fakes.invoke_run("--config", config, "--no-cache", "-q")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (tmp_path / "results").iterdir()) == ["fleet", "fleetrun-run.log"]


# --- the output folder ------------------------------------------------------------------------

def test_a_failed_run_says_the_folder_still_holds_the_earlier_run(tmp_path):
    """Before: a nightly run that failed on a bad workbook left yesterday's outputs in place
    with nothing saying they were not today's."""
    out = tmp_path / "out"
    assert fakes.invoke_run(small_fleet(tmp_path / "f.xlsx"), "--out", out, "--no-cache", "-q").exit_code == 0
    created = json.loads((out / "manifest.json").read_text(encoding="utf-8"))["created_utc"]
    bad = write_fleet(tmp_path / "bad.xlsx", [fakes.vehicle(count=-1)], [scenario()])
    result = fakes.invoke_run(bad, "--out", out, "--no-cache", "-q")
    assert_user_error(result, "Vehicles!E2 count: -1")
    assert f"{out} still holds the outputs of the earlier run of {created}, not of this run" in result.stderr


def test_an_output_path_under_a_file_names_the_file(tmp_path):
    """Before: "cannot write here (File exists)", not which file is in the way."""
    (tmp_path / "results").write_text("notes", encoding="utf-8")
    result = fakes.invoke_run(small_fleet(tmp_path / "f.xlsx"), "--out", tmp_path / "results" / "may", "--no-cache")
    assert_user_error(result, f"({tmp_path / 'results'} is a file, not a folder)")
    assert (tmp_path / "results").read_text(encoding="utf-8") == "notes"


# --- interrupted runs -------------------------------------------------------------------------

def _stop_during_simulation(monkeypatch, stop):
    from fleetrun.run import batch

    def stopped(*args, **kwargs):
        stop()
        time.sleep(5)   # the signal's handler raises before this ends
        raise AssertionError("not stopped")

    monkeypatch.setattr(batch, "run_fleet", stopped)


@pytest.fixture
def signals_as_from_a_terminal():
    """SIGTERM and SIGHUP at their default, as a command started from a terminal has them: under
    `nohup` (a CI job may run so) SIGHUP is ignored, and the command rightly leaves an ignored
    signal ignored (test_nohup_still_outlives_the_terminal), so this test would not see it."""
    ignored = [n for n in (signal.SIGTERM, signal.SIGHUP) if signal.getsignal(n) is signal.SIG_IGN]
    for number in ignored:
        signal.signal(number, signal.SIG_DFL)
    yield
    for number in ignored:
        signal.signal(number, signal.SIG_IGN)


@pytest.mark.usefixtures("signals_as_from_a_terminal")
@pytest.mark.parametrize("how, said", [
    (lambda: os.kill(os.getpid(), signal.SIGTERM), "stopped by SIGTERM"),
    (lambda: os.kill(os.getpid(), signal.SIGHUP), "stopped by SIGHUP"),
    (lambda: (_ for _ in ()).throw(KeyboardInterrupt), "interrupted (Ctrl-C)"),
])
def test_an_interrupted_run_is_logged_and_leaves_the_earlier_run(tmp_path, monkeypatch, how, said):
    """Before: SIGTERM (a scheduler's time limit, `kill`) and SIGHUP (the ssh session closed)
    ended the process with no message, exit -15 / -1, and no line in the log; Ctrl-C's message did not name the log, and the log
    ended mid-run without a word."""
    out, log = tmp_path / "out", tmp_path / "run.log"
    fleet = small_fleet(tmp_path / "f.xlsx")
    assert fakes.invoke_run(fleet, "--out", out, "--no-cache", "-q").exit_code == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    handlers = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGHUP)
    _stop_during_simulation(monkeypatch, how)
    result = fakes.invoke_run(fleet, "--out", out, "--no-cache", "-q", "--log", log)
    assert_user_error(result, said, f"(logged in {log})")
    assert f"{said}; nothing more was written and {out} is as it was" in log.read_text(encoding="utf-8")
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.xlsx", "out", "run.log"]   # no staging, no lock
    assert (signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGHUP)) == handlers   # restored


# --- import-registrations: a DMV extract ------------------------------------------------------

def assert_import_keeps_the_workbook_it_replaces(command: str, source: Path, workbook: Path) -> None:
    """A second ``command source -o workbook`` keeps the earlier workbook in earlier-imports/
    and names it (exit 0); --force keeps nothing more."""
    assert invoke(command, source, "-o", workbook).exit_code == 0
    edited = workbook.read_bytes()
    again = invoke(command, source, "-o", workbook)
    assert again.exit_code == 0, again.output
    kept = list((workbook.parent / "earlier-imports").glob(f"{workbook.stem}-*.xlsx"))
    assert len(kept) == 1 and kept[0].read_bytes() == edited and str(kept[0]) in again.output
    assert invoke(command, source, "-o", workbook, "--force").exit_code == 0
    assert len(list((workbook.parent / "earlier-imports").iterdir())) == 1      # --force keeps nothing more


def test_import_registrations_keeps_the_workbook_it_replaces(tmp_path):
    """Before: next month's import over last month's fleet.xlsx silently replaced it, and with
    it the tax rates and VMT the analyst had typed into its Scenarios sheet. Now the earlier
    workbook is kept in earlier-imports/ and the message says where (exit 0: the command still
    does what it is asked); --force replaces without keeping."""
    extract = tmp_path / "dmv.csv"
    extract.write_text("vehicle_class,count\nautomobile,100\n", encoding="utf-8")
    assert_import_keeps_the_workbook_it_replaces("import-registrations", extract, tmp_path / "fleet.xlsx")


@pytest.mark.parametrize("content, said", [
    (b"", "is empty (0 bytes)"),
    (b"vehicle_class,count,make\nautomobile,1,Citro\xebn\n", "is not UTF-8 text (byte 0xeb"),
    (b"vehicle_class,count\n", "has no data lines below the header"),
])
def test_import_registrations_unusable_extract_is_a_user_error(tmp_path, content, said):
    """Before: an empty file and a Windows-1252 extract (Citroën) were internal errors (exit 4);
    a header without lines wrote a workbook of no registrations (exit 0)."""
    extract = tmp_path / "dmv.csv"
    extract.write_bytes(content)
    assert_user_error(invoke("import-registrations", extract, "-o", tmp_path / "f.xlsx"), f"{extract}: {said}")
    assert not (tmp_path / "f.xlsx").exists()


def test_import_registrations_reads_what_excel_exports(tmp_path):
    """Before: a semicolon-separated export (Excel where the decimal mark is a comma), headers
    such as 'Vehicle Class' and counts with thousands separators were refused."""
    extract = tmp_path / "dmv.csv"
    extract.write_text('Vehicle Class;Count\nautomobile;"2,524,145"\ntruck;2721534\n', encoding="utf-8-sig")
    result = invoke("import-registrations", extract, "-o", tmp_path / "f.xlsx")
    assert result.exit_code == 0, result.output
    fleet = read_fleet(tmp_path / "f.xlsx")
    assert {r["vehicle_class"]: r["count"] for r in fleet.registrations} == {"automobile": 2524145, "truck": 2721534}
    total = tmp_path / "total.csv"
    total.write_text("vehicle_class,count\nautomobile,5\nTotal,5\n", encoding="utf-8")
    assert_user_error(invoke("import-registrations", total, "-o", tmp_path / "g.xlsx"),
                      "line 3: vehicle_class 'total' looks like a total row")


@pytest.mark.parametrize("count, read", [("2.524", "2524"), ("2,524", "2524")])
def test_a_semicolon_export_count_a_thousand_times_apart_is_refused(tmp_path, count, read):
    """In a semicolon-separated export (a locale whose decimal mark is a comma and thousands
    separator a point) '2.524' is 2524 vehicles; it was read as 2.524, silently (and '2,524'
    as 2524, though there the comma is the decimal mark): refused, naming the file's line."""
    extract = tmp_path / "dmv.csv"
    extract.write_text(f"vehicle_class;count\nbus;12\nautomobile;{count}\n", encoding="utf-8")
    assert_user_error(invoke("import-registrations", extract, "-o", tmp_path / "f.xlsx"), str(extract),
                      f"line 3: count '{count}' could be {read} (a thousands separator) or 2.524 (a decimal mark)",
                      "without thousands separators")


@pytest.mark.parametrize("out", [".", ".."])
def test_out_naming_the_working_folder_keeps_the_shell_in_a_live_folder(tmp_path, monkeypatch, out):
    """Before: `fleetrun run fleet.xlsx --out .` renamed the working folder aside and removed
    it: the analyst's shell was left in a removed folder, where `ls` showed nothing (the
    outputs and their own notes looked lost) and new files could not be made."""
    folder = tmp_path / "fleets" / "may"
    folder.mkdir(parents=True)
    small_fleet(folder / "fleet.xlsx")
    (folder / "notes.txt").write_text("mine", encoding="utf-8")
    monkeypatch.chdir(folder)
    for _ in range(2):   # the second run replaces the first's outputs, keeping it in earlier-runs/
        result = fakes.invoke_run("fleet.xlsx", "--out", out, "-q", "--no-cache")
        assert result.exit_code == 0, result.output
        assert os.path.samefile(os.getcwd(), folder)   # still the live folder
    written = set(os.listdir(out))
    assert {"report.xlsx", "manifest.json", "results.csv", "earlier-runs"} <= written
    assert (folder / "notes.txt").read_text(encoding="utf-8") == "mine"
    assert len(os.listdir(Path(out) / "earlier-runs")) == 1
    assert [p.name for p in tmp_path.rglob(".*")] == []   # no staging, old or lock left


def test_base_vmt_below_the_vehicles_rows_own_miles_is_refused_not_negative(tmp_path):
    """Before: Vehicles rows driving 28 million miles beside registrations with
    base_year_vmt_million = 1 left -27 million miles to the registrations: negative gallons and
    negative tax in every output, exit 0."""
    path = small_fleet(tmp_path / "f.xlsx")
    wb = openpyxl.load_workbook(path)
    wb["Registrations"].append(["automobile", 1000])
    sc = wb["Scenarios"]
    column = [c.value for c in sc[1]].index("base_year_vmt_million") + 1
    for row in range(2, sc.max_row + 1):
        sc.cell(row=row, column=column, value=1)
    wb.save(path)
    letter = openpyxl.utils.get_column_letter(column)
    for args in (("validate", path), ("run", path, "--out", tmp_path / "out", "--no-cache")):
        result = fakes.invoke_run(*args[1:]) if args[0] == "run" else invoke(*args)
        assert_user_error(result, f"Scenarios!{letter}2 base_year_vmt_million: 1 million is not more than the "
                                  "Vehicles rows' own first-year miles")
    assert not (tmp_path / "out").exists()


def test_simulate_on_a_registrations_only_workbook_says_why_there_is_no_vehicle(tmp_path):
    """Before: "unknown vehicle_id 'automobile'; valid: " and an empty list."""
    path = registrations(tmp_path / "f.xlsx", MV1)
    assert_user_error(invoke("simulate", path, "--vehicle", "automobile", "--cycle", "UDDS"),
                      f"{path}: has no Vehicles rows, so no vehicle_id 'automobile'", "--vehicle-file")


def test_a_log_path_under_a_file_names_the_file(tmp_path):
    """Before: "cannot write the log (File exists)"."""
    (tmp_path / "logs").write_text("notes", encoding="utf-8")
    result = fakes.invoke_run(small_fleet(tmp_path / "f.xlsx"), "--out", tmp_path / "out", "--log",
                              tmp_path / "logs" / "run.log", "--no-cache")
    assert_user_error(result, f"cannot write the log ({tmp_path / 'logs'} is a file, not a folder)")


def test_base_vmt_typed_in_billions_is_a_warning(tmp_path):
    """Before: base_year_vmt_million = 60 (a state's 60 billion miles typed in billions) was read
    silently as 60 million miles: every gallon 1,000 times too small."""
    result = invoke("validate", registrations(tmp_path / "f.xlsx", MV1, scenario_changes={"base_year_vmt_million": 60}))
    assert result.exit_code == 0, result.output
    assert "Scenarios!K2 base_year_vmt_million: 60 is unusual (expected 100 to 4e+06); check the units" in result.stderr


@pytest.mark.parametrize("rows, said", [
    ([("automobile", 0), ("truck", 0)], "count: every count is 0"),
    ([("automobile", 1000, None, "electric")], "count: every registration counted is electric"),
])
def test_a_fleet_with_nothing_to_forecast_is_refused(tmp_path, rows, said):
    """Before: every count 0 ran to a report of $0 revenue (exit 0); registrations that were all
    electric (which no library vehicle represents) crashed writing summary.html (exit 4)."""
    path = registrations(tmp_path / "f.xlsx", rows, header=("vehicle_class", "count", "model_year", "fuel"))
    for result in (invoke("validate", path), fakes.invoke_run(path, "--out", tmp_path / "out", "--no-cache")):
        assert_user_error(result, f"{path}: Registrations: {said}", "nothing to forecast")
    assert not (tmp_path / "out").exists()


def test_a_registered_model_year_after_the_base_year_is_a_warning(tmp_path):
    """Before: model_year 2031 (a typo for 2013) in counts of 2027 ran silently as brand-new
    vehicles with the fuel economy of 2031."""
    from fleetrun.registrations.expand import expand

    fleet = read_fleet(registrations(tmp_path / "f.xlsx", [("automobile", 1000, 2031), ("automobile", 10, 2028)],
                                     header=("vehicle_class", "count", "model_year")))
    warnings = expand(fleet, fleet.scenarios).warnings
    assert any("1 row(s) give a model year after 2028, though the counts describe 2027 (Registrations!row 2)" in w
               for w in warnings), warnings


def test_a_lock_wait_that_is_not_a_number_is_the_jobs_error(tmp_path, monkeypatch):
    """Before: FLEETRUN_LOCK_WAIT_S=10m (a cron job's typo) was an internal error, exit 4."""
    monkeypatch.setenv("FLEETRUN_LOCK_WAIT_S", "10m")
    result = fakes.invoke_run(small_fleet(tmp_path / "f.xlsx"), "--out", tmp_path / "out", "--no-cache")
    assert_user_error(result, "$FLEETRUN_LOCK_WAIT_S '10m' is not a number of seconds")


def test_class_names_written_with_spaces_are_the_class(tmp_path):
    """Before: 'Light Truck' and 'single unit truck' (as FHWA's tables print them) were "not one
    of ... light_truck, single_unit_truck", in the sheet and in an extract alike."""
    fleet = read_fleet(registrations(tmp_path / "f.xlsx", [("Light Truck", 5), ("single unit truck", 3)]))
    assert [r["vehicle_class"] for r in fleet.registrations] == ["light_truck", "single_unit_truck"]
    extract = tmp_path / "dmv.csv"
    extract.write_text("vehicle_class,count\nLight Truck,5\nsingle-unit truck,3\n", encoding="utf-8")
    assert invoke("import-registrations", extract, "-o", tmp_path / "g.xlsx").exit_code == 0
    assert {r["vehicle_class"] for r in read_fleet(tmp_path / "g.xlsx").registrations} == {"light_truck",
                                                                                          "single_unit_truck"}


def test_a_batch_glob_skips_the_reports_of_earlier_runs(tmp_path):
    """Before: with inputs = ["regions/*/*.xlsx"] and out = "regions", the second night read
    the first night's regions/north-fleet/report.xlsx as a fleet and exited 3."""
    for region in ("north", "south"):
        (tmp_path / "regions" / region).mkdir(parents=True)
        small_fleet(tmp_path / "regions" / region / "fleet.xlsx")
    config = tmp_path / "batch.toml"
    config.write_text('inputs = ["regions/*/*.xlsx"]\nout = "regions"\n', encoding="utf-8")
    for night in range(2):
        result = fakes.invoke_run("--config", config, "--no-cache", "-q")
        assert result.exit_code == 0, result.output
    assert (tmp_path / "regions" / "north-fleet" / "earlier-runs").is_dir()


def test_true_typed_in_a_yes_no_column_is_yes(tmp_path):
    """Before: TRUE in calibrate_to_observed (Excel makes it a boolean cell) was "True is not text"."""
    fleet = read_fleet(registrations(tmp_path / "f.xlsx", MV1, scenario_changes={
        "calibrate_to_observed": True, "observed_base_gallons_gasoline": 3e9}))
    assert fleet.scenarios[0].calibrate_to_observed is True


def test_a_total_row_under_the_vehicles_table_is_named_as_such(tmp_path):
    """Before: "14 required cells are empty: ..." for a row `Total | 2465000` under the table."""
    path = small_fleet(tmp_path / "f.xlsx")
    wb = openpyxl.load_workbook(path)
    wb["Vehicles"].append(["Total", None, None, None, 2600])
    wb.save(path)
    assert_user_error(invoke("validate", path), "Vehicles!row 6: 'Total' looks like a total row; delete the row")


def test_kept_earlier_runs_are_linked_not_copied_again_every_night(tmp_path):
    """Before: every run copied every earlier run it kept (earlier-runs/), byte for byte, so a
    nightly job's write time and disk grew with each night until the disk was full and the
    outputs stopped changing. Now each is a hard link of the file it keeps (tmp_path's file
    system has them)."""
    out, fleet = tmp_path / "out", small_fleet(tmp_path / "f.xlsx")
    inodes = []
    for night in range(3):
        assert fakes.invoke_run(fleet, "--out", out, "--no-cache", "-q").exit_code == 0
        inodes.append(os.stat(out / "results.csv").st_ino)
    kept = {os.stat(p).st_ino for p in (out / "earlier-runs").glob("*/results.csv")}
    assert kept == set(inodes[:2])   # the same files, kept where they were


def test_nohup_still_outlives_the_terminal(tmp_path, monkeypatch):
    """A SIGHUP the caller ignores (`nohup fleetrun run ...`) stays ignored while the command runs."""
    previous = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        seen = []
        _stop_during_simulation(monkeypatch, lambda: seen.append(signal.getsignal(signal.SIGHUP)) or (_ for _ in ()).throw(KeyboardInterrupt))
        fakes.invoke_run(small_fleet(tmp_path / "f.xlsx"), "--out", tmp_path / "out", "--no-cache", "-q")
        assert seen == [signal.SIG_IGN]
    finally:
        signal.signal(signal.SIGHUP, previous)


def test_a_csv_given_as_the_workbook_points_to_import_registrations(tmp_path):
    """Before: "is not an .xlsx workbook (not a zip file; corrupt, ...)" for the analyst's DMV CSV."""
    extract = tmp_path / "dmv.csv"
    extract.write_text("vehicle_class,count\nautomobile,100\n", encoding="utf-8")
    assert_user_error(invoke("run", extract, "--out", tmp_path / "out"), f"{extract}: is a CSV file, not a fleet workbook",
                      "fleetrun import-registrations dmv.csv -o dmv.xlsx")
