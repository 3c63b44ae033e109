"""The result of a fleet run: what the reports and the outputs folder are written from.

Produced by :func:`fleetrun.run.runner.run_fleet`; read by :mod:`fleetrun.reports` and
:mod:`fleetrun.run.outputs`. It lives below both so the reports never import the orchestrator.
Every part is a typed, frozen record; ``as_json()`` gives the form manifest.json holds
(docs/interface.md).
"""
from __future__ import annotations

import datetime as dt
from dataclasses import asdict, dataclass, field

import pandas as pd

from fleetrun.budget.ranges import PeriodRange, YearRange
from fleetrun.budget.uncertainty import ErrorModel
from fleetrun.effects.base import AppliedEffect
from fleetrun.fileio import JsonDocument
from fleetrun.workbook.reader import Fleet, Scenario

__all__ = ["RunResult", "CycleInfo", "EfficiencyMap", "EngineInfo", "AppliedEffect", "RunChanges",
           "InputChange", "TotalChange", "ChangeCause"]


@dataclass(frozen=True)
class CycleInfo:
    """A drive cycle the run used: its name, length, duration and (for a file) path and sha256."""

    name: str
    miles: float
    duration_s: float
    path: str | None = None
    sha256: str | None = None

    def as_json(self) -> JsonDocument:
        keys = ("name", "miles", "duration_s") + (("path", "sha256") if self.path else ())
        return {k: getattr(self, k) for k in keys}


@dataclass(frozen=True)
class EfficiencyMap:
    """Differential efficiency of one configuration over torque fraction x input speed, at the
    fleet's median gear ratio and Kim scale (``efficiency[i][j]``: torque fraction i, speed j)."""

    configuration: str
    gear_ratio: float
    low_gear_ratio: float | None
    axle_gear: str
    torque_fractions: tuple[float, ...]
    speeds_rpm: tuple[float, ...]
    efficiency: tuple[tuple[float, ...], ...]
    vehicle_types: int


@dataclass(frozen=True)
class EngineInfo:
    """Where the simulations ran: ``local`` or ``dask`` (with its scheduler address)."""

    engine: str
    scheduler: str | None = None

    def as_json(self) -> JsonDocument:
        return {"engine": self.engine, **({"scheduler": self.scheduler} if self.scheduler is not None else {})}


@dataclass(frozen=True)
class InputChange:
    """One input file, compared by sha256 with the earlier run: added, removed, changed, same."""

    path: str
    status: str
    earlier_sha256: str | None
    sha256: str | None


@dataclass(frozen=True)
class TotalChange:
    """One scenario total, earlier vs now (None: not in that run); ``change_pct`` a fraction."""

    scenario_id: str
    total: str
    earlier: float | None
    now: float | None
    change_pct: float | None


@dataclass(frozen=True)
class ChangeCause:
    """The part of one scenario total's change due to one cause (``vehicles``, ``scenario``,
    ``model version``, ``calibration``, ``tax rates``, or several inputs together), in the
    total's unit."""

    scenario_id: str
    total: str
    cause: str
    amount: float


@dataclass(frozen=True)
class RunChanges:
    """What changed since the run that was in the output folder (:mod:`fleetrun.reports.changes`)."""

    earlier_created_utc: str
    earlier_version: str
    inputs: tuple[InputChange, ...]
    totals: tuple[TotalChange, ...]
    causes: tuple[ChangeCause, ...] = ()

    def as_json(self) -> JsonDocument:
        return asdict(self) | {"inputs": [asdict(i) for i in self.inputs], "totals": [asdict(t) for t in self.totals],
                               "causes": [asdict(c) for c in self.causes]}


@dataclass(frozen=True, eq=False)
class RunResult:
    fleet: Fleet
    scenarios: list[Scenario]
    results: pd.DataFrame
    classes: pd.DataFrame
    fiscal: pd.DataFrame                       # fiscal_summary.csv
    cycles: dict[str, CycleInfo]               # cycle name (or CSV path) as the scenarios give it
    maps: list[EfficiencyMap]
    warnings: list[str]
    timings_s: dict[str, float]
    engine: EngineInfo
    physics: str
    mode: str
    cycle_inputs: dict[str, str] = field(default_factory=dict)   # CSV path -> sha256
    effects: list[AppliedEffect] = field(default_factory=list)  # --with
    created_utc: str = field(default_factory=lambda: _now_utc())
    distinct_vehicles: int = 0                 # physically distinct vehicles simulated
    calibration: pd.DataFrame | None = None    # model vs observed base-year gallons per fuel
    error_model: ErrorModel | None = None      # the measured error behind the ranges (None: none)
    tornado: pd.DataFrame | None = None        # state revenue per driver at its 5th / 95th percentile
    memo: pd.DataFrame | None = None           # revenue_memo.csv: fiscal year x fuel with ranges
    periods: pd.DataFrame | None = None        # fiscal_periods.csv: quarters and months
    ranges: dict[tuple[str, str], YearRange] = field(default_factory=dict)  # (scenario, fuel or "all")
    period_ranges: dict[str, PeriodRange] = field(default_factory=dict)  # scenario -> budget-period range
    changes: RunChanges | None = None          # vs the run already in the folder
    registrations: pd.DataFrame | None = None  # registration rows: vehicle chosen, matched on, assumed
    turnover: pd.DataFrame | None = None       # year-on-year gallons change: VMT vs gallons per mile


def _now_utc() -> str:
    return dt.datetime.now(dt.timezone.utc).replace(microsecond=0).isoformat()
