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


CHAR_PX = 6.6     # width of a character of the 11 px chart font, generously (system-ui, Arial)


def text_px(text: str) -> float:
    """An upper estimate of ``text``'s width at the charts' 11 px font [px]."""
    return CHAR_PX * len(str(text))


def _legend(series: list[str], left: float, width: float) -> tuple[list[dict], float]:
    """Legend items laid out in rows that fit ``width`` (never past the right edge); the
    height they take [px]."""
    items, x, y = [], left, 2
    for i, name in enumerate(series):
        span = 14 + text_px(name) + 12
        if x > left and x + span > width:
            x, y = left, y + 16
        items.append({"name": name, "color": PALETTE[i % len(PALETTE)], "x": x, "y": y})
        x += span
    return items, y + 16


def grouped_bars(categories: list[str], series: list[str], values: dict[tuple[str, str], float], *,
                 prefix: str = "", width: int = 420, bar_height: int = 14, label_width: int | None = None) -> dict:
    """Horizontal bars: one group per category, one bar per series in each group. The label
    column is as wide as the longest label and the chart widens with it, and the legend wraps,
    so no text is clipped (the SVG scales to the screen as a whole)."""
    gap = 10
    if label_width is None:
        label_width = int(max(60, max((text_px(c) for c in categories), default=0) + 12))
    width = int(max(width, label_width + 300))
    value_room = max(70, text_px(short_number(1.23e9, prefix)) + 10)
    plot_width = width - label_width - value_room
    legend, legend_height = _legend(series, 4, width - 4) if len(series) > 1 else ([], 0)
    top = 10 + legend_height
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
    return {"width": width, "height": y + 20, "label_width": label_width, "plot_width": plot_width,
            "bar_height": bar_height, "groups": groups, "ticks": ticks, "axis_y": y,
            "legend": legend, "grid_top": top - 4}


def tornado(rows, *, prefix: str = "$", width: int = 460, bar_height: int = 16) -> dict:
    """Sensitivity bars: per driver a bar from its low to its high value around the central
    line (``rows``: dicts with driver, low_usd, high_usd, central_usd; widest first)."""
    rows = list(rows)
    label_width = int(max(60, max((text_px(r["driver"]) for r in rows), default=0) + 12))
    width = int(max(width, label_width + 320))
    plot_left, plot_width = label_width + 50, width - label_width - 100
    lows = [r["low_usd"] for r in rows] + [r["central_usd"] for r in rows]
    highs = [r["high_usd"] for r in rows] + [r["central_usd"] for r in rows]
    lo, hi = (min(lows), max(highs)) if rows else (0.0, 1.0)
    span = (hi - lo) or 1.0

    def x(value):
        return plot_left + plot_width * (value - lo) / span

    scale, word = next(((t, w) for t, w in ((1e12, "T"), (1e9, "B"), (1e6, "M"), (1e3, "k"))
                        if abs(hi) >= t), (1.0, ""))
    digits = max(0, min(4, -math.floor(math.log10(max(span / scale / 10, 1e-9)))))

    def label(value):       # one number of decimals for every label, enough to tell them apart
        return f"{prefix}{value / scale:,.{digits}f}{word}"

    bars, y = [], 24
    for r in rows:
        bars.append({"label": r["driver"], "y": y, "x": x(r["low_usd"]), "w": max(1.0, x(r["high_usd"]) - x(r["low_usd"])),
                     "low": label(r["low_usd"]), "high": label(r["high_usd"]),
                     "low_x": x(r["low_usd"]) - 4, "high_x": x(r["high_usd"]) + 4})
        y += bar_height + 8
    centre = x(rows[0]["central_usd"]) if rows else plot_left
    return {"width": width, "height": y + 24, "label_width": label_width, "bars": bars, "bar_height": bar_height,
            "centre_x": centre, "axis_y": y, "centre_text": label(rows[0]["central_usd"]) if rows else ""}


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
    """The one colour scale of all heat maps: a gradient bar from ``low`` to ``high``, with a
    margin either side for the end labels (centred on the bar's ends, they would be cut)."""
    steps, margin = 24, 28
    stops = [{"x": margin + width * k / steps, "w": width / steps + 0.5,
              "fill": _efficiency_color(low + (high - low) * k / steps, low, high)} for k in range(steps + 1)]
    ticks = [{"x": margin + width * f, "text": f"{low + (high - low) * f:.1%}"} for f in (0.0, 0.5, 1.0)]
    return {"width": width + 2 * margin + width / steps, "stops": stops, "ticks": ticks}


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
