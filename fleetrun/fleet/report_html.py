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
from fleetrun.fleet import charts
from fleetrun.fleet.manifest import manifest_dict, physics_label
from fleetrun.fleet.runner import RunResult
from fleetrun.fleet.totals import CLASS_COLUMNS, scenario_totals
from fleetrun.resources import templates_dir

CLASS_TABLE_COLUMNS = CLASS_COLUMNS[:9]   # the class_summary.csv contract columns
TEXT_FORMATS = {
    "vehicles": "{:,.0f}", "miles_total": "{:,.0f}", "fuel_gal_total": "{:,.0f}", "mpg": "{:.2f}",
    "diff_efficiency": "{:.4f}", "state_tax_usd": "${:,.0f}", "federal_tax_usd": "${:,.0f}",
}


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


def render_summary(result: RunResult) -> str:
    totals = scenario_totals(result.classes)
    described = {s.scenario_id: s for s in result.scenarios}
    cards = []
    base = None
    for row in totals.itertuples(index=False):
        s = described[row.scenario_id]
        change = ""
        if base is None:
            base = row
        elif base.total_tax_usd:
            delta = row.total_tax_usd / base.total_tax_usd - 1.0
            change = f"{delta:+.2%} fuel-tax revenue vs {base.scenario_id}"
        cards.append({"scenario_id": row.scenario_id, "description": s.description,
                      "budget_years": s.budget_years, "gallons": f"{row.fuel_gal_total:,.0f}",
                      "miles": f"{row.miles_total:,.0f}", "mpg": _fmt("mpg", row.mpg),
                      "state_tax": f"${row.state_tax_usd:,.0f}",
                      "federal_tax": f"${row.federal_tax_usd:,.0f}", "change": change})
    revenue = {}
    for row in totals.itertuples(index=False):
        revenue[(row.scenario_id, "state")] = row.state_tax_usd
        revenue[(row.scenario_id, "federal")] = row.federal_tax_usd
    revenue_chart = charts.grouped_bars(list(totals["scenario_id"]), ["state", "federal"], revenue,
                                        prefix="$")
    class_names = list(dict.fromkeys(result.classes["vehicle_class"]))
    scenario_ids = list(totals["scenario_id"])
    fuel = {(r.vehicle_class, r.scenario_id): r.fuel_gal_total for r in result.classes.itertuples(index=False)}
    fuel_chart = charts.grouped_bars(class_names, scenario_ids, fuel)
    class_rows = [[{"column": c, "raw": _raw(v), "text": _fmt(c, v), "numeric": not isinstance(v, str)}
                   for c, v in zip(CLASS_TABLE_COLUMNS, row)]
                  for row in result.classes[CLASS_TABLE_COLUMNS].itertuples(index=False, name=None)]
    maps = []
    for m in result.maps:
        title = f"{m['configuration']}, gear ratio {m['gear_ratio']:g}"
        if m["low_gear_ratio"]:
            title += f", low {m['low_gear_ratio']:g} (high gear)"
        maps.append({"title": title, "chart": charts.heatmap(m)})
    info = manifest_dict(result)
    engine = info["engine"].get("engine", "")
    if info["engine"].get("scheduler"):
        engine += f" ({info['engine']['scheduler']})"
    fleet = result.fleet
    return _environment().get_template("summary.html.j2").render(
        version=__version__, fleet_name=fleet.path.name, vehicle_types=f"{len(fleet.vehicles):,}",
        vehicles=f"{sum(v.count for v in fleet.vehicles):,.0f}", created_utc=result.created_utc,
        physics=physics_label(info), mode=result.mode, engine=engine, fingerprint=fleet.sha256,
        scenarios=cards, revenue_chart=revenue_chart, class_columns=CLASS_TABLE_COLUMNS,
        class_rows=class_rows, fuel_chart=fuel_chart, maps=maps, warnings=result.warnings,
        inputs=info["inputs"], sim_seconds=f"{result.timings_s.get('simulate', 0.0):.1f}")


def write_summary_html(result: RunResult, path: Path) -> None:
    Path(path).write_text(render_summary(result), encoding="utf-8")
