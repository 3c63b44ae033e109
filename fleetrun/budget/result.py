"""The result of a fleet run: what the reports and the outputs folder are written from.

Produced by :func:`fleetrun.run.runner.run_fleet`; read by :mod:`fleetrun.reports` and
:mod:`fleetrun.run.outputs`. It lives below both so the reports never import the orchestrator.
"""
from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field

import pandas as pd

from fleetrun.workbook.reader import Fleet, Scenario

__all__ = ["RunResult"]


@dataclass
class RunResult:
    fleet: Fleet
    scenarios: list[Scenario]
    results: pd.DataFrame
    classes: pd.DataFrame
    fiscal: pd.DataFrame                       # fiscal_summary.csv
    cycles: dict[str, dict]
    maps: list[dict]
    warnings: list[str]
    timings_s: dict[str, float]
    engine: dict
    physics: str
    mode: str
    cycle_inputs: dict[str, str] = field(default_factory=dict)   # CSV path -> sha256
    effects: list = field(default_factory=list)   # --with: [{"effect", "level", "parameters"}]
    created_utc: str = field(default_factory=lambda: _now_utc())
    distinct_vehicles: int = 0                 # physically distinct vehicles simulated
    calibration: pd.DataFrame | None = None    # model vs observed base-year gallons per fuel
    error_model: object = None                 # uncertainty.ErrorModel behind the ranges (None: none)
    tornado: pd.DataFrame | None = None        # state revenue per driver at its 5th / 95th percentile
    memo: pd.DataFrame | None = None           # revenue_memo.csv: fiscal year x fuel with ranges
    periods: pd.DataFrame | None = None        # fiscal_periods.csv: quarters and months
    ranges: dict = field(default_factory=dict)  # scenario -> fuel or "all" -> (low, high) / central per year
    changes: dict | None = None                # changes.compare with the run already in the folder


def _now_utc() -> str:
    return dt.datetime.now(dt.timezone.utc).replace(microsecond=0).isoformat()


