"""Read and validate the fleet workbook (docs/interface.md, "Fleet workbook").

``read_fleet(path)`` checks everything before any simulation and reports every problem at
once: one :class:`~fleetrun.errors.InputError` whose message is the count of problems followed
by one line per problem, e.g. ``Vehicles!H4 peak_engine_torque_Nm: 'abc' is not a number``.
Implausible but possible values (a 30 t light-duty vehicle) become warnings on the Fleet.

Layout handled: header in row 1 (names matched case-insensitively), blank rows skipped, extra
columns kept in ``VehicleSpec.extra`` with a warning, hidden sheets read with a warning.
Refused: merged cells in the data, formulas whose result was never saved, duplicate headers.
"""
from __future__ import annotations

import hashlib
import math
import re
import zipfile
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np
from python_calamine import CalamineError
from xlsxwriter.utility import xl_col_to_name

from fleetrun.cycles import load_cycle, shipped_cycles
from fleetrun.errors import InputError, closest_names, unknown_name_error
from fleetrun.simulation.params import refused_vehicles
from fleetrun.vehicle import VehicleSpec
from fleetrun.workbook import cells, rows
from fleetrun.workbook.cells import CellProblem
from fleetrun.workbook.schema import (EXAMPLE_PREFIX, PLAUSIBLE_SCENARIO, REGISTRATION_COLUMNS,
                                   REGISTRATIONS_SHEET, SCENARIO_COLUMNS, SCENARIOS_SHEET, VEHICLE_COLUMNS,
                                   VEHICLES_SHEET, Column)
from fleetrun.workbook.xlsx_read import XlsxBook
from fleetrun.workbook.xlsx_safety import HINT, check_xlsx, column_number, scan_sheets


def get_column_letter(index: int) -> str:
    """A 1-based column index as its letters (1 = A)."""
    return xl_col_to_name(index - 1)


ROW_MOSTLY_EMPTY = 4       # this many empty required cells: report the row once
MIX_SUM_TOLERANCE = 0.01   # shares typed as 0.33,0.33,0.33 (0.99) are normalised (with a warning)
MIX_COLUMNS = ("cycle_mix", "cycle_mix_MD", "cycle_mix_HD")


@dataclass(frozen=True)
class Scenario:
    scenario_id: str
    description: str
    ambient_temp_C: float
    cycle_mix: dict[str, float]          # cycle name (or CSV path) -> share of annual miles
    budget_years: int
    vmt_growth_pct_per_year: float
    state_tax_gasoline_usd_per_gal: float
    state_tax_diesel_usd_per_gal: float
    federal_tax_gasoline_usd_per_gal: float
    federal_tax_diesel_usd_per_gal: float
    cycle_mix_MD: dict[str, float] | None = None   # None: MD vehicles drive cycle_mix
    cycle_mix_HD: dict[str, float] | None = None   # None: HD vehicles drive cycle_mix
    first_fiscal_year: int | None = None             # None: budget years numbered 1, 2, ...
    onroad_adjustment: str | float = "epa_label"    # "epa_label", "none" or a factor
    observed_base_gallons_gasoline: float | None = None
    observed_base_gallons_diesel: float | None = None
    observed_base_gallons_gasoline_LD: float | None = None   # per-class calibration (docs/budget.md)
    observed_base_gallons_gasoline_HD: float | None = None
    observed_base_gallons_diesel_LD: float | None = None
    observed_base_gallons_diesel_HD: float | None = None
    calibrate_to_observed: bool = False
    ev_fee_usd_per_vehicle_year: float = 0.0
    # drivers (docs/budget.md): fiscal periods, fuel price (a number or {fiscal year: $/gal}),
    # price elasticities (None: models/budget.toml), state tax per fiscal year
    fiscal_year_start_month: int | None = None
    fuel_price_gasoline_usd_per_gal: float | dict | None = None
    fuel_price_diesel_usd_per_gal: float | dict | None = None
    price_elasticity_short_run: float | None = None
    price_elasticity_long_run: float | None = None
    state_tax_schedule_gasoline_usd_per_gal: dict | float | None = None
    state_tax_schedule_diesel_usd_per_gal: dict | float | None = None
    state_tax_index_pct_per_year: float | None = None
    base_year_vmt_million: float | None = None          # registrations: base fiscal year's VMT
    base_year_vmt_share_pct: dict | None = None         # registrations: {FHWA class: % of the VMT}
    new_vehicle_mpg_change_pct_per_year: float | None = None   # None: the published trend's
    extra: dict = field(default_factory=dict, compare=False)

    def mix_for(self, duty_class: str) -> dict[str, float]:
        """The cycle mix that vehicles of ``duty_class`` drive in this scenario."""
        own = {"MD": self.cycle_mix_MD, "HD": self.cycle_mix_HD}.get(duty_class)
        return own or self.cycle_mix

    def state_tax_usd_per_gal(self, fuel: str, year: int = 1) -> float:
        """The state fuel-tax rate of ``fuel`` in budget year ``year`` (1 = the first; 0 for
        electric: no gallons): the schedule's rate of that fiscal year (a year it does not list:
        the latest listed year before it, else the base rate), else the base rate indexed by
        ``state_tax_index_pct_per_year``."""
        base = {"gasoline": self.state_tax_gasoline_usd_per_gal,
                "diesel": self.state_tax_diesel_usd_per_gal}.get(fuel, 0.0)
        schedule = {"gasoline": self.state_tax_schedule_gasoline_usd_per_gal,
                    "diesel": self.state_tax_schedule_diesel_usd_per_gal}.get(fuel)
        if isinstance(schedule, (int, float)):
            return float(schedule)
        if schedule:
            fiscal_year = (self.first_fiscal_year or 1) + year - 1
            earlier = [y for y in schedule if y <= fiscal_year]
            return float(schedule[max(earlier)]) if earlier else base
        index = (self.state_tax_index_pct_per_year or 0.0) / 100.0
        return base * (1.0 + index) ** (year - 1)

    def federal_tax_usd_per_gal(self, fuel: str) -> float:
        """The federal fuel-tax rate of ``fuel`` (0 for electric)."""
        return {"gasoline": self.federal_tax_gasoline_usd_per_gal,
                "diesel": self.federal_tax_diesel_usd_per_gal}.get(fuel, 0.0)

    def observed_base_gallons(self, fuel: str) -> float | None:
        """Taxable gallons of ``fuel`` collected in the first fiscal year, if given (the sum of
        the light- and heavy-duty split where only that is given)."""
        total = {"gasoline": self.observed_base_gallons_gasoline,
                 "diesel": self.observed_base_gallons_diesel}.get(fuel)
        split = self.observed_split(fuel)
        return total if total is not None or split is None else split["LD"] + split["HD"]

    def observed_split(self, fuel: str) -> dict[str, float] | None:
        """``{"LD": ..., "HD": ...}`` taxable gallons of ``fuel`` by class group (HD: medium- and
        heavy-duty rows) in the first fiscal year, where both are given."""
        ld = getattr(self, f"observed_base_gallons_{fuel}_LD", None)
        hd = getattr(self, f"observed_base_gallons_{fuel}_HD", None)
        return None if ld is None or hd is None else {"LD": ld, "HD": hd}

    def mile_factor(self) -> float:
        """Budget-period miles per unit of annual miles: sum over y of (1 + g)^(y - 1)."""
        g = self.vmt_growth_pct_per_year / 100.0
        return float(sum((1.0 + g) ** (y - 1) for y in range(1, self.budget_years + 1)))


@dataclass
class Fleet:
    path: Path
    sha256: str
    vehicles: list[VehicleSpec]
    scenarios: list[Scenario]
    warnings: list[str] = field(default_factory=list)
    vehicle_rows: dict[str, int] = field(default_factory=dict)    # vehicle_id -> Excel row
    scenario_rows: dict[str, int] = field(default_factory=dict)
    # Registrations sheet rows: column -> value, plus "_row" (Excel row); docs/registrations.md
    registrations: list[dict] = field(default_factory=list)

    def input_files(self) -> list[Path]:
        """The files besides the workbook that a run of this fleet reads (cycle CSVs)."""
        found = {}
        for s in self.scenarios:
            for mix in (s.cycle_mix, s.cycle_mix_MD, s.cycle_mix_HD):
                for name in mix or {}:
                    if name.lower().endswith(".csv"):
                        found[name] = Path(name)
        return list(found.values())

    def vehicle(self, vehicle_id: str) -> VehicleSpec:
        for v in self.vehicles:
            if v.vehicle_id == vehicle_id:
                return v
        if not self.vehicles:   # a fleet from registrations only: its vehicles are chosen by `run`
            raise InputError(f"has no Vehicles rows, so no vehicle_id '{vehicle_id}' (a fleet from registrations: "
                             "its vehicles are chosen from the library by `fleetrun run`, listed in registrations.csv)",
                             file=self.path, hint="Add a Vehicles row for it, or give --vehicle-file")
        error = unknown_name_error("vehicle_id", vehicle_id, [v.vehicle_id for v in self.vehicles])
        error.file = self.path
        raise error

    def scenario(self, scenario_id: str) -> Scenario:
        for s in self.scenarios:
            if s.scenario_id == scenario_id:
                return s
        error = unknown_name_error("scenario_id", scenario_id, [s.scenario_id for s in self.scenarios],
                                   hint="Scenario ids are in the Scenarios sheet")
        error.file = self.path
        raise error


class Problems:
    """Collects errors and warnings, each tied to a cell, sheet or row."""

    def __init__(self):
        self.errors: list[tuple[tuple, str]] = []
        self.warnings: list[tuple[tuple, str]] = []

    @staticmethod
    def where(sheet, row=None, col=None, name=None) -> tuple[tuple, str]:
        ref = sheet + "!"
        if col is not None and row is not None:
            ref += f"{get_column_letter(col)}{row}"
        elif row is not None:
            ref += f"row {row}"
        else:
            ref = sheet
        if name:
            ref += f" {name}"
        return (sheet, row or 0, col or 0), ref

    def error(self, text, sheet, row=None, col=None, name=None):
        key, ref = self.where(sheet, row, col, name)
        self.errors.append((key, f"{ref}: {text}"))

    def warn(self, text, sheet, row=None, col=None, name=None):
        key, ref = self.where(sheet, row, col, name)
        self.warnings.append((key, f"{ref}: {text}"))

    def sorted_errors(self) -> list[str]:
        return [text for _, text in sorted(self.errors, key=lambda e: e[0])]

    def sorted_warnings(self) -> list[str]:
        return [text for _, text in sorted(self.warnings, key=lambda e: e[0])]


def file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def read_fleet(path) -> Fleet:
    """Read, validate and return the fleet in ``path``; InputError lists every problem."""

    path = Path(path)
    check_xlsx(path)
    scans = scan_sheets(path, (VEHICLES_SHEET, SCENARIOS_SHEET, REGISTRATIONS_SHEET))   # before any allocation
    problems = Problems()
    vehicle_table = scenario_table = registration_table = None
    try:
        with XlsxBook(path, scans) as book:
            sheets = {s.name: s for s in book.sheets}
            if REGISTRATIONS_SHEET in sheets:   # an empty Registrations sheet (the template's) is no fleet
                registration_table = _read_table(book, sheets[REGISTRATIONS_SHEET], REGISTRATION_COLUMNS, problems,
                                                 allow_empty=True)
            has_registrations = bool(registration_table and registration_table.rows)
            for name in (VEHICLES_SHEET, SCENARIOS_SHEET):
                alike = [t for t in sheets if cells.skeleton(t).strip().casefold() == name.casefold()]
                if len(alike) > 1:
                    problems.error(f"the workbook has {len(alike)} sheets named like it ("
                                   f"{', '.join(repr(t) for t in alike)}); which to read is ambiguous: "
                                   "delete or rename the others", name)
                if name == VEHICLES_SHEET and name not in sheets and has_registrations:
                    continue   # a fleet from registrations only
                if name not in sheets:
                    similar = [t for t in sheets if t.strip().lower() == name.lower()]
                    hint = f" (found '{similar[0]}': rename it)" if similar else ""
                    problems.error(f"sheet is missing{hint}; the workbook has: "
                                   f"{', '.join(sheets) or 'no sheets'}", name)
            if VEHICLES_SHEET in sheets:   # may be empty beside registrations
                vehicle_table = _read_table(book, sheets[VEHICLES_SHEET], VEHICLE_COLUMNS, problems,
                                            allow_empty=has_registrations)
            if SCENARIOS_SHEET in sheets:
                scenario_table = _read_table(book, sheets[SCENARIOS_SHEET], SCENARIO_COLUMNS, problems)
    except (CalamineError, KeyError, ValueError, IndexError, zipfile.BadZipFile, OSError, EOFError) as exc:
        raise InputError(f"cannot be read as an .xlsx workbook (corrupt? {type(exc).__name__}: {exc})",
                         file=path, hint=HINT) from None

    vehicles, vehicle_rows = ([], {})
    if vehicle_table is not None:
        vehicles, vehicle_rows = _vehicles(vehicle_table, problems)
        if not problems.errors:  # the simulation's checks presume cells that passed their own
            _simulation_checks(vehicle_table, vehicles, vehicle_rows, problems)
    scenarios, scenario_rows = ([], {})
    if scenario_table is not None:
        scenarios, scenario_rows = _scenarios(scenario_table, problems, path.parent)
    registrations = _registrations(registration_table, vehicle_rows, problems) if registration_table else []
    if not problems.errors and registrations:
        _check_something_to_forecast(vehicles, registrations, registration_table, problems)
    if scenario_table is not None:
        _check_share_classes(scenarios, scenario_rows, registrations, scenario_table, problems)
        if registrations:
            _check_base_vmt(scenarios, scenario_rows, vehicles, scenario_table, problems)

    if problems.errors:
        errors = problems.sorted_errors()
        noun, pronoun = ("problem", "it") if len(errors) == 1 else ("problems", "them")
        # docs/interface.md: the first line names file, sheet, cell and value; the others follow
        tail = (f"{len(errors)} {noun} in the fleet workbook; fix {pronoun} and check again with "
                f"`fleetrun validate {path.name}`")
        error = InputError("\n".join([f"{path}: {errors[0]}"] + ["  " + e for e in errors[1:]] + [tail]))
        error.problems = errors
        error.warnings = problems.sorted_warnings()
        raise error
    return Fleet(path=path, sha256=file_sha256(path), vehicles=vehicles, scenarios=scenarios,
                 warnings=problems.sorted_warnings(), vehicle_rows=vehicle_rows,
                 scenario_rows=scenario_rows, registrations=registrations)


# --- reading a sheet into rows of raw values ---------------------------------------------

@dataclass
class _Table:
    sheet: str
    columns: dict[str, int]              # schema column name -> 1-based column index
    extra_columns: dict[str, int]        # other headers -> column index
    rows: list[tuple[int, tuple]]        # (Excel row number, values)
    uncached: dict = field(default_factory=dict)   # (row, col) -> formula without saved result
    present: list[tuple[Column, int]] = field(default_factory=list)   # schema columns found, in order
    plan: list | None = None             # _plan's per-column fast-path bounds, made once
    texts: dict = field(default_factory=dict)   # column index -> {text: parsed value or CellProblem}


def _read_table(book, info, schema: tuple[Column, ...], problems: Problems, allow_empty: bool = False) -> _Table:
    sheet = info.name
    if info.state != "visible":
        problems.warn("sheet is hidden; read anyway", sheet)
    values = book.read(info)
    for ref in values.merged:
        first = ref.split(":")[0]
        match = re.match(r"([A-Z]+)([0-9]+)", first)
        key = (sheet, int(match.group(2)), column_number(match.group(1))) if match else (sheet, 0, 0)
        problems.errors.append((key, f"{sheet}!{ref}: merged cells; unmerge them and give every "
                                     "row its own values"))
    if values.hidden_rows:
        shown = ", ".join(map(str, values.hidden_rows[:10])) + (" ..." if len(values.hidden_rows) > 10 else "")
        problems.warn(f"{len(values.hidden_rows)} hidden row(s) ({shown}); read anyway", sheet)
    if values.hidden_columns:
        problems.warn("hidden column(s) " + ", ".join(get_column_letter(c) for c in values.hidden_columns[:10])
                      + "; read anyway", sheet)
    header = values.rows[0][1] if values.rows and values.rows[0][0] == 1 else ()
    known = {c.name.lower(): c.name for c in schema}
    columns: dict[str, int] = {}
    extra: dict[str, int] = {}
    mistyped: set[str] = set()      # headers spelt with look-alike letters (reported as such)
    for index, value in enumerate(header, start=1):
        if cells.is_blank(value):
            continue
        text = str(value).strip()
        name = known.get(text.lower()) or known.get(cells.as_name(text))   # "Vehicle Class"
        if name is None and known.get(cells.skeleton(text).lower()):
            mistyped.add(known[cells.skeleton(text).lower()])
            problems.error(f"header {cells.show(text)} looks like {known[cells.skeleton(text).lower()]} but has "
                           f"look-alike letters: {', '.join(cells.lookalike_letters(text))}; retype it",
                           sheet, 1, index)
            continue
        if name is None:
            if text in extra:
                problems.error(f"column '{text}' appears twice (also column "
                               f"{get_column_letter(extra[text])})", sheet, 1, index)
            else:
                extra[text] = index
                problems.warn(f"column '{text}' is not a fleetrun column; ignored "
                              "(echoed in the report's Inputs sheet)", sheet, 1, index)
            continue
        if name in columns:
            problems.error(f"column '{name}' appears twice (also column "
                           f"{get_column_letter(columns[name])}); delete one", sheet, 1, index)
            continue
        columns[name] = index
    missing = [c.name for c in schema if c.required and c.name not in columns and c.name not in mistyped]
    if missing:
        near = [f"'{found[0]}' for {m}" for m in missing if (found := closest_names(m, extra))]
        problems.error(f"missing required column(s) {', '.join(missing)}; add them to the header row"
                       + (f" (or rename {', '.join(near)})" if near else ""), sheet, 1, name=None)
    body: list[tuple[int, tuple]] = []
    headed = set(columns.values()) | set(extra.values())
    widest = max((len(r) for _, r in values.rows), default=0)
    unheaded = [i for i in range(1, widest + 1) if i not in headed]   # looked at in each row
    unheaded_warned: set[int] = set()
    uncached_rows = {r for r, _ in values.uncached_formulas}
    for row_number, row_values in values.rows:
        if row_number == 1:
            continue
        if all(cells.is_blank(v) for v in row_values) and row_number not in uncached_rows:
            continue  # blank rows (between blocks, or formatted-but-empty at the end)
        width = len(row_values)
        for index in unheaded:
            if index > width:
                break
            if index not in unheaded_warned and not cells.is_blank(row_values[index - 1]):
                unheaded_warned.add(index)
                problems.warn(f"has data in column {get_column_letter(index)} that has no header; "
                              "ignored", sheet, row_number, index)
        body.append((row_number, row_values))
    if not body and not allow_empty:
        problems.error("has no data rows below the header", sheet)
    present = [(c, columns[c.name]) for c in schema if c.name in columns]
    return _Table(sheet, columns, extra, body, values.uncached_formulas, present)


def _cell(values: tuple, index: int | None):
    if index is None or index > len(values):
        return None
    return values[index - 1]


def _parse_row(table: _Table, schema, row_number: int, values: tuple, problems: Problems) -> tuple[dict, bool]:
    """The row's schema columns as typed values (None when blank or bad), and whether all
    cells were good (row-level checks still run on the good ones)."""
    parsed = dict.fromkeys(_names(schema))
    ok = True
    blanks: list[tuple[Column, int]] = []
    uncached, width = table.uncached, len(values)
    for column, index, low, high, known, whole in _plan(table):
        raw = values[index - 1] if index <= width else None
        if uncached and (row_number, index) in uncached:
            problem, raw = rows.scanned_cell(column, uncached[(row_number, index)], raw)
            if problem:
                problems.error(problem, table.sheet, row_number, index, column.name)
                ok = False
                continue
        if type(raw) is float and low <= raw <= high:   # a number within its range: rows.parse_value's fast path
            if not whole:
                parsed[column.name] = raw
                continue
            if raw.is_integer():   # an integer column's whole number (what rows.parse_value gives it)
                parsed[column.name] = int(raw)
                continue
        if type(raw) is str and (comma := rows.comma_reading(column, raw)):   # 1,500: 1500 or 1.5?
            problems.warn(comma, table.sheet, row_number, index, column.name)
        value = known.get(raw, _UNSEEN) if type(raw) is str else _UNSEEN   # a text seen before in this column
        if value is not _UNSEEN and not isinstance(value, CellProblem):
            parsed[column.name] = value
            continue
        if raw is None or (type(raw) is str and not raw.strip()):
            if column.required:
                blanks.append((column, index))
            continue
        value = _parsed_value(table, column, index, raw)
        if isinstance(value, CellProblem):
            problems.error(str(value), table.sheet, row_number, index, column.name)
            ok = False
        else:
            parsed[column.name] = value
    if len(blanks) >= ROW_MOSTLY_EMPTY:
        # A half-filled row: one line for the row, not one per cell.
        listed = ", ".join(f"{c.name} ({get_column_letter(i)})" for c, i in blanks)
        label = next((v for v in values if isinstance(v, str) and cells.is_total_label(v)), None)
        total = f"{cells.show(label)} {cells.TOTAL_ROW}; else " if label else ""   # a Total row under the table
        problems.error(f"{total}{len(blanks)} required cells are empty: {listed}", table.sheet, row_number)
    for column, index in (blanks if len(blanks) < ROW_MOSTLY_EMPTY else ()):
        problems.error("is empty (required)", table.sheet, row_number, index, column.name)
    extra = {name: _cell(values, index) for name, index in table.extra_columns.items()}
    parsed["_extra"] = {k: v for k, v in extra.items() if not cells.is_blank(v)}
    return parsed, ok and not blanks


@lru_cache(maxsize=8)
def _names(schema) -> tuple[str, ...]:
    return tuple(c.name for c in schema)


def _plan(table: _Table) -> list[tuple[Column, int, float, float, dict, bool]]:
    """Per schema column present: (column, index, low, high, texts, whole), the range a float
    cell may take without further parsing (rows.parse_value's own fast path; for an integer
    column (whole) a whole number in it is taken as int; an empty range for the others) and the
    column's parsed texts (:func:`_parsed_value`)."""
    if table.plan is None:
        table.plan = [(c, i, *(rows.number_bounds(c) if c.kind in ("number", "integer") else (math.inf, -math.inf)),
                       table.texts.setdefault(i, {}), c.kind == "integer") for c, i in table.present]
    return table.plan


TEXT_CACHE_SIZE = 4096   # distinct texts remembered per column (choices, ratios and tyres repeat)


def _parsed_value(table: _Table, column: Column, index: int, raw):
    """rows.parse_value of a non-blank cell, or the CellProblem it raised. A text cell's result
    is remembered per column of this table: a fleet repeats its choices, ratios and tyres."""
    if type(raw) is not str:
        try:
            return rows.parse_value(column, raw)
        except CellProblem as problem:
            return problem
    known = table.texts.setdefault(index, {})
    value = known.get(raw, _UNSEEN)
    if value is _UNSEEN:
        try:
            value = rows.parse_value(column, raw)
        except CellProblem as problem:
            value = problem
        if len(known) < TEXT_CACHE_SIZE:
            known[raw] = value
    return value


_UNSEEN = object()


def _text_or_blank(raw) -> str:
    try:
        return "" if cells.is_blank(raw) else cells.parse_text(raw)
    except CellProblem:
        return ""


def _warn_example(parsed: dict, key: str, table: "_Table", row_number: int, problems: Problems) -> None:
    """A row whose id still carries the template's example prefix: warn (it would be counted)."""
    value = parsed.get(key)
    if isinstance(value, str) and value.upper().startswith(EXAMPLE_PREFIX):
        problems.warn(f"{cells.show(value)} is one of the template's example rows; replace it with your own "
                      "data or delete the row", table.sheet, row_number, table.columns.get(key), key)


def _first_use(parsed: dict, key: str, rows: dict, table: "_Table", row_number: int, problems: Problems) -> bool:
    """Record the row of ``parsed[key]``; an id seen before is an error naming its first row."""
    value = parsed.get(key)
    if not value:
        return True
    if value in rows:
        noun = key.removesuffix("_id")
        problems.error(f"{cells.show(value)} is used again (first in row {rows[value]}); {noun} ids must be unique",
                       table.sheet, row_number, table.columns.get(key), key)
        return False
    rows[value] = row_number
    return True


# --- Vehicles -----------------------------------------------------------------------------

def _vehicles(table: _Table, problems: Problems):
    vehicles: list[VehicleSpec] = []
    first_rows: dict[str, int] = {}
    for row_number, values in table.rows:
        parsed, ok = _parse_row(table, VEHICLE_COLUMNS, row_number, values, problems)
        ok = _first_use(parsed, "vehicle_id", first_rows, table, row_number, problems) and ok
        _warn_example(parsed, "vehicle_id", table, row_number, problems)
        ok = rows.check_vehicle(parsed, _reporter(table, row_number, problems)) and ok
        if ok:
            vehicles.append(rows.vehicle_spec(parsed, parsed["_extra"]))
    return vehicles, first_rows


def _reporter(table: _Table, row: int, problems: Problems):
    """rows.Report for one row of ``table``: a column name -> its cell."""
    def report(name: str, text: str, warning: bool = False):
        col = table.columns.get(name)
        if col is None and name == "low_gear_ratio":
            col = table.columns.get("configuration")
        (problems.warn if warning else problems.error)(text, table.sheet, row, col, name)
    return report


def _simulation_checks(table: _Table, vehicles: list[VehicleSpec], first_rows: dict[str, int],
                       problems: Problems):
    """What the simulation would refuse in rows that passed the cell checks
    (:func:`fleetrun.simulation.params.refused_vehicles`), as problems at the row and column:
    `validate` catches what `run` would refuse."""
    for i, exc in refused_vehicles(vehicles):
        column = exc.column if isinstance(exc.column, str) else None
        index = (table.columns.get(column) or table.extra_columns.get(column)) if column else None
        value = "" if exc.value is None else f" (value {cells.show(exc.value)})"
        hint = f"; {exc.hint}" if exc.hint else ""
        problems.error(f"{exc.message}{value}{hint}", table.sheet, first_rows[vehicles[i].vehicle_id], index,
                       column if index else None)


# --- Scenarios ----------------------------------------------------------------------------

def _scenarios(table: _Table, problems: Problems, workbook_dir: Path):
    sheet, col = table.sheet, table.columns.get
    scenarios: list[Scenario] = []
    first_rows: dict[str, int] = {}
    known_cycles = _shipped_cycle_names()
    for row_number, values in table.rows:
        parsed, ok = _parse_row(table, SCENARIO_COLUMNS, row_number, values, problems)
        ok = _first_use(parsed, "scenario_id", first_rows, table, row_number, problems) and ok
        _warn_example(parsed, "scenario_id", table, row_number, problems)
        _warn_typed_truck_mixes(parsed, table, row_number, problems)
        shares = parsed.get("base_year_vmt_share_pct")
        if shares and max(shares.values()) < 1.0:
            problems.warn("every share is below 1: these are percents (combination_truck:9.1 is 9.1 % of the "
                          "miles), not fractions; check them", sheet, row_number, col("base_year_vmt_share_pct"),
                          "base_year_vmt_share_pct")
        _default_mixes(parsed)
        mixes = {}
        for name in MIX_COLUMNS:
            if parsed[name] is not None:
                mixes[name] = _check_cycle_mix(parsed[name], known_cycles, workbook_dir, table, row_number,
                                               problems, name)
                ok = ok and mixes[name] is not None
        mix = mixes.get("cycle_mix")
        g = parsed["vmt_growth_pct_per_year"]
        if g is not None and g <= -100:
            problems.error(f"{g:g} % would make the miles negative", sheet, row_number,
                           col("vmt_growth_pct_per_year"), "vmt_growth_pct_per_year")
            ok = False
        if not ok or mix is None:
            continue
        for name, (low, high) in PLAUSIBLE_SCENARIO.items():
            value = parsed[name]
            if value is not None and not (low <= value <= high):
                problems.warn(f"{value:g} is unusual (expected {low:g} to {high:g}); check the units",
                              sheet, row_number, col(name), name)
        fields = {c.name: parsed[c.name] for c in SCENARIO_COLUMNS}
        fields["description"] = fields["description"] or ""
        if not _budget_fields(fields, table, row_number, problems):
            continue
        fields.update(mixes)
        scenarios.append(Scenario(**fields, extra=parsed["_extra"]))
    rows.check_temperature_budget([(first_rows.get(s.scenario_id), s.ambient_temp_C) for s in scenarios],
                                  lambda row, text: problems.error(text, sheet, row, col("ambient_temp_C"),
                                                                   "ambient_temp_C"))
    return scenarios, first_rows


def _budget_fields(fields: dict, table: _Table, row: int, problems: Problems) -> bool:
    """Defaults of the optional budget columns; calibration needs observed gallons."""
    fields["onroad_adjustment"] = fields["onroad_adjustment"] or "epa_label"
    fields["ev_fee_usd_per_vehicle_year"] = fields["ev_fee_usd_per_vehicle_year"] or 0.0
    fields["calibrate_to_observed"] = fields["calibrate_to_observed"] == "yes"
    for fuel in ("gasoline", "diesel"):
        if not _split_is_whole(fields, fuel, table, row, problems):
            return False
    observed = [fields[c.name] for c in SCENARIO_COLUMNS if c.name.startswith("observed_base_gallons_")]
    if fields["calibrate_to_observed"] and all(g is None for g in observed):
        problems.error("is yes, but neither observed_base_gallons_gasoline nor observed_base_gallons_diesel "
                       "is given; fill in the gallons collected in the first fiscal year, or set it to no",
                       table.sheet, row, table.columns.get("calibrate_to_observed"), "calibrate_to_observed")
        return False
    return True


def _split_is_whole(fields: dict, fuel: str, table: _Table, row: int, problems: Problems) -> bool:
    """A class split of observed gallons gives both groups, and agrees with a total given beside it
    (to 0.5 %: the total is the split's sum, rounded)."""
    ld, hd = (f"observed_base_gallons_{fuel}_{g}" for g in ("LD", "HD"))
    total = fields[f"observed_base_gallons_{fuel}"]
    if (fields[ld] is None) != (fields[hd] is None):
        missing = hd if fields[hd] is None else ld
        problems.error(f"is empty, but {ld if missing == hd else hd} is given; a class split needs both groups",
                       table.sheet, row, table.columns.get(missing), missing)
        return False
    if fields[ld] is not None and total is not None and abs(fields[ld] + fields[hd] - total) > 0.005 * total:
        problems.error(f"is {total:,.0f}, but {ld} + {hd} = {fields[ld] + fields[hd]:,.0f}; give the split, the total "
                       "or both agreeing", table.sheet, row, table.columns.get(f"observed_base_gallons_{fuel}"),
                       f"observed_base_gallons_{fuel}")
        return False
    return True


def _check_cycle_mix(mix, known, workbook_dir: Path, table: _Table, row: int, problems: Problems,
                     column: str = "cycle_mix"):
    sheet, index = table.sheet, table.columns.get(column)
    resolved: dict[str, float] = {}
    ok = True
    for name, share in mix.items():
        if name.lower().endswith(".csv"):
            candidate = Path(name)
            if not candidate.is_absolute():
                candidate = workbook_dir / candidate
            if not candidate.is_file():
                problems.error(f"cycle file '{name}' not found (looked for {candidate})", sheet, row,
                               index, column)
                ok = False
                continue
            problem = _cycle_file_problem(candidate)
            if problem:
                problems.error(f"cycle file '{name}': {problem}", sheet, row, index, column)
                ok = False
                continue
            resolved[str(candidate.resolve())] = share
        elif known is not None:
            match = {k.upper(): k for k in known}.get(name.upper())
            if match is None:
                near = closest_names(name, known)
                guess = f" (did you mean {near[0]}?)" if near else ""
                problems.error(f"unknown drive cycle '{name}'{guess}; shipped: {', '.join(known)}, "
                               "or give a CSV path", sheet, row, index, column)
                ok = False
                continue
            resolved[match] = share
        else:
            resolved[name] = share
    if not ok:
        return None
    total = sum(resolved.values())
    if abs(total - 1.0) > MIX_SUM_TOLERANCE + 1e-9:   # 0.33 x 3 sums to 0.99 + 1e-17
        problems.error(f"shares add up to {total:g}, not 1 (they are shares of the annual miles)",
                       sheet, row, index, column)
        return None
    if total != 1.0:
        if abs(total - 1.0) > 1e-9:
            problems.warn(f"shares add up to {total:g}; scaled to 1", sheet, row, index, column)
        resolved = {k: v / total for k, v in resolved.items()}
    return resolved


def _cycle_file_problem(path: Path) -> str | None:
    """Why a drive-cycle CSV cannot be driven (what ``run`` would refuse), or None."""
    stat = path.stat()
    return _cycle_problem(str(path), stat.st_mtime_ns, stat.st_size)


@lru_cache(maxsize=256)
def _cycle_problem(path: str, mtime_ns: int, size: int) -> str | None:
    try:
        load_cycle(Path(path))
    except InputError as exc:
        return exc.message
    return None


def _shipped_cycle_names() -> list[str]:
    """Names of the shipped drive cycles."""
    found = shipped_cycles()
    if isinstance(found, dict):
        found = list(found)
    return [getattr(c, "name", c) for c in found]


# --- Registrations (docs/registrations.md) ------------------------------------------------

def _warn_typed_truck_mixes(parsed: dict, table: _Table, row: int, problems: Problems) -> None:
    """``cycle_mix = default`` beside a typed ``cycle_mix_MD`` / ``cycle_mix_HD`` (the template's
    example rows have them): the typed mix wins; say so, since the reader asked for defaults."""
    if parsed.get("cycle_mix") != rows.DEFAULT_MIX:
        return
    for name in ("cycle_mix_MD", "cycle_mix_HD"):
        if parsed.get(name) not in (None, rows.DEFAULT_MIX):
            problems.warn("is typed, so these trucks drive it instead of their default mix (cycle_mix is "
                          "default); empty the cell or write default for the documented GEM weighting",
                          table.sheet, row, table.columns.get(name), name)


def _default_mixes(parsed: dict) -> None:
    """``cycle_mix = default``: each duty class's documented mix (models/turnover.toml
    [cycle_mix_default]); an MD / HD mix column left empty (or ``default``) takes its class's."""
    from fleetrun.resources import model_file

    if rows.DEFAULT_MIX not in (parsed.get(name) for name in MIX_COLUMNS):
        return
    defaults = model_file("turnover.toml")["cycle_mix_default"]
    all_default = parsed.get("cycle_mix") == rows.DEFAULT_MIX
    for name, duty in (("cycle_mix", "LD"), ("cycle_mix_MD", "MD"), ("cycle_mix_HD", "HD")):
        value = parsed.get(name)
        if value == rows.DEFAULT_MIX or (value is None and all_default):
            parsed[name] = default_mix(defaults[duty])


def default_mix(text: str) -> dict[str, float]:
    """A ``[cycle_mix_default]`` entry as a mix: ``gem:<vehicle type>`` is that GEM weighting
    as its owner, models/heavy_duty/gem_cycles.toml, gives it; otherwise a CYCLE:share list."""
    from fleetrun.simulation.heavy_duty_gem import gem_cycle_mix

    if text.startswith("gem:"):
        return gem_cycle_mix(text[len("gem:"):])
    return cells.parse_cycle_mix(text)


def _check_something_to_forecast(vehicles, registrations, table: _Table, problems: Problems) -> None:
    """A fleet from registrations whose every count is 0, or whose registrations are all
    vehicles nothing in the library represents (electric: docs/registrations.md), would spread
    ``base_year_vmt_million`` over no vehicle and forecast no revenue at all (or fail writing
    its report): an error, not a report of zeros. (A Vehicles-only fleet of count 0 still runs
    to a report of zeros: tests/test_report.py.)"""
    if any(v.count > 0 for v in vehicles):
        return
    counted = [r for r in registrations if r["count"] > 0]
    if any(r.get("fuel") != "electric" or r.get("vehicle_id") for r in counted):
        return
    what = ("every registration counted is electric, which no library vehicle represents (docs/registrations.md)"
            if counted else "every count is 0")
    problems.error(f"count: {what}, and no Vehicles row has a count above 0: nothing to forecast; give the "
                   "fleet's counts (or a Vehicles row for its electric vehicles)", table.sheet)


def own_year1_miles(vehicles) -> float:
    """The Vehicles rows' own first-year miles, sum of count x annual_miles: the part of
    ``base_year_vmt_million`` the registrations do not drive (registrations.expand.FleetYears)."""
    return float(np.array([v.count * v.annual_miles for v in vehicles], dtype=float).sum())


def _check_base_vmt(scenarios, scenario_rows, vehicles, table: _Table, problems: Problems) -> None:
    """``base_year_vmt_million`` is the whole fleet's first-year miles, Vehicles rows included:
    the registrations drive what is left (registrations.expand.Expansion.year_miles), so it
    must exceed the Vehicles rows' own (count x annual_miles), or their miles and gallons would
    come out negative."""
    own = own_year1_miles(vehicles)
    for s in scenarios:
        if s.base_year_vmt_million is not None and s.base_year_vmt_million * 1e6 <= own:
            problems.error(f"{s.base_year_vmt_million:,.6g} million is not more than the Vehicles rows' own first-year "
                           f"miles ({own / 1e6:,.6g} million, count x annual_miles), so nothing is left for the "
                           "registrations; give the whole fleet's vehicle-miles (Vehicles rows included), or set "
                           "count 0 on Vehicles rows that only stand in for registrations", table.sheet,
                           scenario_rows.get(s.scenario_id), table.columns.get("base_year_vmt_million"),
                           "base_year_vmt_million")


def _check_share_classes(scenarios, scenario_rows, registrations, table: _Table, problems: Problems) -> None:
    """A class given a share of the miles (``base_year_vmt_share_pct``) needs registrations of
    it (MV-1's ``truck`` counts for the three truck classes), or its miles would vanish."""
    present = {r["vehicle_class"] for r in registrations}
    if "truck" in present:
        present |= {"light_truck", "single_unit_truck", "combination_truck"}
    for s in scenarios:
        missing = [name for name, pct in (s.base_year_vmt_share_pct or {}).items() if pct > 0 and name not in present]
        if missing:
            problems.error(f"gives a share of the miles to {', '.join(missing)}, but the Registrations sheet has "
                           f"no such vehicles; add their registrations or drop them from the list", table.sheet,
                           scenario_rows.get(s.scenario_id), table.columns.get("base_year_vmt_share_pct"),
                           "base_year_vmt_share_pct")


def _registrations(table: _Table, vehicle_rows: dict[str, int], problems: Problems) -> list[dict]:
    """The Registrations rows as typed values (``_row``: the Excel row); a ``vehicle_id``
    must name a Vehicles row."""
    found = []
    seen: dict[tuple, int] = {}   # a row's values -> the first row holding them
    for row_number, values in table.rows:
        parsed, ok = _parse_row(table, REGISTRATION_COLUMNS, row_number, values, problems)
        # every cell, the extra columns' too (two counties' rows may hold the same class and count)
        same = seen.setdefault((*(v for k, v in parsed.items() if k != "_extra"),
                                *sorted(parsed["_extra"].items())), row_number)
        if same != row_number:   # a pasted block twice: every vehicle of it counted twice
            problems.warn(f"repeats row {same} exactly; both are counted (delete one if it is a copy)",
                          table.sheet, row_number)
        if note := rows.fractional_count(parsed.get("count")):
            problems.warn(note, table.sheet, row_number, table.columns.get("count"), "count")
        vid = parsed.get("vehicle_id")
        if vid and vid not in vehicle_rows:
            problems.error(f"{cells.show(vid)} is not a vehicle_id of the Vehicles sheet", table.sheet, row_number,
                           table.columns.get("vehicle_id"), "vehicle_id")
            ok = False
        if ok:
            parsed.pop("_extra", None)
            parsed["_row"] = row_number
            found.append(parsed)
    return found
