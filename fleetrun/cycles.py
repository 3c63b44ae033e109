"""Drive cycles: the shipped EPA/regulatory speed schedules and user CSVs.

A drive cycle is a speed trace ``speed_mps`` [m/s] against time ``time_s`` [s], with road grade
``grade_pct`` [%] (rise/run x 100, positive uphill; zeros when the source has none).

Shipped cycles live in ``inputs/cycles/<NAME>.csv`` (header ``time_s,speed_mps[,grade_pct]``);
their sources, unit conversions and checked durations/distances are in
``inputs/cycles/PROVENANCE.md``:

- ``UDDS``, ``HWFET``, ``US06``, ``WLTC`` (class 3b) from fastsim 2.1.5 (NREL, Apache-2.0);
- ``NYCC``, ``HD-UDDS`` (EPA UDDSHDV) from the EPA schedules embedded in zahner_potentiostat
  1.1.2 (MIT), converted from mph.
- ``ARB-TRANSIENT`` (GEM's transient cycle, CARB HHDDT transient mode) from NREL T3CO
  (BSD-3-Clause), as are ``CRUISE-55-GRADE``, ``CRUISE-65-GRADE`` (GEM's cruise cycles over
  the regulatory grade profile); ``CRUISE-55``, ``CRUISE-65`` (level) written by ``make_cruise.py``.

A *composed* cycle (``inputs/cycles/<NAME>.toml``; ``FTP``) joins parts of shipped schedules
into named phases with engine-off soaks between them (:class:`CyclePhase`); its fuel economy
is a weighted composite of the phases (:func:`composite_fuel_per_mile`, EPA's bag weighting
for the FTP).

A user cycle is a CSV with ``time_s`` and exactly one speed column (``vehicle_speed_kph``,
``vehicle_speed_mph``, ``vehicle_speed_mps``, ``speed_mps``, ``speed_kph`` or ``speed_mph``) and
an optional ``grade_pct``; other columns are ignored, so a vehicle-level recording
(docs/interface.md, "Recordings") loads as its own drive cycle. Time steps may be uneven
(:func:`resample` puts a cycle on an even grid). Errors are :class:`fleetrun.errors.InputError`
with the file, the row as a spreadsheet shows it (header = row 1), the column and the value.
"""
from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd

from fleetrun import plausible
from fleetrun.errors import FleetrunError, InputError, unknown_name_error
from fleetrun.fileio import refuse_unreadable_size
from fleetrun.resources import inputs_dir
from fleetrun.plausible import MAX_CYCLE_BYTES, MAX_CYCLE_ROWS
from fleetrun.units import METERS_PER_MILE

MPH_TO_MPS = 0.44704       # 1 mph in m/s, exact
KPH_TO_MPS = 1.0 / 3.6     # 1 km/h in m/s, exact

# The first cycles `shipped_cycles()` lists, in this order (docs/interface.md); others follow by name.
PRIMARY_CYCLES = ("UDDS", "HWFET", "US06", "NYCC", "HD-UDDS")

# Accepted speed columns -> factor to m/s.
SPEED_COLUMNS = {
    "vehicle_speed_kph": KPH_TO_MPS,
    "vehicle_speed_mph": MPH_TO_MPS,
    "vehicle_speed_mps": 1.0,
    "speed_mps": 1.0,
    "speed_kph": KPH_TO_MPS,
    "speed_mph": MPH_TO_MPS,
}
TIME_COLUMN = "time_s"
GRADE_COLUMN = "grade_pct"


@dataclass(frozen=True)
class CyclePhase:
    """A named part of a composed cycle (an FTP "bag"), on the cycle's own time axis.

    The phase holds the steps that lie within [``start_s``, ``end_s``] [s] (step i covers
    [t(i-1), t(i)]). ``soak_before_s`` [s]: engine-off time before the phase starts; ``inf`` is
    a cold start after a full soak to ambient, 0 that the engine runs on from the phase before.
    Steps that lie in no phase are the engine-off soaks (40 CFR 86.135-12(a): the FTP's hot
    start follows the end of the cold start test by 10 minutes).
    """

    name: str
    start_s: float
    end_s: float
    soak_before_s: float = 0.0


@dataclass(frozen=True, eq=False)
class DriveCycle:
    """A speed schedule.

    ``time_s`` [s] strictly increasing (need not start at 0 or be evenly spaced),
    ``speed_mps`` [m/s] >= 0, ``grade_pct`` [%]; all 1-D float arrays of the same length >= 2,
    stored read-only. ``phases``: the :class:`CyclePhase` parts of a composed cycle (empty for
    a plain schedule, which is driven with a warm engine, as EPA's HWFET and US06 are after
    their preconditioning); ``composite``: the rule that weights the phases' fuel (a key of
    :data:`COMPOSITE_RULES`; "" = fuel per mile of the whole cycle).
    """

    name: str
    time_s: np.ndarray
    speed_mps: np.ndarray
    grade_pct: np.ndarray
    phases: tuple = ()
    composite: str = ""

    def __post_init__(self):
        arrays = {}
        for field_name in ("time_s", "speed_mps", "grade_pct"):
            a = np.array(getattr(self, field_name), dtype=float)  # a private copy
            if a.ndim != 1:
                raise ValueError(f"DriveCycle.{field_name} must be 1-D, got shape {a.shape}")
            a.setflags(write=False)
            arrays[field_name] = a
        n = {len(a) for a in arrays.values()}
        if len(n) != 1:
            raise ValueError("DriveCycle arrays must have the same length: "
                             + ", ".join(f"{k}={len(v)}" for k, v in arrays.items()))
        for k, v in arrays.items():
            object.__setattr__(self, k, v)

    @property
    def duration_s(self) -> float:
        """Last time minus first time [s]."""
        return float(self.time_s[-1] - self.time_s[0])

    @property
    def distance_m(self) -> float:
        """Distance driven [m]: trapezoidal integral of speed over time.

        For the 1 Hz EPA schedules, which start and end at rest, this equals the plain sum of
        speed x 1 s that EPA's published distances use.
        """
        dt = np.diff(self.time_s)
        return float(np.sum(0.5 * (self.speed_mps[1:] + self.speed_mps[:-1]) * dt))

    @property
    def miles(self) -> float:
        """Distance driven [mi] (international mile, 1609.344 m)."""
        return self.distance_m / METERS_PER_MILE

    @property
    def max_speed_mps(self) -> float:
        """Highest speed [m/s]."""
        return float(np.max(self.speed_mps))

    @property
    def mean_speed_mps(self) -> float:
        """Average speed including stops [m/s]: distance / duration (EPA's 'average speed')."""
        return self.distance_m / self.duration_s if self.duration_s > 0 else 0.0

    def step_phase(self) -> np.ndarray:
        """Index into ``phases`` of each step (N,): -1 for a step in no phase (an engine-off
        soak). Step 0 (no time) belongs to the first phase; all 0 for a plain cycle."""
        t = self.time_s
        index = np.zeros(t.size, dtype=np.intp)
        if not self.phases:
            return index
        index[1:] = -1
        tol = 1e-9 * max(1.0, float(np.max(np.abs(t))))
        for k, phase in enumerate(self.phases):
            inside = (t[:-1] >= phase.start_s - tol) & (t[1:] <= phase.end_s + tol)
            index[1:][inside] = k
        return index

    def engine_off_steps(self) -> np.ndarray:
        """Steps (N,) of the engine-off soaks between phases (bool)."""
        return self.step_phase() < 0

    def __repr__(self) -> str:
        return (f"DriveCycle({self.name!r}, {len(self.time_s)} points, "
                f"{self.duration_s:g} s, {self.miles:.3f} mi)")


# ----------------------------------------------------------------------------- shipped cycles

def _cycles_dir() -> Path:
    return inputs_dir() / "cycles"


def _norm(name: str) -> str:
    """Case-insensitive, '-' and '_' interchangeable."""
    return name.strip().upper().replace("_", "-")


def _shipped_files() -> dict[str, Path]:
    try:
        folder = _cycles_dir()
    except FileNotFoundError as exc:
        raise FleetrunError(f"the shipped drive cycles are missing ({exc})",
                            hint="Reinstall fleetrun; its inputs/cycles data folder "
                                 "was not installed") from None
    if not folder.is_dir():
        raise FleetrunError("the shipped drive cycles are missing", file=folder,
                            hint="Reinstall fleetrun; its inputs/cycles data folder "
                                 "was not installed")
    found = {p.stem: p for p in folder.glob("*.toml")}   # composed cycles (FTP)
    found.update({p.stem: p for p in folder.glob("*.csv")})
    return found


def shipped_cycles() -> list[str]:
    """Names of the shipped cycles: UDDS, HWFET, US06, NYCC, HD-UDDS first, then the others
    in alphabetical order.

    Returns
    -------
    list of str, the cycle names.
    """
    names = list(_shipped_files())
    first = [n for n in PRIMARY_CYCLES if n in names]
    rest = sorted((n for n in names if n not in PRIMARY_CYCLES), key=str.upper)
    return first + rest


def _looks_like_path(text: str) -> bool:
    return (os.sep in text or (os.altsep and os.altsep in text) or "/" in text
            or Path(text).suffix != "")


def load_cycle(name_or_path) -> DriveCycle:
    """A shipped cycle by name (case-insensitive, '-'/'_' interchangeable) or a CSV file.

    A :class:`pathlib.Path`, or a string that contains a path separator or has a file
    extension, is read as a file; any other string is looked up among :func:`shipped_cycles`
    (and, failing that, read as a file if one of that name exists).

    Parameters
    ----------
    name_or_path : str or os.PathLike, a shipped name (``fleetrun cycles``) or a CSV file with
        ``time_s`` [s], one speed column (m/s, km/h or mph by its name) and optional
        ``grade_pct`` [%]

    Returns
    -------
    :class:`DriveCycle` (speeds in m/s)

    >>> udds = load_cycle("udds")
    >>> udds.name, udds.duration_s, round(udds.miles, 2)
    ('UDDS', 1369.0, 7.45)
    """
    if isinstance(name_or_path, DriveCycle):
        return name_or_path
    if isinstance(name_or_path, os.PathLike):
        return _read_cycle_file(Path(name_or_path))
    if not isinstance(name_or_path, str):
        raise InputError(f"a drive cycle is a shipped name or a CSV path, "
                         f"not {type(name_or_path).__name__}", value=name_or_path)
    text = name_or_path.strip()
    if not text:
        raise unknown_name_error("drive cycle", name_or_path, shipped_cycles(),
                                 hint="Give a shipped cycle name or the path of a CSV file")
    if _looks_like_path(text):
        return _read_cycle_file(Path(text))
    files = _shipped_files()
    by_norm = {_norm(n): n for n in files}
    if _norm(text) in by_norm:
        name = by_norm[_norm(text)]
        return _shipped_cycle(files[name], name)
    if Path(text).is_file():
        return read_cycle_csv(Path(text))
    raise unknown_name_error(
        "drive cycle", text, shipped_cycles(),
        hint="Names are case-insensitive; or give the path of a CSV file with time_s and "
             "one speed column (e.g. speed_mps)")


@lru_cache(maxsize=64)
def _shipped_cycle(path: Path, name: str) -> DriveCycle:
    """A shipped cycle, read once per process (a DriveCycle's arrays are read-only)."""
    return _read_cycle_file(path, name=name)


def _read_cycle_file(path: Path, name: str | None = None) -> DriveCycle:
    """A composed cycle (.toml) or a schedule CSV."""
    if path.suffix.lower() == ".toml":
        return read_composed_cycle(path, name=name)
    return read_cycle_csv(path, name=name)


# ----------------------------------------------------------------------------- composed cycles

def ftp_weighted_per_mile(bag1, bag2, bag3, miles1, miles2, miles3):
    """EPA's FTP weighting of the three bags: an amount per mile (fuel [g or gal] per mile).

    40 CFR 86.144-94(a): ``Y_wm = 0.43 (Y_ct + Y_s) / (D_ct + D_s) + 0.57 (Y_ht + Y_s) /
    (D_ht + D_s)`` with Y the bag's mass (ct = cold transient, bag 1; s = stabilised, bag 2;
    ht = hot transient, bag 3) and D its measured distance [mi]. 40 CFR 600.113 computes the
    city fuel economy from these weighted grams per mile (carbon balance), so the weighting
    applies to fuel per mile, not to mpg: composite mpg = 1 / (weighted gallons per mile).
    Works element-wise on arrays (one value per vehicle).

    Parameters
    ----------
    bag1, bag2, bag3 : float or array, the bags' amounts (fuel [g] or [gal])
    miles1, miles2, miles3 : float or array, the bags' distances [mi]

    Returns
    -------
    amount per mile (the unit of the bags per mi)

    >>> round(ftp_weighted_per_mile(100.0, 150.0, 90.0, 3.6, 3.9, 3.6), 4)
    32.5733
    """
    return (FTP_TRANSIENT_WEIGHT * (bag1 + bag2) / (miles1 + miles2)
            + FTP_HOT_WEIGHT * (bag3 + bag2) / (miles3 + miles2))


#: 40 CFR 86.144-94(a): the weights of the cold-start (bags 1 + 2) and hot-start (bags 3 + 2)
#: halves of the FTP in :func:`ftp_weighted_per_mile`
FTP_TRANSIENT_WEIGHT = 0.43
FTP_HOT_WEIGHT = 0.57


def ftp_bag1_end_s() -> float:
    """End of FTP bag 1 [s] on the UDDS schedule: the first 505 s (40 CFR 86.135-12(a)), as
    the shipped FTP rule (inputs/cycles/FTP.toml) sets it; bag 2 is the rest of the UDDS.

    Returns
    -------
    float, end of bag 1 [s].

    >>> ftp_bag1_end_s()
    505.0
    """
    return float(load_cycle("FTP").phases[0].end_s)


#: Composite rules by name: (phase names in the rule's argument order, function).
COMPOSITE_RULES = {"ftp": (("bag1", "bag2", "bag3"), ftp_weighted_per_mile)}


def composite_per_mile(rule: str, amounts: dict, miles: dict):
    """An amount per mile over a composed cycle's phases: ``amounts`` and ``miles`` map phase
    names to values (arrays over vehicles). ``rule`` "" = total amount / total miles; otherwise
    the :data:`COMPOSITE_RULES` entry (the FTP: :func:`ftp_weighted_per_mile`).

    Parameters
    ----------
    rule : str, a :data:`COMPOSITE_RULES` name, or "" for total / total
    amounts : dict, phase name -> amount per vehicle (e.g. fuel [g])
    miles : dict, phase name -> miles driven per vehicle [mi]

    Returns
    -------
    amount per mile [amount/mi], an array over vehicles.
    """
    if not rule:
        return sum(amounts.values()) / sum(miles.values())
    names, weighting = COMPOSITE_RULES[rule]
    return weighting(*(amounts[n] for n in names), *(miles[n] for n in names))


def read_composed_cycle(path, name: str | None = None) -> DriveCycle:
    """A composed cycle from its TOML (``inputs/cycles/FTP.toml`` documents the keys): the
    phases' parts of shipped schedules joined on one time axis, soaks as engine-off gaps.

    Parameters
    ----------
    path : str or Path, the composed cycle's TOML file
    name : str or None, the cycle's name (None: the file stem)

    Returns
    -------
    DriveCycle, with its phases, soaks and composite rule.
    """
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            spec = tomllib.load(fh)
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"cannot read the composed drive cycle ({exc})", file=path,
                         hint="Fix the TOML file") from None
    rule = spec.get("composite", "")
    if rule and rule not in COMPOSITE_RULES:
        raise unknown_name_error("composite rule", rule, list(COMPOSITE_RULES))
    specs = spec.get("phase") or []
    if not specs:
        raise InputError("a composed drive cycle needs at least one [[phase]]", file=path,
                         hint="Add [[phase]] tables with name, cycle, start_s, end_s")
    parts, phases, end = [], [], 0.0
    for k, ph in enumerate(specs):
        t, v, g, phase = _phase_part(path, ph, end, first=(k == 0))
        parts.append((t, v, g))
        phases.append(phase)
        end = phase.end_s
    t, v, g = (np.concatenate([p[i] for p in parts]) for i in range(3))
    return DriveCycle(name=name or path.stem, time_s=t, speed_mps=v, grade_pct=g,
                      phases=tuple(phases), composite=rule)


def _phase_part(path, ph: dict, previous_end_s: float, first: bool):
    """One phase's samples on the composed time axis, and its CyclePhase."""
    try:
        name, base = str(ph["name"]), load_cycle(str(ph["cycle"]))
        start, stop, soak = float(ph["start_s"]), float(ph["end_s"]), float(ph.get("soak_before_s", 0.0))
    except KeyError as exc:
        raise InputError(f"a [[phase]] lacks the key {exc}", file=path,
                         hint="Each phase needs name, cycle, start_s and end_s") from None
    sel = (base.time_s >= start - 1e-9) & (base.time_s <= stop + 1e-9)
    if sel.sum() < 2 or not soak >= 0:
        raise InputError(f"phase '{name}': {start:g}-{stop:g} s of {base.name} holds no step, "
                         f"or soak_before_s = {soak:g} is negative", file=path)
    t, v, g = base.time_s[sel], base.speed_mps[sel], base.grade_pct[sel]
    if first:
        offset = -t[0]
    elif soak == 0:  # the engine runs on: this phase's first sample is the last one before
        offset = previous_end_s - t[0]
        t, v, g = t[1:], v[1:], g[1:]
    else:  # the soak is one engine-off step at rest
        if v[0] != 0:
            raise InputError(f"phase '{name}' follows a soak but does not start at rest", file=path)
        offset = previous_end_s + soak - t[0]
    t = t + offset
    return t, v, g, CyclePhase(name, float(t[0] if first or soak else previous_end_s), float(t[-1]), soak)


# ----------------------------------------------------------------------------- CSV reading

def read_cycle_csv(path, name: str | None = None) -> DriveCycle:
    """Read and validate a drive-cycle CSV (see the module docstring for the columns).

    ``name`` defaults to the file stem. Raises :class:`InputError` naming the file, row
    (header = row 1), column and offending value.

    Parameters
    ----------
    path : str or Path, the drive-cycle CSV
    name : str or None, the cycle's name (None: the file stem)

    Returns
    -------
    DriveCycle, time [s], speed [m/s] and grade [%] per row.
    """
    path = Path(path)
    df = _read_csv_cells(path)
    df, rows = _without_trailing_blank_rows(df, path)
    speed_col = _speed_column(df, path)
    if len(df) < 2:
        raise InputError(f"a drive cycle needs at least 2 data rows, found {len(df)}",
                         file=path, hint="Give the speed at two or more times")

    t = _numeric(df, TIME_COLUMN, rows, path)
    v = _numeric(df, speed_col, rows, path) * SPEED_COLUMNS[speed_col]
    g = (_numeric(df, GRADE_COLUMN, rows, path) if GRADE_COLUMN in df.columns
         else np.zeros(len(df)))

    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise InputError(
            f"time must strictly increase: {TIME_COLUMN} = {_cell_text(df[TIME_COLUMN].iloc[i])} "
            f"follows {_cell_text(df[TIME_COLUMN].iloc[i - 1])} in row {int(rows[i - 1])}",
            file=path, row=int(rows[i]), column=TIME_COLUMN,
            value=_cell_text(df[TIME_COLUMN].iloc[i]),
            hint="Sort the rows by time and remove repeated times")
    neg = np.flatnonzero(v < 0)
    if neg.size:
        i = int(neg[0])
        raise InputError(f"negative speed in column '{speed_col}': {_cell_text(df[speed_col].iloc[i])}",
                         file=path, row=int(rows[i]), column=speed_col,
                         value=_cell_text(df[speed_col].iloc[i]),
                         hint="Speeds must be >= 0; replace reversing or sensor noise by 0")
    _check_plausible(path, t, v, g, rows, speed_col)
    return DriveCycle(name=name or path.stem, time_s=t, speed_mps=v, grade_pct=g)


def _check_plausible(path: Path, t, v, g, rows, speed_col: str) -> None:
    """Units off by 1000 and a cycle that never moves (which ``run`` could not drive) are
    errors here, so ``validate`` refuses them too (limits: :mod:`fleetrun.plausible`)."""
    plausible.check_speed(v, file=path, column=speed_col, rows=rows)
    plausible.check_grade(g, file=path, column=GRADE_COLUMN, rows=rows)
    plausible.check_time_steps(t, file=path, column=TIME_COLUMN, rows=rows)
    if not np.any(v > 0):
        raise InputError("every speed is 0: the cycle never moves, so it has no miles to give fuel "
                         "per mile for", file=path, column=speed_col,
                         hint="Give a cycle that drives (or leave it out of the cycle mix)")


def _check_size(path: Path) -> None:
    refuse_unreadable_size(path, MAX_CYCLE_BYTES, "drive cycles", "Give the path of a .csv file",
                           "Resample the cycle to 1 Hz or split it")


def _read_csv_cells(path: Path):
    """The CSV's cells as text (pandas DataFrame, stripped column names); InputError for a
    missing file, a folder, another extension, binary content, an undecodable or ragged file."""
    if not path.exists():
        raise InputError("drive-cycle file not found", file=path,
                         hint="Check the path, or run `fleetrun cycles` for the shipped names")
    if path.is_dir():
        raise InputError("is a folder, not a CSV file", file=path,
                         hint="Give the path of a .csv file")
    if path.suffix.lower() != ".csv":
        raise InputError(f"not a CSV file (extension '{path.suffix}')", file=path,
                         hint="Save the drive cycle as .csv with a header row "
                              "time_s,speed_mps[,grade_pct]")
    _check_size(path)
    with open(path, "rb") as fh:
        head = fh.read(8192)
    if b"\x00" in head:
        raise InputError("not a CSV file (binary content; a spreadsheet saved under .csv?)",
                         file=path, hint="Save the drive cycle as CSV text with a header row "
                                         "time_s,speed_mps[,grade_pct]")
    try:
        # UTF-8 (with or without BOM); Excel's default "CSV" on Windows is cp1252
        try:
            df = pd.read_csv(path, dtype=str, keep_default_na=False, skip_blank_lines=False,
                             encoding="utf-8-sig", nrows=MAX_CYCLE_ROWS + 1)
        except UnicodeDecodeError:
            df = pd.read_csv(path, dtype=str, keep_default_na=False, skip_blank_lines=False,
                             encoding="cp1252", nrows=MAX_CYCLE_ROWS + 1)
    except UnicodeDecodeError:
        raise InputError("not a text CSV file (cannot decode as UTF-8 or Windows-1252)",
                         file=path, hint="Save the drive cycle as a UTF-8 CSV") from None
    except pd.errors.EmptyDataError:
        raise InputError("the file is empty", file=path,
                         hint="Give a header row time_s,speed_mps and at least two data rows"
                         ) from None
    except pd.errors.ParserError as exc:
        raise InputError(f"not a readable CSV ({str(exc).strip()})", file=path,
                         hint="Check that every row has the same number of comma-separated "
                              "fields as the header") from None
    if len(df) > MAX_CYCLE_ROWS:
        raise InputError(f"has more than {MAX_CYCLE_ROWS:,} rows; fleetrun reads drive cycles up to "
                         f"{MAX_CYCLE_ROWS:,} rows", file=path, row=MAX_CYCLE_ROWS + 2,
                         hint="Resample the cycle to 1 Hz or split it")
    df.columns = [str(c).strip() for c in df.columns]
    return df


def _without_trailing_blank_rows(df, path: Path):
    """Drop fully blank lines at the end of the file (blank lines inside are errors); returns
    the rows and their numbers as a spreadsheet shows them (header row 1, first data row 2)."""
    rows = np.arange(len(df)) + 2
    blank = np.array([all(_cell_text(v) == "" for v in rec) for rec in df.itertuples(index=False)],
                     dtype=bool) if len(df) else np.zeros(0, dtype=bool)
    keep = len(df)
    while keep > 0 and blank[keep - 1]:
        keep -= 1
    df, rows, blank = df.iloc[:keep], rows[:keep], blank[:keep]
    if blank.any():
        r = int(rows[np.argmax(blank)])
        raise InputError("empty row inside the data", file=path, row=r,
                         hint="Delete the empty row")
    return df, rows


def _speed_column(df, path: Path) -> str:
    """The one speed column (after checking the time column is there)."""
    if TIME_COLUMN not in df.columns:
        raise InputError(f"no '{TIME_COLUMN}' column (found: {', '.join(df.columns)})",
                         file=path, row=1, column=TIME_COLUMN,
                         hint="The header needs time_s and one speed column, "
                              "e.g. time_s,speed_mps")
    speed_cols = [c for c in df.columns if c in SPEED_COLUMNS]
    if not speed_cols:
        raise InputError(f"no speed column (found: {', '.join(df.columns)})", file=path, row=1,
                         hint="Add exactly one of " + ", ".join(SPEED_COLUMNS))
    if len(speed_cols) > 1:
        raise InputError(f"more than one speed column ({', '.join(speed_cols)}); "
                         "which one to use is ambiguous", file=path, row=1,
                         column=speed_cols[1],
                         hint="Keep exactly one of " + ", ".join(SPEED_COLUMNS))
    return speed_cols[0]


def _cell_text(value) -> str:
    """A cell as stripped text; a missing cell (short row) is ''."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    return str(value).strip()


def _numeric(df, column: str, rows, path) -> np.ndarray:
    """Column ``column`` as finite floats, or an InputError at the first bad cell."""
    text = [_cell_text(v) for v in df[column]]
    out = np.empty(len(text))
    for i, s in enumerate(text):
        if s == "":
            raise InputError(f"empty cell in column '{column}'", file=path, row=int(rows[i]),
                             column=column, value="",
                             hint="Fill in a number")
        try:
            x = float(s)
        except ValueError:
            raise InputError(f"not a number in column '{column}': '{s}'", file=path,
                             row=int(rows[i]), column=column, value=s,
                             hint="Use plain numbers with '.' as decimal separator") from None
        if math.isnan(x):
            raise InputError(f"NaN in column '{column}'", file=path, row=int(rows[i]),
                             column=column, value=s, hint="Replace the NaN by a number")
        if math.isinf(x):
            raise InputError(f"infinite value in column '{column}': '{s}'", file=path,
                             row=int(rows[i]), column=column, value=s,
                             hint="Replace it by a finite number")
        out[i] = x
    return out


# ----------------------------------------------------------------------------- resampling

def resample(cycle: DriveCycle, dt_s: float = 1.0) -> DriveCycle:
    """``cycle`` on an even time grid ``t0, t0 + dt_s, ...`` [s], linear interpolation.

    The grid ends at the last grid point not after the cycle's end (to within 1e-9 s), so a
    final stretch shorter than ``dt_s`` is dropped; speed and grade are interpolated linearly.

    Parameters
    ----------
    cycle : :class:`DriveCycle`
    dt_s : float, the grid step [s]

    Returns
    -------
    :class:`DriveCycle` on the even grid, with the same phases and composite rule

    >>> resample(load_cycle("UDDS"), 0.5).time_s[:3].tolist()
    [0.0, 0.5, 1.0]
    """
    dt_s = float(dt_s)
    if not math.isfinite(dt_s) or dt_s <= 0:
        raise InputError(f"resampling step must be a positive number of seconds, got {dt_s:g}",
                         value=dt_s, hint="Use e.g. dt_s=1.0")
    t0, t1 = float(cycle.time_s[0]), float(cycle.time_s[-1])
    n = int(math.floor((t1 - t0) / dt_s + 1e-9)) + 1
    if n < 2:
        raise InputError(f"resampling step {dt_s:g} s is longer than the cycle "
                         f"({t1 - t0:g} s)", value=dt_s, hint="Use a shorter step")
    t = t0 + dt_s * np.arange(n)
    t[-1] = min(t[-1], t1)  # guard the last point against rounding past the end
    v = np.interp(t, cycle.time_s, cycle.speed_mps)
    g = np.interp(t, cycle.time_s, cycle.grade_pct)
    return DriveCycle(name=cycle.name, time_s=t, speed_mps=v, grade_pct=g, phases=cycle.phases,
                      composite=cycle.composite)


def cycle_summary(cycle: DriveCycle) -> dict:
    """Name, duration [s], distance [mi, km], max and mean speed [mph, km/h] of a cycle.

    Parameters
    ----------
    cycle : DriveCycle, a drive cycle

    Returns
    -------
    dict, ``name``, ``duration_s`` [s], ``distance_mi`` [mi], ``distance_km`` [km],
    ``max_speed_mph``/``mean_speed_mph`` [mph], ``max_speed_kph``/``mean_speed_kph`` [km/h].
    """
    return {
        "name": cycle.name,
        "duration_s": cycle.duration_s,
        "distance_mi": cycle.miles,
        "distance_km": cycle.distance_m / 1000.0,
        "max_speed_mph": cycle.max_speed_mps / MPH_TO_MPS,
        "mean_speed_mph": cycle.mean_speed_mps / MPH_TO_MPS,
        "max_speed_kph": cycle.max_speed_mps * 3.6,
        "mean_speed_kph": cycle.mean_speed_mps * 3.6,
    }
