"""The memo table (fiscal year x fuel with ranges) and quarterly / monthly rows (docs/budget.md).

Fiscal years: a fiscal year that starts in month ``m`` (``fiscal_year_start_month``; 7 = July,
the default) and is named ``Y`` runs from month m of calendar year Y - 1 to month m - 1 of Y
(the usual state convention: FY2027 = July 2026 to June 2027); with m = 1 it is calendar year Y.
A month's share of its fiscal year is its share of the year's vehicle-miles in FHWA's monthly
Traffic Volume Trends (models/budget.toml [seasonality]); quarters are sums of three months.
"""
from __future__ import annotations

import calendar
import math

import numpy as np
import pandas as pd

from fleetrun.budget import arithmetic as budget
from fleetrun.budget import drivers

MEMO_COLUMNS = ["scenario_id", "fiscal_year", "fuel", "fuel_gal", "fuel_gal_low", "fuel_gal_high",
                "state_tax_usd", "state_tax_low_usd", "state_tax_high_usd", "federal_tax_usd",
                "federal_tax_low_usd", "federal_tax_high_usd"]
PERIOD_COLUMNS = ["scenario_id", "fiscal_year", "fuel", "period", "calendar_year", "calendar_month",
                  "share", "fuel_gal", "state_tax_usd", "federal_tax_usd"]
ALL_FUELS = "all fuels"


def month_shares() -> np.ndarray:
    """Each calendar month's share (January first) of a year's vehicle-miles."""
    s = budget.constants()["seasonality"]
    monthly = (np.asarray(s["urban_daily_vmt_billion"]) + np.asarray(s["rural_daily_vmt_billion"])) * np.asarray(s["days"])
    return monthly / monthly.sum()


def fiscal_months(start_month: int, fiscal_year: int | None) -> list[tuple[int | None, int]]:
    """(calendar year, month) of the 12 months of a fiscal year, in order."""
    out = []
    for k in range(12):
        month = (start_month - 1 + k) % 12 + 1
        if fiscal_year is None:
            out.append((None, month))
        else:
            year = fiscal_year - 1 if (start_month > 1 and month >= start_month) else fiscal_year
            out.append((year, month))
    return out


def memo_table(fiscal: pd.DataFrame, ranges: dict) -> pd.DataFrame:
    """Per scenario x fiscal year x fuel (and all fuels): gallons, state and federal revenue,
    each with its 90 % range (revenue ranges are the gallons' range x the year's rates)."""
    rows = []
    for (scenario_id, year), group in fiscal.groupby(["scenario_id", "fiscal_year"], sort=False):
        index = _year_index(fiscal, scenario_id, year)
        for fuel, part in list(group.groupby("fuel", sort=False)) + [(ALL_FUELS, group)]:
            if fuel == "electric":
                continue
            part = part[part.fuel != "electric"]
            found = ranges.get((scenario_id, "all" if fuel == ALL_FUELS else fuel))
            low, high = (found.low, found.high) if found else (np.ones(index + 1), np.ones(index + 1))
            row = {"scenario_id": scenario_id, "fiscal_year": year, "fuel": fuel}
            for column, prefix in (("fuel_gal", "fuel_gal"), ("state_tax_usd", "state_tax"),
                                   ("federal_tax_usd", "federal_tax")):
                total = math.fsum(part[column])
                row[column] = total
                suffix = "" if column == "fuel_gal" else "_usd"
                row[f"{prefix}_low{suffix}"] = total * float(low[index])
                row[f"{prefix}_high{suffix}"] = total * float(high[index])
            rows.append(row)
    return pd.DataFrame(rows, columns=MEMO_COLUMNS)


def _year_index(fiscal: pd.DataFrame, scenario_id: str, year) -> int:
    years = list(dict.fromkeys(fiscal.fiscal_year[fiscal.scenario_id == scenario_id]))
    return years.index(year)


def period_rows(memo: pd.DataFrame, scenarios) -> pd.DataFrame:
    """Quarterly and monthly rows of each scenario x fiscal year x fuel of the memo table."""
    shares = month_shares()
    by_id = {s.scenario_id: s for s in scenarios}
    rows = []
    for row in memo.itertuples(index=False):
        s = by_id[row.scenario_id]
        months = fiscal_months(drivers.start_month(s), row.fiscal_year if s.first_fiscal_year else None)
        weights = np.array([shares[m - 1] for _, m in months])
        weights = weights / weights.sum()
        parts = {c: budget.exact_parts(getattr(row, c) * weights, getattr(row, c))
                 for c in ("fuel_gal", "state_tax_usd", "federal_tax_usd")}
        base = {"scenario_id": row.scenario_id, "fiscal_year": row.fiscal_year, "fuel": row.fuel}
        for q in range(4):
            span = slice(3 * q, 3 * q + 3)
            rows.append({**base, "period": f"Q{q + 1}", "calendar_year": months[3 * q][0],
                         "calendar_month": "-".join(calendar.month_abbr[m] for _, m in months[span][::2]),
                         "share": float(weights[span].sum()),
                         **{c: math.fsum(parts[c][span]) for c in parts}})
        for k, (year, month) in enumerate(months):
            rows.append({**base, "period": f"M{k + 1:02d}", "calendar_year": year,
                         "calendar_month": calendar.month_abbr[month], "share": float(weights[k]),
                         **{c: parts[c][k] for c in parts}})
    return pd.DataFrame(rows, columns=PERIOD_COLUMNS)
