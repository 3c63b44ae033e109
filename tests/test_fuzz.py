"""Fuzzing the fleet workbook (issue 9): what `validate` accepts, `run` runs to finite outputs.

For any workbook: no traceback, exit code 0, 1 or 2 only, an ``Error:`` first line naming the
file when it fails, no inf or NaN in any output, and never "validate passes and run fails".

- ``test_cells_property`` (default suite, a few dozen examples): hypothesis writes hostile
  values into the cells of a valid one-vehicle workbook.
- ``test_seeded_mutation_fuzz`` (``-m slow``): 1,000 workbooks, each the small example fleet
  with 1-4 cells mutated by a seeded generator (numbers scaled by 1e-12..1e12, signs flipped,
  text, blanks, dates, booleans, formulas, huge strings).

Both run `validate` and `run` in-process (click's CliRunner), on the real simulation over a
30-second drive cycle (`short.csv`) in `direct` mode, so one case takes a fraction of a second.
"""
from __future__ import annotations

import datetime
import json
import random
from pathlib import Path

import openpyxl
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fleetrun.cli import cli
from fleetrun.workbook.schema import SCENARIO_COLUMNS, VEHICLE_COLUMNS
from test_fleet_fakes import read_csv, scenario, vehicle, write_fleet

SHORT_CYCLE = "time_s,speed_mps\n" + "".join(
    f"{t},{min(t, 30 - t, 10) * 1.2:.2f}\n" for t in range(31))


def _base(folder: Path) -> Path:
    """A valid workbook: a car and a truck, one scenario over the short cycle."""
    (folder / "short.csv").write_text(SHORT_CYCLE)
    truck = vehicle("TRUCK", vehicle_class="Truck", duty_class="HD", configuration="HD_RWD", fuel="diesel",
                    transmission="manual", transmission_gear_ratios="12.8,9.3,6.8,4.9,3.6,2.6,1.9,1.4,1.0",
                    final_drive_ratio=3.55, test_weight_kg=20000, peak_engine_torque_Nm=2000,
                    coastdown_A_lbf=200, coastdown_B_lbf_per_mph=1.2, coastdown_C_lbf_per_mph2=0.1,
                    tire_size="295/75R22.5", count=300, annual_miles=60000)
    return write_fleet(folder / "base.xlsx", [vehicle("CAR"), truck],
                       [scenario(cycle_mix="short.csv:1", cycle_mix_HD="short.csv:1", budget_years=2)])


def _mutated(base: Path, target: Path, edits: dict[tuple[str, str, int], object]) -> Path:
    wb = openpyxl.load_workbook(base)
    for (sheet, column, row), value in edits.items():
        columns = [c.name for c in (VEHICLE_COLUMNS if sheet == "Vehicles" else SCENARIO_COLUMNS)]
        cell = wb[sheet].cell(row=row, column=columns.index(column) + 1)
        cell.value = value
        if isinstance(value, str) and not value.startswith("="):
            cell.data_type = "s"
    wb.save(target)
    return target


TEXT_COLUMNS = {"scenario_id", "vehicle_id", "vehicle_class", "configuration", "fuel", "duty_class",
                "description", "fiscal_year"}


def _finite_outputs(out: Path) -> list[str]:
    """The non-finite numbers in the run's outputs (numeric CSV columns, the manifest)."""
    import numpy as np

    found = []
    for name in ("results.csv", "class_summary.csv", "fiscal_summary.csv"):
        if not (out / name).exists():
            continue
        table = read_csv(out / name, keep_default_na=False, dtype=str)
        for column in table.columns:
            if column in TEXT_COLUMNS:
                continue
            numbers = np.array([_number(t) for t in table[column] if t != ""], dtype=float)
            if not np.isfinite(numbers).all():
                found.append(f"{name}: {column}")
    manifest = (out / "manifest.json").read_text()
    for token in ("NaN", "Infinity"):
        if token in manifest:
            found.append(f"manifest.json: {token}")
    json.loads(manifest)
    return found


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return float("nan")    # text in a numeric column counts as not a number


def check_case(path: Path, out: Path) -> tuple[int, int]:
    """The fuzz properties for one workbook; (validate exit code, run exit code)."""
    runner = CliRunner()
    checked = runner.invoke(cli, ["validate", str(path)])
    ran = runner.invoke(cli, ["run", str(path), "--out", str(out), "--mode", "direct", "--no-cache", "-q"])
    for result in (checked, ran):
        assert result.exit_code in (0, 1, 2), (result.exit_code, result.output, result.exception)
        assert "Traceback" not in result.output
        if result.exit_code:
            assert result.stderr.startswith(f"Error: {path}") or result.stderr.startswith("Error: "), result.stderr
    assert not (checked.exit_code == 0 and ran.exit_code != 0), ("validate passed, run failed", ran.stderr)
    if checked.exit_code == 1:
        assert ran.exit_code == 1 and ran.stderr.splitlines()[0] == checked.stderr.splitlines()[0]
    if ran.exit_code == 0:
        assert _finite_outputs(out) == []
    return checked.exit_code, ran.exit_code


NUMBER_COLUMNS = [c.name for c in VEHICLE_COLUMNS if c.kind in ("number", "integer")]
hostile_values = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False),
    st.floats(min_value=-1e6, max_value=1e6),
    st.integers(min_value=-10**18, max_value=10**18),
    st.sampled_from(["", " ", "abc", "inf", "-inf", "nan", "1e308", "-0", "1,5", "=1+1", "#DIV/0!",
                     "0x10", "١٢", "1e-320", "\t5", "9" * 400]),
    st.text(st.characters(blacklist_categories=("Cs", "Cc")), max_size=30),   # what a cell can hold
    st.booleans(),
    st.just(datetime.datetime(2024, 1, 5)),
)


@pytest.fixture(scope="module")
def base_workbook(tmp_path_factory) -> Path:
    return _base(tmp_path_factory.mktemp("fuzz"))


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow])
@given(column=st.sampled_from(NUMBER_COLUMNS + ["transmission_gear_ratios", "tire_size", "configuration"]),
       row=st.sampled_from([2, 3]), value=hostile_values)
def test_cells_property(base_workbook, tmp_path_factory, column, row, value):
    folder = base_workbook.parent
    path = _mutated(base_workbook, folder / "case.xlsx", {("Vehicles", column, row): value})
    check_case(path, folder / "out")


def _mutation(rng: random.Random, value):
    """One hostile edit of a cell value."""
    kind = rng.randrange(10)
    if kind == 0 and isinstance(value, (int, float)) and not isinstance(value, bool):
        return value * 10.0 ** rng.randint(-12, 12)
    if kind == 1 and isinstance(value, (int, float)) and not isinstance(value, bool):
        return -value
    if kind == 2:
        return rng.choice(["", None, " "])
    if kind == 3:
        return rng.choice(["abc", "1e308", "-1e308", "inf", "nan", "=HYPERLINK(\"x\")", "@cmd", "#N/A",
                           "x" * rng.randint(100, 5000)])
    if kind == 4:
        return rng.choice([True, False, datetime.datetime(2020, 2, 29, 12, 0)])
    if kind == 5:
        return rng.uniform(-1e4, 1e4)
    if kind == 6:
        return rng.choice([0, 1e-9, 1e-320, 5e-324, 2**63, 10**30])
    if kind == 7 and isinstance(value, str):
        return value[: rng.randint(0, len(value))] + rng.choice(["", ",", ":", "0", "-", ";;"])
    if kind == 8 and isinstance(value, (int, float)) and not isinstance(value, bool):
        return value + rng.choice([-1, 1]) * rng.random() * abs(value or 1)
    return rng.choice(["UDDS:1", "short.csv:0.5,short.csv:0.5", "HWFET:2", "short.csv:1", "LD_RWD",
                       "HD_TANDEM_DUAL", "electric", "manual", "P215/55R17", "11R22.5", "4,3,2,1"])


@pytest.mark.slow
def test_seeded_mutation_fuzz(tmp_path):
    """1,000 mutated workbooks (seed 9): the properties of check_case hold for every one."""
    base = _base(tmp_path)
    wb = openpyxl.load_workbook(base)
    cells = [(sheet, c.name, row) for sheet, columns, rows in (("Vehicles", VEHICLE_COLUMNS, (2, 3)),
                                                               ("Scenarios", SCENARIO_COLUMNS, (2,)))
             for c in columns for row in rows]
    original = {}
    for sheet, name, row in cells:
        columns = [c.name for c in (VEHICLE_COLUMNS if sheet == "Vehicles" else SCENARIO_COLUMNS)]
        original[(sheet, name, row)] = wb[sheet].cell(row=row, column=columns.index(name) + 1).value
    rng = random.Random(9)
    outcomes = {}
    for case in range(1000):
        picked = rng.sample(cells, rng.randint(1, 4))
        edits = {key: _mutation(rng, original[key]) for key in picked}
        path = _mutated(base, tmp_path / "case.xlsx", edits)
        try:
            codes = check_case(path, tmp_path / "out")
        except AssertionError as failure:
            raise AssertionError(f"case {case}: edits {edits!r}: {failure}") from None
        outcomes[codes] = outcomes.get(codes, 0) + 1
    assert sum(outcomes.values()) == 1000
    assert outcomes.get((0, 0), 0) >= 50 and outcomes.get((1, 1), 0) >= 300, outcomes
