"""diagnosis.html of ``fleetrun diagnose-fleet``: the fleet's story in tables, words and plots."""
from __future__ import annotations

import numpy as np
from jinja2 import Environment, FileSystemLoader, select_autoescape

from fleetrun.fileio import JsonDocument
from fleetrun.diagnose.report import NO_FIGURES, _png, data_uri
from fleetrun.errors import MissingExtraError
from fleetrun.plots import pyplot
from fleetrun.resources import templates_dir


def fleet_figures(result: JsonDocument) -> dict[str, bytes]:
    """Mean error per test (baseline, after the findings, full model) and the unexplained
    error against the strongest vehicle property; none without matplotlib (NO_FIGURES)."""
    try:
        plt = pyplot("diagnosis.html's figures")
    except MissingExtraError:
        return {}

    tests = list(result["baseline"]["tests"])
    x = np.arange(len(tests))
    fig, ax = plt.subplots(figsize=(8, 3.2))
    series = (("baseline (warm engine)", result["baseline"]["tests"], "tab:blue"),
              ("+ findings", result["after"]["tests"], "tab:red"),
              ("full model (cold-start model on)", result["full_model"]["tests"], "grey"))
    for k, (label, table, color) in enumerate(series):
        ax.bar(x + (k - 1) * 0.27, [100 * table[t]["mean_error"] for t in tests], 0.27, color=color, label=label)
    ax.axhline(0, color="black", lw=0.5)
    ax.set_xticks(x, tests, fontsize=8)
    ax.set_ylabel("mean error [%]\n(predicted mpg / measured - 1)")
    ax.set_title("Where the mismatch sits: mean error per test")
    ax.legend(fontsize=8)
    figs = {"tests": _png(fig)}
    drivers = result["unexplained"]["drivers"]
    if drivers:
        d = drivers[0]
        fig, ax = plt.subplots(figsize=(7, 3.0))
        prof = d["profile"]
        ax.bar(range(len(prof)), [100 * p["mean_error"] for p in prof], color="tab:purple")
        ax.set_xticks(range(len(prof)), [f"{p['bin']}\n(n={p['n']})" for p in prof], fontsize=7)
        ax.axhline(0, color="black", lw=0.5)
        ax.set_ylabel("mean held-out error [%]")
        ax.set_title(f"Unexplained: error by {d['property']} (after the findings)")
        figs["property"] = _png(fig)
    return figs


def summary_words(result: JsonDocument) -> str:
    """The first paragraph: what was found, where, and what stays unexplained."""
    parts = []
    for f in result["findings"]:
        parts.append(f["explanation"])
    if not result["findings"]:
        parts.append("No candidate effect improves the error on held-out manufacturers.")
    u = result["unexplained"]
    drv = [d["property"].replace("_", " ") for d in u["drivers"] if d["significant"]]
    if u["significant"]:
        text = "Still unexplained after the findings:"
        if u["tests"]:
            text += " a mean error in " + ", ".join(u["tests"]) + ";"
        if drv:
            text += " errors that follow " + ", ".join(drv[:4]) + " (vehicle properties)"
        parts.append(text.rstrip(";") + ".")
    return " ".join(parts)


def render_fleet_html(prob, result: JsonDocument) -> str:
    env = Environment(loader=FileSystemLoader(str(templates_dir() / "diagnosis")),
                      autoescape=select_autoescape(["html", "j2"]))
    figs = {k: data_uri(v) for k, v in fleet_figures(result).items()}
    return env.get_template("fleet.html.j2").render(r=result, figs=figs, no_figures=NO_FIGURES,
                                                          summary=summary_words(result))
