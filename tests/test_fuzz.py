"""Fuzzing the fleet workbook (issue 9): what `validate` accepts, `run` runs to finite outputs.

For any workbook: no traceback, exit code 0, 1 or 2 only, an ``Error:`` first line naming the
file when it fails, no inf or NaN in any output, and never "validate passes and run fails".

- ``test_cells_property`` (default suite, a few dozen examples): hypothesis writes hostile
  values into the cells of a valid one-vehicle workbook.
- ``test_seeded_mutation_fuzz`` (``-m slow``): 1,000 workbooks, each the small example fleet
  with 1-4 cells mutated by a seeded generator (numbers scaled by 1e-12..1e12, signs flipped,
  text, blanks, dates, booleans, formulas, huge strings).
- ``test_seeded_csv_fuzz`` (default suite, issue 18): 300 drive-cycle CSVs, diagnose recordings
  and measured fuel-economy files each, mutated line by line (a column scaled by 10^-3..10^6,
  signs, blanks, text, control characters, duplicated, dropped or swapped rows, a renamed
  header): the reader gives a value within the plausible ranges (fleetrun.plausible) or an
  InputError naming the file, never another exception.

Both run `validate` and `run` in-process (click's CliRunner), on the real simulation over a
30-second drive cycle (`short.csv`) in `direct` mode, so one case takes a fraction of a second.
"""
from __future__ import annotations

import datetime
import json
import random
from pathlib import Path

import numpy as np
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


# --- cycles, recordings and measured files (issue 18) ------------------------------------------

def _cycle_text() -> str:
    return "time_s,speed_mps,grade_pct\n" + "".join(
        f"{t},{min(t, 60 - t, 20) * 1.1:.2f},{(t % 7) - 3}\n" for t in range(61))


def _recording_text() -> str:
    import math

    return "time_s,diff_input_torque_Nm,diff_input_speed_rpm,diff_output_torque_Nm\n" + "".join(
        f"{t / 2:g},{100 + 10 * math.sin(t / 2):.4f},{1500 + t:.1f},{350 + 30 * math.sin(t / 2):.4f}\n"
        for t in range(120))


def _measured_text() -> str:
    rows = [f"CAR-{i},{test},{20 + 3 * i + j},{'acme' if i % 2 else 'zeta'}"
            for i in range(1, 4) for j, test in enumerate(("FTP", "HWFET", "US06"))]
    return "vehicle_id,test,mpg,manufacturer\n" + "\n".join(rows) + "\n"


def _mutate_csv(rng: random.Random, text: str) -> str:
    """1-3 line-level hostile edits of a CSV's text."""
    lines = text.splitlines()
    for _ in range(rng.randint(1, 3)):
        if not lines:
            break
        kind = rng.randrange(9)
        row = rng.randrange(1, len(lines)) if len(lines) > 1 else 0
        cells = lines[row].split(",")
        col = rng.randrange(len(cells))
        if kind == 0:        # a unit off: one column of every row scaled
            factor = 10.0 ** rng.choice([-3, 3, 6])
            lines = [lines[0]] + [",".join(f"{float(c) * factor:g}" if i == col and _number(c) == _number(c) else c
                                          for i, c in enumerate(line.split(","))) for line in lines[1:]]
            continue
        if kind == 1:
            cells[col] = rng.choice(["", " ", "abc", "1e308", "-1e308", "inf", "nan", "#N/A", "=1+1",
                                     "\x1b]0;x\x07", "1,5", "x" * 500])
        elif kind == 2:
            cells[col] = "-" + cells[col]
        elif kind == 3:
            lines.insert(row, lines[row])                     # a duplicated row
            continue
        elif kind == 4 and len(lines) > 3:
            del lines[row]
            continue
        elif kind == 5 and len(lines) > 3:
            other = rng.randrange(1, len(lines))
            lines[row], lines[other] = lines[other], lines[row]
            continue
        elif kind == 6:
            header = lines[0].split(",")
            header[rng.randrange(len(header))] = rng.choice(["time_ms", "speed_kph", "mpg ", "Vehicle_ID", "x"])
            lines[0] = ",".join(header)
            continue
        elif kind == 7:
            lines = lines[: rng.randint(0, len(lines))]
            continue
        else:
            cells.append(rng.choice(["", "1", "extra"]))
        lines[row] = ",".join(cells)
    return "\n".join(lines) + ("\n" if lines else "")


def _check_cycle(path: Path) -> None:
    from fleetrun import plausible
    from fleetrun.cycles import load_cycle

    cycle = load_cycle(path)
    assert np.all(np.isfinite(cycle.speed_mps)) and np.all(np.isfinite(cycle.time_s))
    assert cycle.speed_mps.max() <= plausible.MAX_SPEED_MPS and cycle.distance_m > 0
    assert np.abs(cycle.grade_pct).max() <= plausible.MAX_GRADE_PCT


def _check_recording(path: Path) -> None:
    from fleetrun import plausible
    from fleetrun.diagnose.recording import load_recording

    recording = load_recording(path)
    frame = recording.data
    values = frame.to_numpy(dtype=float)
    assert np.all(np.isfinite(values))
    assert np.abs(frame["diff_input_torque_Nm"].to_numpy()).max() <= plausible.MAX_TORQUE_NM


def _check_measured(path: Path) -> None:
    from fleetrun import plausible
    from fleetrun.diagnose.fleet import read_measured

    measured = read_measured(path, [f"CAR-{i}" for i in range(1, 4)])
    mpg = np.array([value[0] for value in measured.values()])
    assert np.all((mpg >= plausible.MPG_RANGE[0]) & (mpg <= plausible.MPG_RANGE[1]))


SIDECAR = (b'configuration = "LD_RWD"\ngear_ratio = 3.73\npeak_engine_torque_Nm = 400\n'
           b"torque_converter_ratio = 3.0\nmax_transmission_gear_ratio = 4.0\n")
CSV_KINDS = {"cycle": (_cycle_text, _check_cycle), "recording": (_recording_text, _check_recording),
             "measured": (_measured_text, _check_measured)}


@pytest.mark.parametrize("kind", sorted(CSV_KINDS))
def test_seeded_csv_fuzz(tmp_path, kind):
    """300 mutated files of each kind (seed 18): a plausible value or a located InputError."""
    from fleetrun.errors import InputError

    make, check = CSV_KINDS[kind]
    path = tmp_path / f"{kind}.csv"
    (tmp_path / f"{kind}.toml").write_bytes(SIDECAR)
    path.write_text(make())
    check(path)                                              # the unmutated file passes
    rng = random.Random(18)
    outcomes = {"ok": 0, "refused": 0}
    for case in range(300):
        text = _mutate_csv(rng, make())
        path.write_text(text)
        try:
            check(path)
            outcomes["ok"] += 1
        except InputError as exc:
            assert str(path) in str(exc) or str(path.with_suffix(".toml")) in str(exc), (case, str(exc)[:300])
            outcomes["refused"] += 1
        except AssertionError as failure:
            raise AssertionError(f"case {case}: {text[:400]!r}: {failure}") from None
        except Exception as exc:
            raise AssertionError(f"case {case}: {type(exc).__name__}: {exc}\n{text[:400]!r}") from None
    assert outcomes["ok"] >= 20 and outcomes["refused"] >= 100, outcomes
