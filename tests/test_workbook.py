"""The fleet workbook reader: schema, every problem at once, layout quirks, safety."""
from __future__ import annotations

import io
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import openpyxl
from openpyxl.utils import get_column_letter
import pytest
from click.testing import CliRunner

import fleetrun
from fleetrun.cli import cli
from fleetrun.errors import InputError
from fleetrun.resources import inputs_dir
from fleetrun.workbook import read_fleet
from fleetrun.workbook.schema import SCENARIO_COLUMNS, VEHICLE_COLUMNS
from fleetrun.workbook.template import write_template
from test_fleet_fakes import scenario, small_fleet, vehicle, write_fleet


def problems_of(path) -> list[str]:
    with pytest.raises(InputError) as info:
        read_fleet(path)
    return info.value.problems


def test_template_reads_back_clean(tmp_path):
    path = tmp_path / "t.xlsx"
    write_template(path)
    fleet = read_fleet(path)
    assert [v.vehicle_id for v in fleet.vehicles] == ["EXAMPLE-LD-CAR-01", "EXAMPLE-HD-TRACTOR-01"]
    assert [s.scenario_id for s in fleet.scenarios] == ["EXAMPLE-baseline", "EXAMPLE-hot_summer"]
    # the example rows are marked: reading them back warns, once per row, naming the cell
    assert fleet.warnings == [
        "Scenarios!A2 scenario_id: 'EXAMPLE-baseline' is one of the template's example rows; replace it with "
        "your own data or delete the row",
        "Scenarios!A3 scenario_id: 'EXAMPLE-hot_summer' is one of the template's example rows; replace it with "
        "your own data or delete the row",
        "Vehicles!A2 vehicle_id: 'EXAMPLE-LD-CAR-01' is one of the template's example rows; replace it with "
        "your own data or delete the row",
        "Vehicles!A3 vehicle_id: 'EXAMPLE-HD-TRACTOR-01' is one of the template's example rows; replace it with "
        "your own data or delete the row"]
    assert len(fleet.sha256) == 64
    assert fleet.scenarios[0].cycle_mix == {"UDDS": 0.55, "HWFET": 0.45}
    assert fleet.vehicles[0].transmission_gear_ratios[0] == 4.62


def test_template_has_instructions_dropdowns_and_examples(tmp_path):
    path = tmp_path / "t.xlsx"
    assert CliRunner().invoke(cli, ["template", "-o", str(path)]).exit_code == 0
    wb = openpyxl.load_workbook(path)
    assert wb.sheetnames == ["Instructions", "Registrations", "Vehicles", "Scenarios"]   # registrations first
    ws = wb["Vehicles"]
    header = [c.value for c in ws[1]]
    lists = {dv.formula1 for dv in ws.data_validations.dataValidation}
    assert any("LD_FWD" in f and "HD_TAG_DUAL" in f for f in lists)
    assert '"gasoline,diesel,electric"' in lists and '"automatic,manual"' in lists
    assert ws.max_row == 3 and header[0] == "vehicle_id"
    # every numeric column refuses text and out-of-range numbers in Excel, in both sheets
    for sheet, columns in (("Vehicles", VEHICLE_COLUMNS), ("Scenarios", SCENARIO_COLUMNS)):
        rules = {str(dv.sqref).split(":")[0]: dv for dv in wb[sheet].data_validations.dataValidation}
        for index, column in enumerate(columns, start=1):
            if column.kind in ("number", "integer"):
                rule = rules[f"{get_column_letter(index)}2"]
                assert rule.type == ("whole" if column.kind == "integer" else "decimal"), column.name
                if column.maximum is not None:
                    # no operator attribute means "between" (ECMA-376 ST_DataValidationOperator default)
                    assert (rule.operator or "between", float(rule.formula2)) == ("between", column.maximum), column.name
                elif column.strictly_positive:
                    assert (rule.operator, rule.formula1) == ("greaterThan", "0"), column.name
    again = CliRunner().invoke(cli, ["template", "-o", str(path)])
    assert again.exit_code == 1 and again.stderr.startswith("Error:") and "--force" in again.stderr


def test_values_are_typed_and_normalised(tmp_path):
    path = write_fleet(tmp_path / "f.xlsx",
                       [vehicle("101", configuration="ld-rwd", fuel="Gasoline", transmission="AUTOMATIC",
                                transmission_gear_ratios="4.0; 2.5, 1.5 1.0", count="250")],
                       [scenario(cycle_mix="udds:0.5,hwfet:0.5")])
    fleet = read_fleet(path)
    v = fleet.vehicles[0]
    assert (v.configuration, v.fuel, v.transmission, v.count) == ("LD_RWD", "gasoline", "automatic", 250.0)
    assert v.transmission_gear_ratios == (4.0, 2.5, 1.5, 1.0)
    assert fleet.scenarios[0].cycle_mix == {"UDDS": 0.5, "HWFET": 0.5}


def test_every_problem_reported_at_once_with_cell_and_value(tmp_path):
    path = write_fleet(tmp_path / "bad.xlsx",
                       [vehicle("A", peak_engine_torque_Nm="abc"),
                        vehicle("B", count=-3, fuel="kerosene"),
                        vehicle("A", configuration="LD_XWD"),
                        vehicle("D", duty_class="HD", configuration="LD_FWD"),
                        vehicle("E", vehicle_class="Trucks", duty_class="HD", configuration="HD_DUAL")],
                       [scenario(cycle_mix="UDDS:0.5,HWFX:0.5"), scenario("s2", budget_years=1.5,
                                                                          cycle_mix="UDDS:0.5")])
    problems = problems_of(path)
    assert "Vehicles!H2 peak_engine_torque_Nm: 'abc' is not a number; type a number" in problems
    assert any(p.startswith("Vehicles!E3 count: -3 must be at least 0 (the range of count is 0 to ")
               for p in problems)
    assert "Vehicles!G3 fuel: 'kerosene' is not one of gasoline, diesel, electric" in problems
    assert any(p.startswith("Vehicles!A4 vehicle_id: 'A' is used again (first in row 2)") for p in problems)
    assert any(p.startswith("Vehicles!D5 configuration: 'LD_FWD' does not fit duty_class HD") for p in problems)
    assert any(p.startswith("Vehicles!S6 low_gear_ratio: is empty, but HD_DUAL") for p in problems)
    assert any(p.startswith("Scenarios!D2 cycle_mix: unknown drive cycle 'HWFX' (did you mean HWFET?)")
               for p in problems)
    assert "Scenarios!E3 budget_years: 1.5 is not a whole number" in problems
    assert any(p.startswith("Scenarios!D3 cycle_mix: shares add up to 0.5, not 1") for p in problems)


def test_cli_validate_one_error_message_first_line_counts(tmp_path):
    path = write_fleet(tmp_path / "bad.xlsx", [vehicle(peak_engine_torque_Nm="abc"), vehicle("X", count=-1)])
    result = CliRunner().invoke(cli, ["validate", str(path)])
    assert result.exit_code == 1
    assert result.stderr.startswith("Error: ")
    assert result.stderr.count("Error:") == 1
    first, *lines = result.stderr.strip().splitlines()
    # docs/interface.md: the first line names the file, sheet, cell and value; the others follow
    assert first == f"Error: {path}: Vehicles!H2 peak_engine_torque_Nm: 'abc' is not a number; type a number"
    assert lines == ["  Vehicles!E3 count: -1 must be at least 0 (the range of count is 0 to "
                     "100,000,000; check the units)",
                     "2 problems in the fleet workbook; fix them and check again with "
                     "`fleetrun validate bad.xlsx`"]
    assert "Traceback" not in result.output + result.stderr


def test_cli_validate_ok_and_warnings(tmp_path):
    path = write_fleet(tmp_path / "w.xlsx", [vehicle(test_weight_kg=30000)])
    result = CliRunner().invoke(cli, ["validate", str(path)])
    assert result.exit_code == 0, result.stderr
    assert "Warning: Vehicles!L2 test_weight_kg: 30000 is unusual for a LD vehicle" in result.stderr
    assert "OK: 1 vehicle types" in result.stdout
    strict = CliRunner().invoke(cli, ["validate", "--strict", str(path)])
    assert strict.exit_code == 1 and strict.stderr.count("Error:") == 1


def test_plausibility_warnings_not_errors(tmp_path):
    path = write_fleet(tmp_path / "p.xlsx", [vehicle(test_weight_kg=30000, annual_miles=0, count=2.5)],
                       [scenario(ambient_temp_C=55, state_tax_gasoline_usd_per_gal=4.5)])
    fleet = read_fleet(path)
    text = "\n".join(fleet.warnings)
    assert "Vehicles!L2 test_weight_kg: 30000 is unusual for a LD vehicle" in text
    assert "Vehicles!F2 annual_miles: 0 miles" in text
    assert "Vehicles!E2 count: 2.5 vehicles is not a whole number" in text
    assert "Scenarios!C2 ambient_temp_C: 55 is unusual" in text
    assert "Scenarios!G2 state_tax_gasoline_usd_per_gal: 4.5 is unusual" in text


def test_blank_rows_skipped_extra_columns_kept(tmp_path):
    path = write_fleet(tmp_path / "b.xlsx", [vehicle("A"), {}, vehicle("B")])
    wb = openpyxl.load_workbook(path)
    ws = wb["Vehicles"]
    ws.cell(row=1, column=30, value="fleet_manager_note")
    ws.cell(row=4, column=30, value="ask Bob")
    wb.save(path)
    fleet = read_fleet(path)
    assert [v.vehicle_id for v in fleet.vehicles] == ["A", "B"]
    assert fleet.vehicle_rows == {"A": 2, "B": 4}
    assert fleet.vehicles[1].extra == {"fleet_manager_note": "ask Bob"}
    assert any("'fleet_manager_note' is not a fleetrun column" in w for w in fleet.warnings)


def test_missing_columns_and_sheets(tmp_path):
    path = write_fleet(tmp_path / "m.xlsx", [vehicle()])
    wb = openpyxl.load_workbook(path)
    wb["Vehicles"].delete_cols(8)   # peak_engine_torque_Nm
    del wb["Scenarios"]
    wb.save(path)
    problems = problems_of(path)
    assert any(p.startswith("Scenarios: sheet is missing") for p in problems)
    assert any("Vehicles!row 1: missing required column(s) peak_engine_torque_Nm; add them to the header row" in p for p in problems)


def test_formula_without_cached_value_and_merged_cells_refused(tmp_path):
    path = write_fleet(tmp_path / "f.xlsx", [vehicle("A"), vehicle("B")])
    wb = openpyxl.load_workbook(path)
    ws = wb["Vehicles"]
    ws["F2"] = "=1000*12"          # openpyxl stores no cached result
    ws.merge_cells("B3:C3")
    wb.save(path)
    problems = problems_of(path)
    assert any(p.startswith("Vehicles!F2 annual_miles: formula '=1000*12' has no saved result") for p in problems)
    assert any(p.startswith("Vehicles!B3:C3: merged cells") for p in problems)


def test_hidden_sheet_read_with_warning(tmp_path):
    path = write_fleet(tmp_path / "h.xlsx", [vehicle()])
    wb = openpyxl.load_workbook(path)
    wb["Scenarios"].sheet_state = "hidden"
    wb["Vehicles"].row_dimensions[2].hidden = True
    wb["Vehicles"].column_dimensions["Q"].hidden = True
    wb.save(path)
    fleet = read_fleet(path)
    assert "Scenarios: sheet is hidden; read anyway" in fleet.warnings
    assert "Vehicles: 1 hidden row(s) (2); read anyway" in fleet.warnings
    assert "Vehicles: hidden column(s) Q; read anyway" in fleet.warnings
    assert len(fleet.vehicles) == 1


def test_half_filled_row_reported_once(tmp_path):
    path = write_fleet(tmp_path / "r.xlsx", [vehicle("A"), {"vehicle_id": "B", "count": 3}])
    problems = problems_of(path)
    assert len(problems) == 1 and problems[0].startswith("Vehicles!row 3: 14 required cells are empty")


def test_label_formulas_stay_text(tmp_path):
    path = write_fleet(tmp_path / "x.xlsx", [vehicle("=HYPERLINK(\"http://x\")", vehicle_class="=1+1")])
    fleet = read_fleet(path)
    assert fleet.vehicles[0].vehicle_class == "=1+1"


# --- refusing unsafe or broken files ------------------------------------------------------

def _cli_error(path) -> str:
    result = CliRunner().invoke(cli, ["validate", str(path)])
    assert result.exit_code == 1, result.output
    assert result.stderr.startswith("Error: ") and "Traceback" not in result.stderr
    return result.stderr


def test_not_a_workbook(tmp_path):
    text = tmp_path / "fleet.xlsx"
    text.write_text("vehicle_id,count\nA,1\n")
    assert "not an .xlsx workbook" in _cli_error(text)
    assert "file not found" in _cli_error(tmp_path / "missing.xlsx")
    zipped = tmp_path / "z.xlsx"
    with zipfile.ZipFile(zipped, "w") as z:
        z.writestr("hello.txt", "hi")
    assert "not an .xlsx workbook (no xl/workbook.xml)" in _cli_error(zipped)


def test_truncated_workbook(tmp_path):
    good = small_fleet(tmp_path / "good.xlsx")
    bad = tmp_path / "truncated.xlsx"
    bad.write_bytes(good.read_bytes()[:-400])
    message = _cli_error(bad)
    assert "truncated.xlsx" in message


def _rewrite(source, target, replace: dict[str, bytes], compress=zipfile.ZIP_DEFLATED):
    with zipfile.ZipFile(source) as zin, zipfile.ZipFile(target, "w", compress) as zout:
        for item in zin.infolist():
            zout.writestr(item.filename, replace.get(item.filename, zin.read(item.filename)))
        for name in set(replace) - set(zin.namelist()):
            zout.writestr(name, replace[name])


def test_xml_entity_attack_refused(tmp_path):
    good = small_fleet(tmp_path / "good.xlsx")
    with zipfile.ZipFile(good) as z:
        workbook_xml = z.read("xl/workbook.xml")
    laughs = (b'<?xml version="1.0"?>\n<!DOCTYPE lolz [<!ENTITY lol "lol">'
              b'<!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">]>\n')
    evil = laughs + workbook_xml[workbook_xml.index(b"<workbook"):]
    bad = tmp_path / "laughs.xlsx"
    _rewrite(good, bad, {"xl/workbook.xml": evil})
    assert "DTD or XML entities" in _cli_error(bad)


def test_zip_bomb_refused(tmp_path):
    good = small_fleet(tmp_path / "good.xlsx")
    bad = tmp_path / "bomb.xlsx"
    _rewrite(good, bad, {"xl/media/padding.bin": b"\0" * 60_000_000})
    assert "zip bomb" in _cli_error(bad)


def test_dates_booleans_and_errors_are_not_numbers(tmp_path):
    import datetime

    path = write_fleet(tmp_path / "d.xlsx", [vehicle(annual_miles=datetime.datetime(2024, 1, 5),
                                                      count=True, peak_engine_torque_Nm="#DIV/0!")])
    problems = problems_of(path)
    assert "Vehicles!F2 annual_miles: 2024-01-05 is a date, not a number (format the column as Number)" in problems
    assert "Vehicles!E2 count: True is not a number" in problems
    assert "Vehicles!H2 peak_engine_torque_Nm: '#DIV/0!' is not a number; an Excel error; fix the formula or type the value" in problems


def test_large_fleet_reads_fast(tmp_path):
    """5,000 rows written without a <dimension> (as pandas or openpyxl write-only do)."""
    import time

    from openpyxl import Workbook

    from fleetrun.workbook.schema import SCENARIO_COLUMNS, VEHICLE_COLUMNS

    wb = Workbook(write_only=True)
    ws = wb.create_sheet("Vehicles")
    names = [c.name for c in VEHICLE_COLUMNS]
    ws.append(names)
    base = vehicle()
    for n in range(5000):
        ws.append([f"V{n}" if c == "vehicle_id" else base.get(c) for c in names])
    sc = wb.create_sheet("Scenarios")
    sc.append([c.name for c in SCENARIO_COLUMNS])
    sc.append([scenario().get(c.name) for c in SCENARIO_COLUMNS])
    path = tmp_path / "big.xlsx"
    wb.save(path)
    started = time.perf_counter()
    fleet = read_fleet(path)
    assert len(fleet.vehicles) == 5000 and fleet.vehicle_rows["V4999"] == 5001
    assert time.perf_counter() - started < 10


def test_duty_class_cycle_mixes_checked(tmp_path):
    path = write_fleet(tmp_path / "m.xlsx", [vehicle()],
                       [scenario(cycle_mix_HD="HD-UDDS:0.5", cycle_mix_MD="HD-UDS:1")])
    problems = problems_of(path)
    assert any(p.startswith("Scenarios!L2 cycle_mix_HD: shares add up to 0.5, not 1") for p in problems)
    assert any(p.startswith("Scenarios!K2 cycle_mix_MD: unknown drive cycle 'HD-UDS' (did you mean HD-UDDS?)")
               for p in problems)
    ok = write_fleet(tmp_path / "ok.xlsx", [vehicle()], [scenario(cycle_mix_HD="hd-udds:1")])
    s = read_fleet(ok).scenarios[0]
    assert s.mix_for("HD") == {"HD-UDDS": 1.0} and s.mix_for("MD") == s.mix_for("LD") == s.cycle_mix


def test_shipped_example_fleet_is_clean_and_reproducible(tmp_path):
    shipped = inputs_dir() / "example_fleet.xlsx"
    result = CliRunner().invoke(cli, ["validate", str(shipped)])
    assert result.exit_code == 0 and result.stderr == "", result.stderr
    fleet = read_fleet(shipped)
    configurations = {v.configuration for v in fleet.vehicles}
    assert {"LD_FWD", "LD_RWD", "LD_4WD", "LD_AWD"} <= configurations
    assert {"HD_RWD", "HD_DUAL", "HD_TANDEM", "HD_TANDEM_DUAL", "HD_TAG", "HD_TAG_DUAL"} <= configurations
    assert [s.scenario_id for s in fleet.scenarios] == ["baseline", "hot_summer", "congested_urban"]
    rebuilt = tmp_path / "rebuilt.xlsx"
    script = inputs_dir() / "make_example_fleet.py"
    # The script imports fleetrun: this checkout's, installed or not.
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(Path(fleetrun.__file__).parents[1]),
                                                                      os.environ.get("PYTHONPATH")]))}
    subprocess.run([sys.executable, str(script), "-o", str(rebuilt)], check=True, capture_output=True, env=env)
    again = read_fleet(rebuilt)
    assert again.vehicles == fleet.vehicles and again.scenarios == fleet.scenarios


def test_rows_become_the_same_vehicles_as_the_dataclass_makes(tmp_path):
    """The reader's VehicleSpec (made without the frozen dataclass's __init__, for speed) equals
    ``VehicleSpec(**fields)``: fields, their order in ``__dict__`` (pickles alike), repr, hash
    and the Kim scale __post_init__ sets (blank in the row, and given); other dicts go through
    __init__, unknown and missing fields raise as it does."""
    import dataclasses
    import pickle

    from fleetrun.vehicle import VehicleSpec, vehicle_from_fields

    path = small_fleet(tmp_path / "f.xlsx")
    read = read_fleet(path).vehicles
    given = dataclasses.replace(read[0], kim_torque_scale_Nm=1234.5)
    for v in [*read, given]:
        values = {f.name: getattr(v, f.name) for f in dataclasses.fields(VehicleSpec)}
        for kim in (None, v.kim_torque_scale_Nm):
            values["kim_torque_scale_Nm"] = kim
            fast, slow = vehicle_from_fields(dict(values)), VehicleSpec(**values)
            assert fast == slow and repr(fast) == repr(slow) and hash(fast) == hash(slow)
            assert list(vars(fast).items()) == list(vars(slow).items())
            assert pickle.dumps(fast) == pickle.dumps(slow)
    values = {f.name: getattr(read[0], f.name) for f in dataclasses.fields(VehicleSpec)}
    values.pop("extra")
    assert vehicle_from_fields(dict(reversed(list(values.items())))) == VehicleSpec(**values)   # defaults
    with pytest.raises(TypeError):
        vehicle_from_fields({**values, "no_such_field": 1})
    with pytest.raises(TypeError):
        vehicle_from_fields({k: v for k, v in values.items() if k != "fuel"})


def test_label_group_is_read_onto_the_vehicle(tmp_path):
    """`label_group` (docs/workbook.md): rows that share one EPA label; text, optional."""
    rows = [vehicle("A", label_combined_mpg=28.0, label_group="camry 2.5"),
            vehicle("B", label_combined_mpg=28.0, label_group="camry 2.5"), vehicle("C")]
    fleet = read_fleet(write_fleet(tmp_path / "f.xlsx", rows, [scenario()]))
    assert [v.label_group for v in fleet.vehicles] == ["camry 2.5", "camry 2.5", None]


def test_label_city_and_highway_are_read_onto_the_vehicle(tmp_path):
    """`label_city_mpg`, `label_highway_mpg` (docs/workbook.md): optional numbers, 3-200 mpg."""
    rows = [vehicle("A", label_city_mpg=24.0, label_highway_mpg=33.0), vehicle("C")]
    fleet = read_fleet(write_fleet(tmp_path / "f.xlsx", rows, [scenario()]))
    assert [(v.label_city_mpg, v.label_highway_mpg) for v in fleet.vehicles] == [(24.0, 33.0), (None, None)]


def test_one_label_figure_of_the_pair_alone_is_a_warning(tmp_path):
    """docs/workbook.md: `label_city_mpg` and `label_highway_mpg` are used together; one alone is
    said at its cell (a warning, the row is still read)."""
    rows = [vehicle("A", label_city_mpg=24.0), vehicle("B", label_highway_mpg=33.0, label_city_mpg=24.0)]
    fleet = read_fleet(write_fleet(tmp_path / "f.xlsx", rows, [scenario()]))
    text = "\n".join(fleet.warnings)
    assert "label_city_mpg" in text and "label_highway_mpg is empty" in text
    assert text.count("used together") == 1 and len(fleet.vehicles) == 2
