"""diagnosis.html: the story of a diagnosis in plots and plain words (self-contained HTML)."""
from __future__ import annotations

import base64
import io

import numpy as np
from jinja2 import Environment, FileSystemLoader, select_autoescape

from fleetrun.fileio import JsonDocument
from fleetrun.diagnose.locate import binned_profile, smooth
from fleetrun.effects import EFFECTS
from fleetrun.resources import templates_dir
from fleetrun.errors import MissingExtraError
from fleetrun.plots import pyplot

#: What diagnosis.html says in place of its figures when matplotlib (the plots extra) is absent.
NO_FIGURES = 'Figures need matplotlib, which is not installed: pip install "fleetrun[plots]".'


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    pyplot("diagnosis.html's figures").close(fig)
    return buf.getvalue()


def data_uri(png: bytes) -> str:
    """A PNG embedded in the self-contained HTML."""
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def _thin(n: int, max_points: int = 4000) -> slice:
    return slice(None, None, max(1, n // max_points))


def _time_figures(problem, result, fitted, t, sl, plt) -> dict:
    """Measured vs model, the residual over time and the cumulative residual."""
    r = problem.residual
    r_after = r - fitted
    smooth_s = max(10.0, 0.01 * float(t[-1]))          # the segments' smoothing (locate.segments)
    win = max(1, int(round(len(t) / max(t[-1], 1e-9) * smooth_s)))
    unit = problem.units
    figs = {}
    fig, ax = plt.subplots(figsize=(10, 3.4))
    ax.plot(t[sl], problem.measured[sl], lw=0.7, label="measured", color="black")
    base_label = "thesis model (baseline)" if problem.level == "differential" else "simulation (baseline)"
    ax.plot(t[sl], problem.baseline[sl], lw=0.7, label=base_label, color="tab:blue")
    if result["findings"]:
        ax.plot(t[sl], (problem.baseline + fitted)[sl], lw=0.7, ls="--", color="tab:red",
                label="model + findings")
    ax.set_xlabel("time since start [s]")
    ax.set_ylabel(f"{problem.target} [{unit}]")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title("Measured vs simulated")
    figs["measured"] = _png(fig)

    fig, ax = plt.subplots(figsize=(10, 3.0))
    ax.plot(t[sl], smooth(r, win)[sl], lw=0.8, color="tab:blue", label=f"residual ({smooth_s:.0f} s mean), baseline")
    if result["findings"]:
        ax.plot(t[sl], smooth(r_after, win)[sl], lw=0.8, color="tab:red", label="after findings")
    for seg in result["mismatch"]["segments"]:
        ax.axvspan(seg["start_s"] - problem.time_s[0], seg["end_s"] - problem.time_s[0],
                   color="orange", alpha=0.25)
    ax.axhline(0, color="grey", lw=0.5)
    ax.set_xlabel("time since start [s]")
    ax.set_ylabel(f"measured - model [{unit}]")
    ax.set_title("Residual over time (shaded: located segments)")
    ax.legend(loc="upper right", fontsize=8)
    figs["residual"] = _png(fig)

    dt = np.gradient(problem.time_s)
    fig, ax = plt.subplots(figsize=(10, 2.6))
    ax.plot(t[sl], np.cumsum(r * dt)[sl], color="tab:blue", label="baseline")
    if result["findings"]:
        ax.plot(t[sl], np.cumsum(r_after * dt)[sl], color="tab:red", label="after findings")
    ax.axhline(0, color="grey", lw=0.5)
    ax.set_xlabel("time since start [s]")
    ax.set_ylabel(f"cumulative residual [{unit} s]")
    ax.set_title("Cumulative residual: where the mismatch adds up")
    ax.legend(loc="best", fontsize=8)
    figs["cumulative"] = _png(fig)
    return figs


def _driver_figure(problem, result, fitted, plt) -> str | None:
    """The residual against its three strongest drivers (binned), before and after."""
    drivers = result["mismatch"]["drivers"]
    if not drivers:
        return None
    r = problem.residual
    top = [d["channel"] for d in drivers[:3]]
    fig, axes = plt.subplots(1, len(top), figsize=(3.6 * len(top), 3.0), squeeze=False)
    for ax, name in zip(axes[0], top):
        x = problem.driver_channels[name]
        xm, rm = binned_profile(x, r)
        ax.plot(xm, rm, "o-", ms=3, color="tab:blue", label="baseline")
        if result["findings"]:
            xm2, rm2 = binned_profile(x, r - fitted)
            ax.plot(xm2, rm2, "o-", ms=3, color="tab:red", label="after")
        ax.axhline(0, color="grey", lw=0.5)
        ax.set_xlabel(name)
        ax.set_ylabel(f"mean residual [{problem.units}]")
    axes[0][0].legend(fontsize=8)
    fig.suptitle("Residual against its strongest drivers (quantile bins)")
    return _png(fig)


def figures(problem, result: JsonDocument, fitted: np.ndarray) -> dict[str, bytes]:
    """The report's figures as PNG bytes, by name (measured, residual, cumulative, drivers,
    heldout); none without matplotlib (the page then says so, :data:`NO_FIGURES`)."""
    try:
        plt = pyplot("diagnosis.html's figures")
    except MissingExtraError:
        return {}

    t = problem.time_s - problem.time_s[0]
    figs = _time_figures(problem, result, fitted, t, _thin(len(t)), plt)
    drivers = _driver_figure(problem, result, fitted, plt)
    if drivers:
        figs["drivers"] = drivers
    labels = ["baseline"]
    vals = [result["baseline"]["heldout_rmse"]]
    for f in result["findings"]:
        labels.append("+ " + f["effect"])
        vals.append(f["heldout_rmse_after"])
    fig, ax = plt.subplots(figsize=(1.6 + 1.4 * len(vals), 3.0))
    ax.bar(range(len(vals)), vals, color=["tab:blue"] + ["tab:red"] * (len(vals) - 1))
    ax.set_xticks(range(len(vals)), labels, fontsize=8)
    ax.set_ylabel(f"held-out RMSE [{problem.units}]")
    ax.set_title("Held-out fit (blocked CV)")
    figs["heldout"] = _png(fig)
    return figs


def _where(result: JsonDocument) -> str:
    segs = result["mismatch"]["segments"][:2]
    drv = [d["channel"].replace("_", " ") for d in result["mismatch"]["drivers"] if d.get("significant")][:3]
    parts = []
    if segs:
        parts.append("the mismatch concentrates in " + " and ".join(
            f"{s['start_s']:.0f}-{s['end_s']:.0f} s ({100 * s['share']:.0f} %)" for s in segs))
    if drv:
        parts.append("it follows " + ", ".join(drv))
    return (" " + "; ".join(parts).capitalize() + ".") if parts else ""


def summary_sentence(result: JsonDocument) -> str:
    """The report's first paragraph: what is left unexplained first, then the findings."""
    return " ".join(x for x in (_unexplained_words(result), _summary(result) + _where(result),
                                _descriptions_words(result)) if x)


def _unexplained_words(result: JsonDocument) -> str:
    u = result.get("unexplained") or {}
    if not u.get("significant"):
        return ""
    drv = [d["channel"].replace("_", " ") for d in u.get("drivers", []) if d.get("significant")][:3]
    what = "the model with its findings" if result["findings"] else "the model"
    text = (f"Something the catalogue does not describe remains: after {what} the residual "
            f"(RMSE {u['rmse']:.3g} {result.get('units', '')}) still has a part that the recorded "
            f"channels explain beyond noise (what no function of them explains: "
            f"{u['noise_rmse']:.3g})")
    if drv:
        text += "; it follows " + ", ".join(drv)
    segs = u.get("segments", [])[:2]
    if segs:
        text += "; it concentrates in " + " and ".join(
            f"{s['start_s']:.0f}-{s['end_s']:.0f} s" for s in segs)
    if result["findings"] and u.get("energy_share") is not None:
        text += (f". Its size: {100 * u['energy_share']:.0f} % of the mismatch's structured "
                 "energy is left")
        if u.get("integral_share") is not None:
            text += f", and {100 * u['integral_share']:.0f} % of its phase-integral error"
    return text + "." + _drift_words(u)


def _drift_words(u: dict) -> str:
    d = u.get("drift") or {}
    if not d.get("significant"):
        return ""
    return (f" The target's sensor looks miscalibrated rather than the physics incomplete: a "
            f"gain drifting by {100 * d['gain_change']:+.1f} % and an offset by "
            f"{d['offset_change']:+.3g} over the run follow it, moving mostly between "
            f"{d['start_s']:.0f} and {d['end_s']:.0f} s (sensor_drift; check the channel's "
            "calibration).")


def _descriptions_words(result: JsonDocument) -> str:
    d = result.get("descriptions") or []
    if not d:
        return ""
    names = ", ".join(f"{EFFECTS[x['effect']].title} ({x['reason'].split(';')[0]})" for x in d)
    return (f"Weak or ambiguous descriptions, not findings: {names}. They describe part of the "
            "mismatch; they are not evidence that the model leaves this physics out.")


def _summary(result: JsonDocument) -> str:
    f = result["findings"]
    if f:
        names = " and then ".join(EFFECTS[x["effect"]].title for x in f)
        return (f"The model leaves out {names}. With it the held-out error falls from "
                f"{result['baseline']['heldout_rmse']:.3g} to {f[-1]['heldout_rmse_after']:.3g} "
                f"{result.get('units', '')}.")
    if result.get("ambiguities"):
        a = result["ambiguities"][0]
        return (f"The recording shows a mismatch that {' or '.join(a['effects'])} could explain; "
                f"the data cannot tell them apart. To separate them: {a['separating_test']}.")
    if (result.get("unexplained") or {}).get("significant"):
        return "No effect of the catalogue explains it: the cause is not in the catalogue."
    if result["mismatch"]["significant"]:
        return ("The residual is larger than noise but none of the candidate physics explains it "
                "better than noise could: the cause is not in the catalog.")
    return "Nothing is missing: the model matches the recording to within its noise."


def render_html(problem, result: JsonDocument, fitted: np.ndarray) -> str:
    env = Environment(loader=FileSystemLoader(str(templates_dir() / "diagnosis")),
                      autoescape=select_autoescape(["html", "j2"]))
    tpl = env.get_template("diagnosis.html.j2")
    figs = {name: data_uri(png) for name, png in figures(problem, result, fitted).items()}
    return tpl.render(r=result, figs=figs, no_figures=NO_FIGURES,
                      summary=summary_sentence(result), effects=EFFECTS)
