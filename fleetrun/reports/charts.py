"""Geometry for the HTML summary's inline SVG charts.

Python computes positions and colours; the jinja2 templates (``templates/charts.html.j2``)
draw them with autoescaping on, so a label from the workbook can never become markup.
"""
from __future__ import annotations

import math

from fleetrun.budget.result import EfficiencyMap

PALETTE = ("#1f4e78", "#c55a11", "#548235", "#7030a0", "#bf9000", "#2e75b6", "#a5a5a5", "#843c0c")


def nice_max(value: float) -> float:
    """A round axis end at or above ``value`` (1, 2, 2.5, 5 x 10^k)."""
    if value <= 0 or not math.isfinite(value):
        return 1.0
    exponent = math.floor(math.log10(value))
    for step in (1, 2, 2.5, 5, 10):
        candidate = step * 10 ** exponent
        if candidate >= value:
            return candidate
    return 10 ** (exponent + 1)


def short_number(value: float, prefix: str = "") -> str:
    """1234567 -> '1.23M' (axis and bar labels)."""
    if value is None or not math.isfinite(value):
        return "n/a"
    magnitude = abs(value)
    for threshold, suffix in ((1e12, "T"), (1e9, "B"), (1e6, "M"), (1e3, "k")):
        if magnitude >= threshold:
            return f"{prefix}{value / threshold:.3g}{suffix}"
    return f"{prefix}{value:.3g}"


def grouped_bars(categories: list[str], series: list[str], values: dict[tuple[str, str], float], *,
                 prefix: str = "", width: int = 420, bar_height: int = 14, label_width: int = 110) -> dict:
    """Horizontal bars: one group per category, one bar per series in each group."""
    gap = 10
    plot_width = width - label_width - 70
    top = 10 + (18 if len(series) > 1 else 0)
    vmax = nice_max(max([v for v in values.values() if v is not None and math.isfinite(v)] or [0.0]))
    groups = []
    y = top
    for category in categories:
        bars = []
        for i, name in enumerate(series):
            value = values.get((category, name))
            length = 0.0 if value is None or not math.isfinite(value) else plot_width * max(value, 0) / vmax
            bars.append({"series": name, "y": y, "length": length, "value": value,
                         "text": short_number(value, prefix), "color": PALETTE[i % len(PALETTE)]})
            y += bar_height + 2
        groups.append({"label": category, "label_y": y - (bar_height + 2) * len(series) / 2 + 4,
                       "bars": bars})
        y += gap
    ticks = [{"x": label_width + plot_width * f, "text": short_number(vmax * f, prefix)}
             for f in (0, 0.25, 0.5, 0.75, 1.0)]
    spacing = min(120.0, (width - label_width) / max(1, len(series)))
    legend = [{"name": name, "color": PALETTE[i % len(PALETTE)], "x": label_width + i * spacing}
              for i, name in enumerate(series)] if len(series) > 1 else []
    return {"width": width, "height": y + 20, "label_width": label_width, "plot_width": plot_width,
            "bar_height": bar_height, "groups": groups, "ticks": ticks, "axis_y": y,
            "legend": legend}


def _efficiency_color(value: float, low: float, high: float) -> str:
    """Red (low) - yellow - green (high), as Excel's 3-colour scale."""
    if not math.isfinite(value):
        return "#dddddd"
    t = 0.5 if high <= low else min(1.0, max(0.0, (value - low) / (high - low)))
    stops = ((248, 105, 107), (255, 235, 132), (99, 190, 123))
    a, b, f = (stops[0], stops[1], t * 2) if t < 0.5 else (stops[1], stops[2], (t - 0.5) * 2)
    r, g, bl = (round(a[k] + (b[k] - a[k]) * f) for k in range(3))
    return f"#{r:02x}{g:02x}{bl:02x}"


def efficiency_scale(maps) -> tuple[float, float]:
    """One colour scale for every map of a run: the lowest and highest efficiency of all."""
    values = [v for m in maps for row in m.efficiency for v in row if math.isfinite(v)]
    return (min(values), max(values)) if values else (0.0, 1.0)


def scale_legend(low: float, high: float, *, width: int = 300) -> dict:
    """The one colour scale of all heat maps: a gradient bar from ``low`` to ``high``."""
    steps = 24
    stops = [{"x": 10 + width * k / steps, "w": width / steps + 0.5,
              "fill": _efficiency_color(low + (high - low) * k / steps, low, high)} for k in range(steps + 1)]
    ticks = [{"x": 10 + width * f, "text": f"{low + (high - low) * f:.1%}"} for f in (0.0, 0.5, 1.0)]
    return {"width": width + 20 + width / steps, "stops": stops, "ticks": ticks}


def heatmap(effmap: EfficiencyMap, *, low: float, high: float, cell_width: int = 40, cell_height: int = 20) -> dict:
    """The efficiency map as a grid of coloured cells with their values [%]; colours on the
    scale ``low``..``high`` shared by every map of the page."""
    left, top = 44, 24
    cells = []
    for i, (tf, row) in enumerate(zip(effmap.torque_fractions, effmap.efficiency)):
        for j, value in enumerate(row):
            cells.append({"x": left + j * cell_width, "y": top + i * cell_height,
                          "fill": _efficiency_color(value, low, high),
                          "text": f"{100 * value:.1f}" if math.isfinite(value) else "n/a"})
    columns = [{"x": left + (j + 0.5) * cell_width, "text": f"{s:g}"} for j, s in enumerate(effmap.speeds_rpm)]
    rows = [{"y": top + (i + 0.5) * cell_height + 4, "text": f"{tf:g}"}
            for i, tf in enumerate(effmap.torque_fractions)]
    return {"width": left + cell_width * len(columns) + 10,
            "height": top + cell_height * len(rows) + 26, "cells": cells, "columns": columns,
            "rows": rows, "cell_width": cell_width, "cell_height": cell_height, "left": left,
            "top": top, "axis_y": top + cell_height * len(rows) + 18}
