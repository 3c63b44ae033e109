"""Figures: efficiency maps drawn like the thesis Figs 6.1-6.6 (matplotlib, no display).

matplotlib is an optional extra (``pip install "fleetrun[plots]"``): only figures need it
(``fleetrun map --plot``, the PNGs of diagnosis.html). :func:`pyplot` imports it or says how to
install it; nothing else in fleetrun imports matplotlib.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fleetrun.errors import InputError, MissingExtraError
from fleetrun.fileio import atomic_file

PLOT_FORMATS = (".png", ".svg")


def pyplot(purpose: str):
    """``matplotlib.pyplot`` with the Agg backend (files, no display); MissingExtraError naming
    ``purpose`` and the extra to install when matplotlib is absent."""
    try:
        import matplotlib
    except ImportError:
        raise MissingExtraError(f"{purpose} needs matplotlib, which is not installed",
                                hint='Install the plots extra: pip install "fleetrun[plots]" '
                                     '(or pip install matplotlib)') from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def efficiency_map_figure(torque_fractions, speeds_rpm, eta, title: str):
    """A two-panel figure: the efficiency surface as filled contours over (speed, torque
    fraction), and efficiency against speed at each torque fraction (thesis Figs 6.1-6.6)."""
    plt = pyplot("--plot (an efficiency-map figure)")

    tf = np.asarray(torque_fractions, dtype=float)
    n = np.asarray(speeds_rpm, dtype=float)
    eta = np.asarray(eta, dtype=float).reshape(tf.size, n.size)
    # Cells where the losses exceed the input (efficiency 0, B.6) are left blank so that the
    # colour scale shows the variation where the differential does drive.
    shown = np.where(eta > 0, eta, np.nan)
    lo, hi = (np.nanmin(shown), np.nanmax(shown)) if np.isfinite(shown).any() else (0.0, 1.0)
    lo, hi = np.floor(lo * 100) / 100, min(1.0, np.ceil(hi * 100) / 100 + 1e-9)
    fig, (ax_map, ax_lines) = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    if tf.size > 1 and n.size > 1 and np.isfinite(shown).sum() > 1:
        filled = ax_map.contourf(n, tf, shown, levels=np.linspace(lo, hi, 21), cmap="viridis")
        fig.colorbar(filled, ax=ax_map, label="efficiency [-] (blank: losses exceed input)")
    else:
        points = ax_map.scatter(np.repeat(n[None, :], tf.size, 0), np.repeat(tf[:, None], n.size, 1),
                                c=shown, vmin=lo, vmax=hi, cmap="viridis")
        fig.colorbar(points, ax=ax_map, label="efficiency [-]")
    ax_map.set_xlabel("differential input speed [rpm]")
    ax_map.set_ylabel("torque fraction [-]")
    ax_map.set_title("efficiency map")
    for i, frac in enumerate(tf):
        if np.isfinite(shown[i]).any():  # a fraction where nothing drives has no line
            ax_lines.plot(n, shown[i], marker="o", ms=3, label=f"{frac:g}")
    ax_lines.set_xlabel("differential input speed [rpm]")
    ax_lines.set_ylabel("efficiency [-]")
    ax_lines.set_ylim(lo - 0.005, min(1.0, hi + 0.005))
    ax_lines.grid(alpha=0.3)
    ax_lines.legend(title="torque fraction", fontsize=8)
    fig.suptitle(title)
    return fig


def save_figure(fig, path) -> None:
    """Save ``fig`` atomically as PNG or SVG (by the file's suffix)."""
    path = Path(path)
    if path.suffix.lower() not in PLOT_FORMATS:
        raise InputError(f"{path}: plot file must end in .png or .svg, got '{path.suffix or '(none)'}'",
                         hint="Name the plot e.g. map.png or map.svg")
    plt = pyplot("--plot (an efficiency-map figure)")

    with atomic_file(path) as tmp:
        fig.savefig(tmp, format=path.suffix[1:].lower(), dpi=120)
    plt.close(fig)
