"""What a measured quantity can plausibly be, in one place: drive-cycle CSVs
(:mod:`fleetrun.cycles`), diagnose recordings and measured fuel economy files check their
columns here, so that a value off by a unit (speeds x 1000, time in milliseconds, km/L under
``mpg``) is an ``Error:`` naming file, row and column instead of a silently wrong number.
(Fleet workbook cells keep their ranges beside their columns, ``fleetrun.workbook.schema``.)

The limits are physical, not statistical; each says where it comes from:

- speed: 90 m/s (324 km/h), above any road vehicle's test or road speed (US06 peaks at
  35.9 m/s, 80.3 mph: 40 CFR 86 App. I);
- grade: +-40 %, steeper than any public road (the steepest streets are about 35 %);
- time step: in a sampled trace (20 samples or more) a median step above 60 s means the time
  is not in seconds (drive cycles and recordings are sampled at 1 Hz or faster; a millisecond
  clock gives steps of 100 or 1000); a few hand-typed points may lie further apart;
- fuel economy: 3 to 200 mpg (a loaded heavy truck to a hybrid's city label; 40 CFR 600);
  measured over simulated fuel economy a median 1/1.8 to 1.8 for a whole file (the simulation
  is within about 25 % of EPA's results on average; km/L under ``mpg`` is 2.35 times too low);
- torque: 100,000 N m at the differential (a Class 8 axle carries about 30,000 N m).
"""
from __future__ import annotations

import math

import numpy as np

from fleetrun.errors import InputError

MAX_SPEED_MPS = 90.0
MAX_GRADE_PCT = 40.0
MAX_MEDIAN_STEP_S = 60.0
MIN_SAMPLES_FOR_STEP_CHECK = 20
MPG_RANGE = (3.0, 200.0)
MAX_TORQUE_NM = 100_000.0
MAX_MEDIAN_MPG_FACTOR = 1.8

# Hard budgets of what an input may ask for, enforced before anything is allocated
MAX_CYCLE_ROWS = 500_000            # a 1 Hz cycle of 5.8 days; 10 Hz: 14 h
MAX_CYCLE_BYTES = 64_000_000        # the CSV file itself
MAX_MAP_POINTS = 1_000_000          # fleetrun map: torque fractions x speeds (the thesis: 5 x 5)
# distinct ambient temperatures of one workbook's scenarios: each costs an efficiency map per
# distinct axle, ~9 MB and 0.5 s each (measured: 40 temperatures, one axle: 490 MB, 24 s)
MAX_AMBIENT_TEMPERATURES = 24


def _first(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask)[0])


def check_speed(speed_mps, *, file, column, rows=None) -> None:
    """InputError at the first speed above MAX_SPEED_MPS (values off by a unit).

    Parameters
    ----------
    speed_mps : float or array, speeds [m/s]
    file : str or Path, the file to name in the error
    column : str, the column to name
    rows : sequence of int or None, the file's row number of each value (None: position + 2)

    Returns
    -------
    None; raises :class:`InputError`.
    """
    speed = np.asarray(speed_mps, dtype=float)
    bad = speed > MAX_SPEED_MPS
    if bad.any():
        i = _first(bad)
        raise InputError(f"speed {speed[i]:,.6g} m/s is not a road vehicle's (at most "
                         f"{MAX_SPEED_MPS:g} m/s = {MAX_SPEED_MPS * 3.6:.0f} km/h)", file=file,
                         row=_row(rows, i), column=column,
                         hint="Check the unit in the column name (a value 1,000 times too large?)")


def check_grade(grade_pct, *, file, column, rows=None) -> None:
    """InputError at the first grade steeper than MAX_GRADE_PCT either way.

    Parameters
    ----------
    grade_pct : float or array, grades [%]
    file : str or Path, the file to name in the error
    column : str, the column to name
    rows : sequence of int or None, the file's row number of each value

    Returns
    -------
    None; raises :class:`InputError`.
    """
    grade = np.asarray(grade_pct, dtype=float)
    bad = np.abs(grade) > MAX_GRADE_PCT
    if bad.any():
        i = _first(bad)
        raise InputError(f"grade {grade[i]:,.6g} % is steeper than any road (at most +-{MAX_GRADE_PCT:g} %)",
                         file=file, row=_row(rows, i), column=column,
                         hint="Give the grade in percent (rise / run x 100)")


def check_time_steps(time_s, *, file, column, rows=None) -> None:
    """InputError when the median step says the time is not in seconds.

    Parameters
    ----------
    time_s : float or array, time stamps [s]
    file : str or Path, the file to name in the error
    column : str, the column to name
    rows : sequence of int or None, the file's row number of each value

    Returns
    -------
    None; raises :class:`InputError`.
    """
    t = np.asarray(time_s, dtype=float)
    if len(t) < MIN_SAMPLES_FOR_STEP_CHECK:
        return
    step = float(np.median(np.diff(t)))
    if step > MAX_MEDIAN_STEP_S:
        raise InputError(f"the usual time step is {step:,.6g} s; samples are 1 s apart or closer, so "
                         "the time is not in seconds (milliseconds?)", file=file, row=_row(rows, 1),
                         column=column, hint="Give the time in seconds")


def check_torque(torque_Nm, *, file, column, rows=None) -> None:
    """InputError at the first torque beyond MAX_TORQUE_NM or not a number.

    Parameters
    ----------
    torque_Nm : float or array, torques [N m]
    file : str or Path, the file to name in the error
    column : str, the column to name
    rows : sequence of int or None, the file's row number of each value

    Returns
    -------
    None; raises :class:`InputError`.
    """
    torque = np.asarray(torque_Nm, dtype=float)
    bad = ~(np.abs(torque) <= MAX_TORQUE_NM)
    if bad.any():
        i = _first(bad)
        raise InputError(f"torque {torque[i]:,.6g} N m is beyond any vehicle's differential (at most "
                         f"{MAX_TORQUE_NM:,.0f} N m)", file=file, row=_row(rows, i), column=column,
                         hint="Check the unit (N m)")


def check_mpg(mpg, *, file, column, rows=None) -> None:
    """InputError at the first fuel economy outside MPG_RANGE (km/L or L/100 km under ``mpg``).

    Parameters
    ----------
    mpg : float or array, fuel economies [mpg]
    file : str or Path, the file to name in the error
    column : str, the column to name
    rows : sequence of int or None, the file's row number of each value

    Returns
    -------
    None; raises :class:`InputError`.
    """
    values = np.asarray(mpg, dtype=float)
    low, high = MPG_RANGE
    bad = ~((values >= low) & (values <= high))
    if bad.any():
        i = _first(bad)
        raise InputError(f"{values[i]:,.6g} mpg is outside {low:g} to {high:g} mpg", file=file,
                         row=_row(rows, i), column=column,
                         hint="Give miles per US gallon (km/L x 2.352 = mpg; 235.2 / (L/100 km) = mpg)")


def check_mpg_scale(measured_over_simulated, *, file, column) -> None:
    """InputError when a file's fuel economies are as a whole a unit off the simulation's (the
    median ratio beyond MAX_MEDIAN_MPG_FACTOR either way: km/L, L/100 km under ``mpg``).

    Parameters
    ----------
    measured_over_simulated : float or array, measured / simulated mpg [-]
    file : str or Path, the file to name in the error
    column : str, the column to name

    Returns
    -------
    None; raises :class:`InputError`.
    """
    ratio = float(np.median(np.asarray(measured_over_simulated, dtype=float)))
    if not 1 / MAX_MEDIAN_MPG_FACTOR <= ratio <= MAX_MEDIAN_MPG_FACTOR:
        raise InputError(f"the measured fuel economies are a median {ratio:.3g} times the simulated ones; "
                         "not miles per US gallon?", file=file, column=column,
                         hint="Give mpg (km/L x 2.352 = mpg; 235.2 / (L/100 km) = mpg)")


def check_budget(what: str, count: int, limit: int, *, file=None, hint: str = "") -> None:
    """InputError when an input asks for more than a hard budget allows (before allocation).

    Parameters
    ----------
    what : str, what is counted, for the message
    count : int, how many the input asks for
    limit : int, the most fleetrun handles
    file : str or Path or None, the file to name in the error
    hint : str, what to do instead

    Returns
    -------
    None; raises :class:`InputError`.
    """
    if count > limit:
        raise InputError(f"{what}: {count:,} is more than fleetrun handles ({limit:,})", file=file,
                         hint=hint or None)


def _row(rows, i: int):
    if rows is None:
        return i + 2            # header = row 1
    value = rows[i]
    return int(value) if not (isinstance(value, float) and math.isnan(value)) else None
