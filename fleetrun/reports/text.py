"""What both reports say in words: headline totals rounded to their range, and the assumptions.

The Excel Summary and the HTML page show the same sentences, made here once.
"""
from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from fleetrun.budget import arithmetic as budget

SCALES = ((1e9, "billion"), (1e6, "million"), (1e3, "thousand"))


def short(value: float, prefix: str = "", low: float | None = None, high: float | None = None) -> str:
    """``value`` rounded to the digit its range supports (:func:`budget.display_round`) and
    written with a word scale: ``$2.46 million``."""
    if value is None or not math.isfinite(value):
        return "n/a"
    rounded = budget.display_round(value, low, high)
    for threshold, word in SCALES:
        if abs(rounded) >= threshold:
            digits = _digits(rounded / threshold, (high - low) / threshold if _has_range(low, high) else None)
            return f"{prefix}{rounded / threshold:,.{digits}f} {word}"
    digits = _digits(rounded, (high - low) if _has_range(low, high) else None)
    return f"{prefix}{rounded:,.{digits}f}"


def _has_range(low, high) -> bool:
    return low is not None and high is not None and math.isfinite(low) and math.isfinite(high) and high > low


def _digits(value: float, width: float | None) -> int:
    """Decimals to show: down to a tenth of the range's width (3 significant digits without)."""
    if width:
        return max(0, -math.floor(math.log10(width / 10.0)))
    if value == 0:
        return 0
    return max(0, 2 - math.floor(math.log10(abs(value))))


def with_range(value: float, low: float, high: float, prefix: str = "", unit: str = "") -> str:
    """``12.3 million gal (11.1 to 13.5 million)``; the value alone when there is no range."""
    unit = f" {unit}" if unit else ""
    if not _has_range(low, high):
        return f"{short(value, prefix)}{unit}"
    return (f"{short(value, prefix, low, high)}{unit} "
            f"({short(low, prefix, low, high)} to {short(high, prefix, low, high)})")


def scenario_ranges(fiscal: pd.DataFrame, scenarios, period_ranges=None) -> dict[str, dict[str, float]]:
    """Per scenario: fuel, state and federal tax over the budget period with their 90 % range
    (the Monte Carlo's percentiles of the period totals, ``RunResult.period_ranges``; without
    them, no range)."""
    out = {}
    for s in scenarios:
        rows = fiscal[(fiscal["scenario_id"] == s.scenario_id) & (fiscal["fuel"] != "electric")]
        found = (period_ranges or {}).get(s.scenario_id)
        entry = {"fuel": math.fsum(rows["fuel_gal"]), "state": math.fsum(rows["state_tax_usd"]),
                 "federal": math.fsum(rows["federal_tax_usd"])}
        for key in ("fuel", "state", "federal"):
            low, high = (getattr(found, f"{key}_low"), getattr(found, f"{key}_high")) if found else (math.nan, math.nan)
            entry[f"{key}_low"], entry[f"{key}_high"] = entry[key] * low, entry[key] * high
        out[s.scenario_id] = entry
    return out


def fuel_mpg(results: pd.DataFrame) -> dict[tuple[str, str], float]:
    """(scenario, fuel) -> miles / gallons of that fuel's vehicles (never gasoline and diesel
    mixed: their gallons differ in energy and tax)."""
    out = {}
    for (scenario_id, fuel), group in results.groupby(["scenario_id", "fuel"], sort=False):
        gallons = math.fsum(group["fuel_gal_total"])
        if fuel != "electric" and gallons > 0:
            out[(scenario_id, fuel)] = math.fsum(group["miles_total"]) / gallons
    return out


def totals_with_fuel_mpg(totals: pd.DataFrame, results: pd.DataFrame) -> pd.DataFrame:
    """The scenario totals with ``mpg_<fuel>`` per fuel in place of one mixed fleet mpg."""
    mpg = fuel_mpg(results)
    fuels = list(dict.fromkeys(f for _, f in mpg))
    frame = totals.drop(columns=["mpg"])
    position = list(totals.columns).index("mpg")
    for k, fuel in enumerate(fuels):
        frame.insert(position + k, f"mpg_{fuel}", [mpg.get((s, fuel), math.nan) for s in frame["scenario_id"]])
    return frame


def headline(s, entry: dict) -> list[tuple[str, str]]:
    """(label, text) pairs for one scenario's headline, state and federal apart."""
    years = budget.fiscal_years(s)
    period = f"fiscal years {years[0]}-{years[-1]}" if s.first_fiscal_year else f"{s.budget_years} budget year(s)"
    return [("Period", period),
            ("Fuel", with_range(entry["fuel"], entry["fuel_low"], entry["fuel_high"], unit="gal")),
            ("State fuel tax", with_range(entry["state"], entry["state_low"], entry["state_high"], prefix="$")),
            ("Federal fuel tax", with_range(entry["federal"], entry["federal_low"], entry["federal_high"], prefix="$"))]


def _mix_text(mix: dict | None) -> str:
    if not mix:
        return "as cycle_mix"
    return ", ".join(f"{Path(k).name if k.lower().endswith('.csv') else k} {w:.0%}" for k, w in mix.items())


def assumptions(s) -> list[tuple[str, str]]:
    """(label, text) pairs: what a reader needs to judge one scenario's numbers."""
    rows = [("Ambient temperature", f"{s.ambient_temp_C:g} C"),
            ("Cycle mix (share of miles)", _mix_text(s.cycle_mix)),
            ("Cycle mix, medium trucks", _mix_text(s.cycle_mix_MD)),
            ("Cycle mix, heavy trucks", _mix_text(s.cycle_mix_HD)),
            ("Miles growth", f"{s.vmt_growth_pct_per_year:g} % per year"),
            ("State tax, gasoline / diesel", f"${s.state_tax_gasoline_usd_per_gal:.3f} / "
                                             f"${s.state_tax_diesel_usd_per_gal:.3f} per gal"),
            ("Federal tax, gasoline / diesel", f"${s.federal_tax_gasoline_usd_per_gal:.3f} / "
                                               f"${s.federal_tax_diesel_usd_per_gal:.3f} per gal"),
            ("On-road fuel", budget.onroad_label(s.onroad_adjustment)),
            ("Fiscal years", ", ".join(str(y) for y in budget.fiscal_years(s))
             if s.first_fiscal_year else f"{s.budget_years} budget year(s), numbered from 1")]
    rows += driver_rows(s)
    rows += registration_rows(s)
    if s.ev_fee_usd_per_vehicle_year:
        rows.append(("Electric-vehicle fee", f"${s.ev_fee_usd_per_vehicle_year:,.2f} per vehicle per year"))
    observed = [f"{fuel} {s.observed_base_gallons(fuel):,.0f} gal" for fuel in ("gasoline", "diesel")
                if s.observed_base_gallons(fuel) is not None]
    if observed:
        rows.append(("Observed first-year gallons", ", ".join(observed)
                     + ("; forecast calibrated to them" if s.calibrate_to_observed else "; not calibrated")))
    return rows


def registration_rows(s) -> list[tuple[str, str]]:
    """The registration controls a scenario gives (docs/registrations.md): the base year's
    vehicle-miles and the share of them by class."""
    rows = []
    if s.base_year_vmt_million is not None:
        rows.append(("Base-year vehicle-miles", f"{s.base_year_vmt_million:,.0f} million (the registrations' "
                                                f"miles are scaled to it)"))
    if s.base_year_vmt_share_pct:
        listed = ", ".join(f"{name} {pct:g} %" for name, pct in s.base_year_vmt_share_pct.items())
        rows.append(("Share of the miles by class", f"{listed}; the other classes the rest"))
    return rows


def _schedule_text(value, unit: str = "$/gal") -> str:
    if isinstance(value, dict):
        return ", ".join(f"{year}: ${rate:.3f}" for year, rate in sorted(value.items())) + f" ({unit})"
    return f"${float(value):.3f} {unit}"


def driver_rows(s) -> list[tuple[str, str]]:
    """The drivers of one scenario (docs/budget.md): fiscal year start, fuel price and price
    response, state tax per year."""
    from fleetrun.budget import drivers

    import calendar

    rows = [("Fiscal year starts", calendar.month_name[drivers.start_month(s)])]
    prices = [f"{fuel} {_schedule_text(p)}" for fuel, p in (("gasoline", s.fuel_price_gasoline_usd_per_gal),
                                                            ("diesel", s.fuel_price_diesel_usd_per_gal)) if p is not None]
    short, long = drivers.elasticities(s)
    rows.append(("Fuel price", "; ".join(prices) if prices else "not given (no price response; price uncertainty "
                                                                  "in the range)"))
    rows.append(("Price elasticity of gallons", f"short run {short:g}, long run {long:g}"))
    schedules = [f"{fuel} {_schedule_text(v)}" for fuel, v in (("gasoline", s.state_tax_schedule_gasoline_usd_per_gal),
                                                               ("diesel", s.state_tax_schedule_diesel_usd_per_gal)) if v]
    if schedules:
        rows.append(("State tax per fiscal year", "; ".join(schedules)))
    elif s.state_tax_index_pct_per_year:
        rows.append(("State tax index", f"{s.state_tax_index_pct_per_year:g} % per year"))
    return rows


# Two kinds of 90 % range appear in the outputs (docs/budget.md, "Ranges"); both reports say
# which is which in these words.
HEADLINE_HEADING = ("Headline: totals over the budget period, each with the 90 % range of that total "
                    "(the range to quote), rounded to the digit the range supports")
TOTAL_RANGE = ("The range given with a total (the headline, each row of the revenue memo) is "
               "the 90 % range of that total itself (5th to 95th percentile): the range to quote.")
ROW_RANGES = ("Per-row ranges: fuel_gal_low / fuel_gal_high (fuel_gal_low_total / fuel_gal_high_total over the "
              "budget period) of the ByVehicle, ByClass and Fiscal years sheets, results.csv, class_summary.csv and "
              "fiscal_summary.csv are each row's share of its fuel's own 5th / 95th percentile in each fiscal year, "
              "so that they add up over rows and years; added up they are wider than the range of the total "
              "(ranges do not add), so do not quote their sums as a total's range.")


def range_source_lines(error_model) -> list[str]:
    """Where the ranges come from, in short lines (docs/budget.md, "Ranges")."""
    from fleetrun.budget import drivers

    u = drivers.uncertainty()
    lines = ["Ranges: 5th to 95th percentile of a Monte Carlo over the model's fleet-level error and the "
             "drivers (VMT growth, fuel price through the price elasticity, fleet mix); a fuel calibrated to "
             "collections keeps the uncertainty of the observed gallons and of the years after them.",
             f"Drivers: VMT growth sd {u['vmt_growth_sd_pct_points']:g} points a year; fuel price sd "
             f"{u['fuel_price_log_sd_per_year']:.0%} a year (log); each fuel's share of the miles sd "
             f"{u['fleet_mix_relative_sd']:.0%} (models/budget.toml)."]
    if error_model is None:
        return lines + ["No model error in these ranges: no measured fleet error in this installation "
                        "(models/fleet_error.toml)."]
    return lines + [f"Model error: {error_model.describe()}."]
