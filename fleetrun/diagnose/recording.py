"""Reading and checking recordings for ``fleetrun diagnose`` (docs/interface.md, "Recordings").

A recording is a CSV (units in the column names) plus a TOML sidecar with the same stem (or
``--meta FILE``). Every problem is an :class:`fleetrun.errors.InputError` naming the file,
the row as a spreadsheet shows it (header = row 1), the column and the value.
"""
from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np
import pandas as pd

from fleetrun.cycles import SPEED_COLUMNS
from fleetrun.differential import canonical_configuration
from fleetrun import plausible
from fleetrun.errors import InputError
from fleetrun.fileio import JsonDocument
from fleetrun.physics.fuels import fuel_table
from fleetrun.workbook.cells import CellProblem
from fleetrun.workbook.rows import parse_value
from fleetrun.workbook.schema import SIDECAR_COLUMNS

DIFF_REQUIRED = ("time_s", "diff_input_torque_Nm", "diff_input_speed_rpm")
DIFF_OPTIONAL = ("diff_output_torque_Nm", "axle_torque_left_Nm", "axle_torque_right_Nm",
                 "wheel_speed_left_rpm", "wheel_speed_right_rpm", "ambient_temp_C", "oil_temp_C",
                 "vehicle_speed_kph")
DIFF_META_REQUIRED = ("configuration", "gear_ratio", "peak_engine_torque_Nm",
                      "torque_converter_ratio", "max_transmission_gear_ratio")
#: Vehicle speed columns -> factor to m/s (the drive cycles' own factors, fleetrun.cycles).
VEHICLE_SPEEDS = {c: SPEED_COLUMNS[c] for c in ("vehicle_speed_kph", "vehicle_speed_mph", "vehicle_speed_mps")}
FUEL_RATES = ("fuel_rate_g_per_s", "fuel_rate_cc_per_s")
#: Fuel densities [g/cm^3 = kg/L] for converting fuel_rate_cc_per_s (models/fuels.toml).
FUEL_DENSITY_G_PER_CC = {name: f.density_kg_per_L for name, f in fuel_table().items()}
#: A time step this many times the median step is a gap, not jitter.
GAP_FACTOR = 10.0

# Channel names a user might write with other units: -> (expected column, conversion hint)
_UNIT_ALIASES = {
    r"^time(_ms)?$|^t$|^time_min$|^timestamp$": ("time_s", "time in seconds"),
    r"^diff_input_torque_(lbft|ftlb|lbf_ft|kNm)$": ("diff_input_torque_Nm", "torque in N m"),
    r"^diff_output_torque_(lbft|ftlb|lbf_ft|kNm)$": ("diff_output_torque_Nm", "torque in N m"),
    r"^diff_input_speed_(rad_s|rads|rad_per_s|hz)$": ("diff_input_speed_rpm", "speed in rpm"),
    r"^wheel_speed_(left|right)_(rad_s|rads|hz)$": ("wheel_speed_<side>_rpm", "speed in rpm"),
    r"^vehicle_speed_(kmh|km_h|kmph)$": ("vehicle_speed_kph", "km/h (the same numbers)"),
    r"^(ambient|oil)_temp_(F|K)$": ("<name>_temp_C", "temperature in deg C"),
    r"^fuel_rate_(g_s|gps|kg_h|l_h|ml_s)$": ("fuel_rate_g_per_s or fuel_rate_cc_per_s", "g/s or cm^3/s"),
}


@dataclass(frozen=True)
class Sidecar:
    """The keys diagnose reads from a recording's sidecar TOML (docs/interface.md, Recordings);
    None: not in the file. Differential level: the configuration and the thesis' Kim torque
    scale inputs, checked against the ranges of the Vehicles columns they mean
    (``SIDECAR_COLUMNS``); vehicle level: the file is one Vehicles row (read as such by
    :func:`fleetrun.workbook.vehicle_file.read_vehicle_toml`), of which the fuel and the
    ambient temperature are read here. Other keys are not read."""

    configuration: str | None = None
    gear_ratio: float | None = None
    peak_engine_torque_Nm: float | None = None
    torque_converter_ratio: float | None = None
    max_transmission_gear_ratio: float | None = None
    low_gear_ratio: float | None = None
    axle_gear: str = "high"
    lubricant: str | None = None
    ambient_temp_C: float | None = None
    fuel: str = "gasoline"

    @classmethod
    def from_toml(cls, document: JsonDocument, level: str, meta_path: Path | None = None) -> "Sidecar":
        """The sidecar of a TOML document (checked values, as :func:`load_recording` leaves them)
        of a ``level`` recording."""
        known = {f.name for f in fields(cls)} if level == "differential" else {"fuel", "ambient_temp_C"}
        values = {k: v for k, v in document.items() if k in known}
        if "fuel" in values:
            values["fuel"] = str(values["fuel"])
        ambient = values.get("ambient_temp_C")
        if ambient is not None and not isinstance(ambient, (int, float)):
            try:
                values["ambient_temp_C"] = float(ambient)
            except (TypeError, ValueError):
                raise InputError("sidecar key ambient_temp_C must be a number", file=meta_path,
                                 column="ambient_temp_C", value=ambient) from None
        return cls(**values)


@dataclass
class Recording:
    """A checked recording on a uniform time grid."""

    path: Path
    level: str                 # "differential" or "vehicle"
    data: pd.DataFrame         # uniform time grid; vehicle level adds vehicle_speed_mps, fuel_rate_g_per_s
    meta: Sidecar
    meta_path: Path | None
    dt_s: float
    resampled: bool = False
    notes: list[str] = field(default_factory=list)

    @property
    def stem(self) -> str:
        return self.path.stem

    def has(self, column: str) -> bool:
        return column in self.data.columns


def _read_sidecar(path: Path, meta: str | Path | None = None) -> tuple[JsonDocument, Path]:
    """The sidecar TOML's content and path (``meta``, else the recording's stem with .toml)."""
    meta_path = Path(meta) if meta else path.with_suffix(".toml")
    if not meta_path.is_file():
        hint = ("Check the --meta path" if meta else
                f"Write {meta_path.name} next to {path.name} (same stem) or pass --meta FILE")
        raise InputError("sidecar TOML not found", file=meta_path, hint=hint)
    try:
        with open(meta_path, "rb") as fh:
            return tomllib.load(fh), meta_path
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not a valid TOML file ({exc})", file=meta_path) from None
    except UnicodeDecodeError as exc:
        raise InputError(f"is not UTF-8 text (byte {exc.object[exc.start]:#04x} at position {exc.start})",
                         file=meta_path, hint="Save the sidecar as UTF-8") from None


def _check_sidecar_numbers(sidecar: JsonDocument, meta_path: Path) -> None:
    """Every differential-level sidecar value within the range its Vehicles/Scenarios column
    has (fleetrun.workbook.schema.SIDECAR_COLUMNS); InputError naming the file and key."""

    for column in SIDECAR_COLUMNS:
        value = sidecar.get(column.name)
        if value is None:
            continue
        try:
            sidecar[column.name] = parse_value(column, value)
        except CellProblem as problem:
            raise InputError(str(problem), file=meta_path, column=column.name, value=value) from None
        if column.kind == "ratios":
            sidecar[column.name] = max(sidecar[column.name])


MAX_HEADER_CHARS = 65_536


def _check_header(path: Path) -> None:
    """Refuse a header line longer than MAX_HEADER_CHARS before pandas reads it."""
    with open(path, "rb") as handle:
        head = handle.readline(MAX_HEADER_CHARS + 1)
    if len(head) > MAX_HEADER_CHARS and not head.endswith(b"\n"):
        raise InputError(f"the header line is longer than {MAX_HEADER_CHARS:,} characters "
                         f"(it starts {head[:60].decode('utf-8', 'replace')!r}...)", file=path,
                         hint="A recording's header names its columns (docs/interface.md, Recordings)")


def _shown(columns, limit: int = 20) -> str:
    """Column names for a message: each cut to 60 characters, at most ``limit`` of them."""
    names = [c if len(c) <= 60 else c[:57] + "..." for c in columns[:limit]]
    return ", ".join(names) + (f" and {len(columns) - limit} more" if len(columns) > limit else "")


def _check_units(path: Path, columns) -> None:
    for col in columns:
        for pattern, (expected, what) in _UNIT_ALIASES.items():
            if re.match(pattern, col, flags=re.IGNORECASE) and col not in (
                    DIFF_REQUIRED + DIFF_OPTIONAL + tuple(VEHICLE_SPEEDS) + FUEL_RATES):
                raise InputError(f"column '{col}' has units fleetrun does not read",
                                 file=path, column=col,
                                 hint=f"Convert it to {what} and name the column '{expected}' "
                                      "(docs/interface.md, Recordings)")


def _level(path: Path, columns) -> str:
    cols = set(columns)
    if "diff_input_torque_Nm" in cols or "diff_input_speed_rpm" in cols or "diff_output_torque_Nm" in cols:
        return "differential"
    if cols & set(VEHICLE_SPEEDS) or cols & set(FUEL_RATES):
        return "vehicle"
    raise InputError("cannot tell the recording level from its columns "
                     f"({_shown(columns)})", file=path,
                     hint="A differential-level recording needs time_s, diff_input_torque_Nm, "
                          "diff_input_speed_rpm and diff_output_torque_Nm; a vehicle-level one "
                          "needs time_s, a vehicle_speed_* and a fuel_rate_* column")


def _require(path, columns, needed, level):
    missing = [c for c in needed if c not in columns]
    if missing:
        raise InputError(f"missing column{'s' if len(missing) > 1 else ''} "
                         f"{', '.join(missing)} for a {level}-level recording",
                         file=path, column=missing[0],
                         hint=f"Columns present: {_shown(columns)}")


def _check_numbers(path: Path, df: pd.DataFrame, columns) -> None:
    for col in columns:
        raw = df[col]
        vals = pd.to_numeric(raw, errors="coerce")
        bad = vals.isna() & raw.notna()
        if bad.any():
            i = int(np.flatnonzero(bad.to_numpy())[0])
            raise InputError(f"not a number: '{raw.iloc[i]}'", file=path, row=i + 2, column=col,
                             value=raw.iloc[i], hint="Recordings hold numbers only")
        if vals.isna().any():
            i = int(np.flatnonzero(vals.isna().to_numpy())[0])
            raise InputError("empty or NaN value", file=path, row=i + 2, column=col,
                             hint="Fill or drop the row (diagnose does not guess missing samples)")
        if not np.isfinite(vals.to_numpy()).all():
            i = int(np.flatnonzero(~np.isfinite(vals.to_numpy()))[0])
            raise InputError(f"infinite value '{raw.iloc[i]}'", file=path, row=i + 2, column=col)
        if col.endswith("torque_Nm"):
            plausible.check_torque(vals.to_numpy(), file=path, column=col)   # units off by far
        df[col] = vals.astype(float)


def _check_time(path: Path, t: np.ndarray) -> float:
    if len(t) < 20:
        raise InputError(f"only {len(t)} samples; diagnose needs at least 20", file=path)
    plausible.check_time_steps(t, file=path, column="time_s")     # milliseconds?
    d = np.diff(t)
    if (d <= 0).any():
        i = int(np.flatnonzero(d <= 0)[0]) + 1
        raise InputError(f"time_s is not strictly increasing ({t[i - 1]:g} then {t[i]:g})",
                         file=path, row=i + 2, column="time_s", value=t[i],
                         hint="Sort the rows by time and remove duplicate time stamps")
    step = float(np.median(d))
    gaps = np.flatnonzero(d > GAP_FACTOR * step)
    if len(gaps):
        i = int(gaps[0]) + 1
        raise InputError(f"gap of {d[i - 1]:g} s in time_s (from {t[i - 1]:g} s to {t[i]:g} s; "
                         f"the usual step is {step:g} s)", file=path, row=i + 2, column="time_s",
                         value=t[i], hint="Split the recording at the gap or fill the missing samples")
    return step


def _resample(df: pd.DataFrame, step: float) -> tuple[pd.DataFrame, bool]:
    t = df["time_s"].to_numpy()
    d = np.diff(t)
    if np.all(np.abs(d - step) <= 0.01 * step):
        return df.reset_index(drop=True), False
    grid = np.arange(t[0], t[-1] + 0.5 * step, step)
    out = {"time_s": grid}
    for col in df.columns:
        if col != "time_s":
            out[col] = np.interp(grid, t, df[col].to_numpy())
    return pd.DataFrame(out), True


def _differential_columns(path, columns, sidecar, meta_path, notes) -> list[str]:
    """Check a differential-level recording's columns and sidecar; the columns used."""
    _require(path, columns, DIFF_REQUIRED, "differential")
    if "diff_output_torque_Nm" not in columns:
        if "axle_torque_left_Nm" in columns and "axle_torque_right_Nm" in columns:
            notes.append("diff_output_torque_Nm = axle_torque_left_Nm + axle_torque_right_Nm")
        else:
            raise InputError("missing column diff_output_torque_Nm (or both axle_torque_left_Nm "
                             "and axle_torque_right_Nm)", file=path, column="diff_output_torque_Nm",
                             hint="The measured half-shaft torque sum is the target diagnose "
                                  "compares the model with")
    if ("wheel_speed_left_rpm" in columns) != ("wheel_speed_right_rpm" in columns):
        one = "wheel_speed_left_rpm" if "wheel_speed_left_rpm" in columns else "wheel_speed_right_rpm"
        raise InputError(f"{one} without its partner", file=path, column=one,
                         hint="Give both wheel_speed_left_rpm and wheel_speed_right_rpm, or neither")
    missing_meta = [k for k in DIFF_META_REQUIRED if k not in sidecar]
    if missing_meta:
        raise InputError(f"sidecar lacks {', '.join(missing_meta)}", file=meta_path,
                         hint="Differential-level sidecar keys: " + ", ".join(DIFF_META_REQUIRED))
    _check_sidecar_numbers(sidecar, meta_path)
    for k in ("gear_ratio", "peak_engine_torque_Nm", "torque_converter_ratio",
              "max_transmission_gear_ratio"):
        v = sidecar[k]
        if not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise InputError(f"sidecar key {k} must be a positive number, got {v!r}",
                             file=meta_path, column=k, value=v)
    try:
        sidecar["configuration"] = canonical_configuration(str(sidecar["configuration"]))
    except InputError as exc:
        exc.file, exc.column = meta_path, "configuration"
        raise
    return [c for c in columns if c in DIFF_REQUIRED + DIFF_OPTIONAL]


def _vehicle_columns(path, columns) -> list[str]:
    """Check a vehicle-level recording's columns; the columns used."""
    speed = [c for c in VEHICLE_SPEEDS if c in columns]
    fuel = [c for c in FUEL_RATES if c in columns]
    if not speed:
        raise InputError("missing a vehicle speed column (vehicle_speed_kph, vehicle_speed_mph "
                         "or vehicle_speed_mps)", file=path, column="vehicle_speed_kph")
    if not fuel:
        raise InputError("missing a fuel rate column (fuel_rate_g_per_s or fuel_rate_cc_per_s)",
                         file=path, column="fuel_rate_g_per_s")
    return ["time_s", speed[0], fuel[0]] + [c for c in ("grade_pct", "ambient_temp_C") if c in columns]


def _differential_values(path, df, notes) -> None:
    if "diff_output_torque_Nm" not in df.columns:
        df["diff_output_torque_Nm"] = df["axle_torque_left_Nm"] + df["axle_torque_right_Nm"]
    if (df["diff_input_speed_rpm"] < -1.0).mean() > 0.5:
        raise InputError("diff_input_speed_rpm is mostly negative", file=path,
                         column="diff_input_speed_rpm", hint="Give forward rotation as positive rpm")
    n_max = float(df["diff_input_speed_rpm"].abs().max())
    if 0 < n_max < 60 and df["diff_input_torque_Nm"].abs().max() > 1:
        notes.append(f"diff_input_speed_rpm never exceeds {n_max:.3g}: is it in rad/s? "
                     "fleetrun reads rpm")


def _vehicle_values(path, df, sidecar, meta_path, notes) -> None:
    scol = next(c for c in VEHICLE_SPEEDS if c in df.columns)
    df["vehicle_speed_mps"] = df[scol] * VEHICLE_SPEEDS[scol]
    if (df["vehicle_speed_mps"] < -0.5).any():
        i = int(np.flatnonzero(df["vehicle_speed_mps"].to_numpy() < -0.5)[0])
        raise InputError("negative vehicle speed", file=path, row=i + 2, column=scol,
                         value=df[scol].iloc[i])
    if df["vehicle_speed_mps"].max() > 90:
        raise InputError(f"vehicle speed up to {df['vehicle_speed_mps'].max():.0f} m/s "
                         "(over 320 km/h)", file=path, column=scol,
                         hint="Check the unit in the column name (kph, mph or mps)")
    if "fuel_rate_g_per_s" not in df.columns:
        fuel = str(sidecar.get("fuel", "gasoline")).lower()
        rho = FUEL_DENSITY_G_PER_CC.get(fuel)
        if rho is None:
            raise InputError(f"sidecar fuel '{fuel}' must be gasoline or diesel", file=meta_path,
                             column="fuel", value=fuel)
        df["fuel_rate_g_per_s"] = df["fuel_rate_cc_per_s"] * rho
        notes.append(f"fuel_rate_g_per_s = fuel_rate_cc_per_s x {rho} g/cm^3 ({fuel})")
    if (df["fuel_rate_g_per_s"] < -1e-9).any():
        i = int(np.flatnonzero(df["fuel_rate_g_per_s"].to_numpy() < -1e-9)[0])
        raise InputError("negative fuel rate", file=path, row=i + 2, column="fuel_rate_g_per_s")


def load_recording(path, meta=None) -> Recording:
    """Read, check and (if its steps are irregular) resample a recording to a uniform grid."""
    path = Path(path)
    if not path.is_file():
        raise InputError("recording not found", file=path, hint="Give the path of a CSV file")
    _check_header(path)
    try:
        df = pd.read_csv(path, dtype=str, skipinitialspace=True)
    except (pd.errors.ParserError, UnicodeDecodeError, pd.errors.EmptyDataError) as exc:
        raise InputError(f"cannot read the CSV ({str(exc).splitlines()[0]})", file=path) from None
    df.columns = [str(c).strip() for c in df.columns]
    columns = list(df.columns)
    _check_units(path, columns)
    if "time_s" not in columns:
        raise InputError("missing column time_s", file=path, column="time_s",
                         hint=f"Columns present: {_shown(columns)}")
    level = _level(path, columns)
    sidecar, meta_path = _read_sidecar(path, meta)
    notes = []
    if level == "differential":
        used = _differential_columns(path, columns, sidecar, meta_path, notes)
    else:
        used = _vehicle_columns(path, columns)
    _check_numbers(path, df, used)
    df = df[used].copy()
    step = _check_time(path, df["time_s"].to_numpy())
    if level == "differential":
        _differential_values(path, df, notes)
    else:
        _vehicle_values(path, df, sidecar, meta_path, notes)
    df, resampled = _resample(df, step)
    if resampled:
        notes.append(f"resampled to a uniform {step:g} s grid (linear interpolation)")
    return Recording(path, level, df, Sidecar.from_toml(sidecar, level, meta_path), meta_path, step, resampled, notes)
