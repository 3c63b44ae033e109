"""``summary.html``: one self-contained page (no network, no script) for a phone or a printer.

Rendered from ``templates/summary.html.j2`` with autoescaping, so workbook labels are text.
The class table carries each value at full precision in ``data-value`` (what the tests compare
with ``class_summary.csv``) and formatted for reading in the cell.
"""
from __future__ import annotations

import math
from pathlib import Path

import jinja2

from fleetrun import __version__
from fleetrun.reports import charts
from fleetrun.reports import text as report_text
from fleetrun.reports.changes import describe as describe_changes
from fleetrun.reports.manifest import physics_label, run_header
from fleetrun.budget.result import RunResult
from fleetrun.budget.totals import CLASS_COLUMNS, FISCAL_COLUMNS, scenario_totals
from fleetrun.resources import templates_dir

CLASS_TABLE_COLUMNS = CLASS_COLUMNS[:9]   # the class_summary.csv contract columns
FISCAL_TABLE_COLUMNS = FISCAL_COLUMNS[1:]  # fiscal_summary.csv without the scenario (one table each)
TEXT_FORMATS = {
    "vehicles": "{:,.0f}", "miles_total": "{:,.0f}", "fuel_gal_total": "{:,.0f}", "mpg": "{:.2f}",
    "diff_efficiency": "{:.2%}", "state_tax_usd": "${:,.0f}", "federal_tax_usd": "${:,.0f}",
    "fiscal_year": "{}", "miles": "{:,.0f}", "fuel_gal": "{:,.0f}", "fuel_gal_low": "{:,.0f}",
    "fuel_gal_high": "{:,.0f}", "co2_t": "{:,.0f}", "kwh": "{:,.0f}", "ev_fee_usd": "${:,.0f}",
    "model_gallons": "{:,.0f}", "observed_gallons": "{:,.0f}", "model_to_observed": "{:.1%}", "scale": "{:.4f}",
    "gal_per_mile": "{:.5f}", "change_gal": "{:+,.0f}", "change_from_vmt_gal": "{:+,.0f}",
    "change_from_gal_per_mile_gal": "{:+,.0f}",
}
MEMO_LABELS = {"fuel_gal": "Gallons", "state_tax_usd": "State revenue", "federal_tax_usd": "Federal revenue"}


def _environment() -> jinja2.Environment:
    return jinja2.Environment(loader=jinja2.FileSystemLoader(str(templates_dir())),
                              autoescape=True, undefined=jinja2.StrictUndefined,
                              trim_blocks=True, lstrip_blocks=True)


def _fmt(column: str, value) -> str:
    if isinstance(value, str):
        return value
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    return TEXT_FORMATS.get(column, "{}").format(value)


def _raw(value) -> str:
    """The value exactly as the CSV writer prints it (shortest round-trip repr)."""
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ""
    return str(value)


def _cards(result: RunResult, totals) -> list[dict]:
    """One card per scenario: totals rounded to their range, state and federal apart, and
    each one's change against the first scenario."""
    ranges = report_text.scenario_ranges(result.fiscal, result.scenarios, result.period_ranges)
    mpg = report_text.fuel_mpg(result.results)
    described = {s.scenario_id: s for s in result.scenarios}
    cards, base = [], None
    for row in totals.itertuples(index=False):
        s = described[row.scenario_id]
        changes = []
        if base is None:
            base = row
        else:
            for label, now, then in (("state", row.state_tax_usd, base.state_tax_usd),
                                     ("federal", row.federal_tax_usd, base.federal_tax_usd)):
                if then:
                    changes.append(f"{label} revenue {now / then - 1.0:+.1%}")
            changes = [f"vs {base.scenario_id}: " + ", ".join(changes)] if changes else []
        items = report_text.headline(s, ranges[s.scenario_id])
        items.insert(1, ("Miles", report_text.short(row.miles_total)))
        for k, fuel in enumerate(f for sid, f in mpg if sid == row.scenario_id):
            items.insert(2 + k, (f"mpg, {fuel}", _fmt("mpg", mpg[(row.scenario_id, fuel)])))
        if row.kwh_total:
            items.append(("Electricity", f"{report_text.short(row.kwh_total)} kWh"))
        if row.ev_fee_usd:
            items.append(("EV fees", report_text.short(row.ev_fee_usd, "$")))
        cards.append({"scenario_id": row.scenario_id, "description": s.description, "lines": items,
                      "change": "; ".join(changes)})
    return cards


def _table_rows(frame, columns) -> list[list[dict]]:
    return [[{"column": c, "raw": _raw(v), "text": _fmt(c, v), "numeric": not isinstance(v, str)}
             for c, v in zip(columns, row)]
            for row in frame[columns].itertuples(index=False, name=None)]


def _fiscal_groups(result: RunResult) -> list[dict]:
    """The fiscal_summary rows, one group per scenario."""
    groups = []
    for s in result.scenarios:
        rows = result.fiscal[result.fiscal["scenario_id"] == s.scenario_id]
        groups.append({"scenario_id": s.scenario_id, "rows": _table_rows(rows, FISCAL_TABLE_COLUMNS)})
    return groups


def _memo_groups(result: RunResult) -> list[dict]:
    """The memo table per scenario: fiscal year x fuel, each value with its 90 % range, rounded
    to the digit the range supports (the same rule as the headline)."""
    memo = result.memo
    groups = []
    for s in result.scenarios:
        rows = []
        for r in memo[memo.scenario_id == s.scenario_id].itertuples(index=False):
            cells = []
            for column, label in MEMO_LABELS.items():
                prefix, stem = ("", "fuel_gal") if column == "fuel_gal" else ("$", column[:-4])
                value, low, high = getattr(r, column), getattr(r, f"{stem}_low" + ("" if not prefix else "_usd")), \
                    getattr(r, f"{stem}_high" + ("" if not prefix else "_usd"))
                cells.append({"label": label, "raw": _raw(value), "column": column,
                              "text": report_text.short(value, prefix, low, high),
                              "range": f"{report_text.short(low, prefix, low, high)} to "
                                       f"{report_text.short(high, prefix, low, high)}"})
            rows.append({"fiscal_year": r.fiscal_year, "fuel": r.fuel, "cells": cells})
        groups.append({"scenario_id": s.scenario_id, "rows": rows})
    return groups


def _tornado(result: RunResult) -> dict | None:
    """The tornado chart of the first scenario (state revenue per driver)."""
    frame = result.tornado
    if frame is None or not len(frame) or not result.scenarios:
        return None
    first = result.scenarios[0].scenario_id
    rows = frame[frame.scenario_id == first].to_dict("records")
    return {"scenario_id": first, "chart": charts.tornado(rows)} if rows else None


def _maps(result: RunResult) -> tuple[list[dict], dict]:
    low, high = charts.efficiency_scale(result.maps)
    maps = []
    for m in result.maps:
        title = f"{m.configuration}, gear ratio {m.gear_ratio:g}"
        if m.low_gear_ratio:
            title += f", low {m.low_gear_ratio:g} (high gear)"
        maps.append({"title": title, "chart": charts.heatmap(m, low=low, high=high)})
    return maps, charts.scale_legend(low, high)


def render_summary(result: RunResult) -> str:
    totals = scenario_totals(result.classes)
    revenue = {}
    for row in totals.itertuples(index=False):
        revenue[(row.scenario_id, "State fuel tax")] = row.state_tax_usd
        revenue[(row.scenario_id, "Federal fuel tax")] = row.federal_tax_usd
    revenue_chart = charts.grouped_bars(list(totals["scenario_id"]), ["State fuel tax", "Federal fuel tax"],
                                        revenue, prefix="$")
    class_names = list(dict.fromkeys(result.classes["vehicle_class"]))
    scenario_ids = list(totals["scenario_id"])
    fuel = {(r.vehicle_class, r.scenario_id): r.fuel_gal_total for r in result.classes.itertuples(index=False)}
    fuel_chart = charts.grouped_bars(class_names, scenario_ids, fuel)
    maps, scale = _maps(result)
    info = run_header(result)
    engine = info["engine"].get("engine", "")
    if info["engine"].get("scheduler"):
        engine += f" ({info['engine']['scheduler']})"
    fleet = result.fleet
    calibration = result.calibration if result.calibration is not None else None
    return _environment().get_template("summary.html.j2").render(
        version=__version__, fleet_name=fleet.path.name, **_fleet_size(result), created_utc=result.created_utc,
        physics=physics_label(info), mode=result.mode, engine=engine, fingerprint=fleet.sha256,
        scenarios=_cards(result, totals), revenue_chart=revenue_chart, memo_groups=_memo_groups(result),
        memo_labels=list(MEMO_LABELS.values()), tornado=_tornado(result), class_columns=CLASS_TABLE_COLUMNS,
        class_rows=_table_rows(result.classes, CLASS_TABLE_COLUMNS), fuel_chart=fuel_chart, maps=maps,
        scale=scale, warnings=result.warnings, inputs=info["inputs"],
        assumptions=_assumption_rows(result), scenario_ids=scenario_ids,
        ranges=report_text.range_source_lines(result.error_model), total_range=report_text.TOTAL_RANGE,
        row_ranges=report_text.ROW_RANGES,
        fiscal_columns=FISCAL_TABLE_COLUMNS, fiscal_groups=_fiscal_groups(result),
        calibration_columns=list(calibration.columns) if calibration is not None and len(calibration) else [],
        calibration_rows=_table_rows(calibration, list(calibration.columns))
        if calibration is not None and len(calibration) else [],
        changes=result.changes, change_lines=describe_changes(result.changes) if result.changes else [],
        **_turnover(result),
        sim_seconds=f"{result.timings_s.get('simulate', 0.0):.1f}")


def _fleet_size(result: RunResult) -> dict:
    """Vehicle types and vehicles: the Vehicles rows, plus the registration cohorts and the
    registered vehicles (docs/registrations.md) when there are registrations."""
    fleet = result.fleet
    types, vehicles = len(fleet.vehicles), sum(v.count for v in fleet.vehicles)
    text = f"{types:,} vehicle types, {vehicles:,.0f} vehicles"
    if result.registrations is not None:
        types = result.results["vehicle_id"].nunique()
        registered = result.registrations[result.registrations["registration_row"] != "new sales"]
        vehicles += float(registered["count"].sum())
        own = f"{len(fleet.vehicles):,} Vehicles rows and " if fleet.vehicles else ""
        text = (f"{own}{len(fleet.registrations):,} registration rows: {vehicles:,.0f} vehicles, simulated "
                f"as {types:,} cohorts (vehicle, class, fuel, model year)")
    return {"vehicle_types": f"{types:,}", "vehicles": f"{vehicles:,.0f}", "fleet_size": text}


def _turnover(result: RunResult) -> dict:
    """The registrations' change table (docs/registrations.md), when the fleet has registrations."""
    if result.turnover is None:
        return {"turnover_rows": [], "turnover_columns": [], "registration_rows": 0}
    columns = list(result.turnover.columns)
    return {"turnover_rows": _table_rows(result.turnover, columns), "turnover_columns": columns,
            "registration_rows": f"{len(result.registrations):,}"}


def _assumption_rows(result: RunResult) -> list[dict]:
    table = [dict(report_text.assumptions(s)) for s in result.scenarios]
    labels = list(dict.fromkeys(label for t in table for label in t))
    return [{"label": label, "cells": [t.get(label, "") for t in table]} for label in labels]


def write_summary_html(result: RunResult, path: Path) -> None:
    Path(path).write_text(render_summary(result), encoding="utf-8")
