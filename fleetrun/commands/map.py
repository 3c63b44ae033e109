"""``fleetrun map``: a differential efficiency map (thesis Sec. 6.2, Tables 6.1/6.2, Figs 6.1-6.6)."""
from __future__ import annotations

import io
import json

import click
import numpy as np

from fleetrun.differential import canonical_configuration, efficiency, reference_capacity_Nm
from fleetrun.effects import efficiency_with_effects, parse_with
from fleetrun.errors import InputError
from fleetrun.fileio import write_text_atomic
from fleetrun.registry import PHYSICS

DEFAULT_TORQUE_FRACTIONS = "0,0.25,0.5,0.75,1"     # thesis Table 6.1
DEFAULT_SPEEDS_RPM = "0,1000,2000,3000,4000"        # thesis Table 6.2


def parse_number_list(text: str, option: str) -> list[float]:
    """``"0,0.25,0.5"`` -> [0.0, 0.25, 0.5]; a usage error (exit 2) names the item that does
    not parse."""
    items = [s.strip() for s in str(text).split(",")]
    if not any(items):
        raise click.BadParameter(f"empty list; give comma-separated numbers, e.g. {option} 0,0.5,1",
                                 param_hint=option)
    values = []
    for i, item in enumerate(items, start=1):
        try:
            value = float(item)
        except ValueError:
            raise click.BadParameter(f"item {i} '{item}' is not a number; give comma-separated "
                                     f"numbers, e.g. {option} 0,0.5,1", param_hint=option) from None
        if not np.isfinite(value):
            raise click.BadParameter(f"item {i} '{item}' is not a finite number", param_hint=option)
        values.append(value)
    return values


def parse_number(text: str, option: str) -> float:
    """A finite number from the command line; anything else is a usage error (exit 2)."""
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise click.BadParameter(f"'{text}' is not a number", param_hint=option) from None
    if not np.isfinite(value):
        raise click.BadParameter(f"'{text}' is not a finite number", param_hint=option)
    return value


def compute_map(configuration, gear_ratio, torque_fractions, speeds_rpm, *, low_gear_ratio=None,
                axle_gear="high", physics="thesis", effects=None):
    """Efficiency on the grid torque fractions (outer) x speeds (inner); shape (n_tf, n_speed)."""
    tf = np.asarray(torque_fractions, dtype=float)[:, None]
    n = np.asarray(speeds_rpm, dtype=float)[None, :]
    kwargs = dict(low_gear_ratio=low_gear_ratio, axle_gear=axle_gear, physics=physics)
    if effects:
        return np.asarray(efficiency_with_effects(configuration, tf, n, gear_ratio, effects,
                                                  kim_torque_scale_Nm=reference_capacity_Nm(configuration), **kwargs))
    return np.asarray(efficiency(configuration, tf, n, gear_ratio, **kwargs))


def render_csv(torque_fractions, speeds_rpm, eta) -> str:
    buf = io.StringIO()
    buf.write("torque_fraction,speed_rpm,efficiency\n")
    for i, frac in enumerate(torque_fractions):
        for j, speed in enumerate(speeds_rpm):
            buf.write(f"{frac!r},{speed!r},{float(eta[i, j])!r}\n")
    return buf.getvalue()


def render_json(meta: dict, torque_fractions, speeds_rpm, eta) -> str:
    doc = dict(meta)
    doc["torque_fractions"] = list(torque_fractions)
    doc["speeds_rpm"] = list(speeds_rpm)
    doc["efficiency"] = [[float(v) for v in row] for row in eta]
    doc["points"] = [{"torque_fraction": f, "speed_rpm": s, "efficiency": float(eta[i, j])}
                     for i, f in enumerate(torque_fractions) for j, s in enumerate(speeds_rpm)]
    return json.dumps(doc, indent=1) + "\n"


@click.command("map")
@click.argument("configuration")
@click.option("--gear-ratio", "gear_ratio", required=True, metavar="G", help="Differential (final drive) gear ratio.")
@click.option("--low-gear-ratio", metavar="R", help="Two-speed axle low ratio (dual configurations), e.g. 4.900735.")
@click.option("--axle-gear", type=click.Choice(["low", "high"], case_sensitive=False), default="high",
              show_default=True, help="Two-speed axle gear engaged (dual configurations).")
@click.option("--torque-fractions", default=DEFAULT_TORQUE_FRACTIONS, show_default=True,
              help="Comma list: differential input torque / Kim torque scale (thesis Sec. 5.2.1.A).")
@click.option("--speeds-rpm", default=DEFAULT_SPEEDS_RPM, show_default=True,
              help="Comma list of differential input speeds [rpm].")
@click.option("--physics", default="thesis", show_default=True,
              help="Baseline model: thesis (Appendix B as printed) or vecto-generic.")
@click.option("--with", "with_effects", metavar="EFFECT[,EFFECT...]",
              help="Add physics the thesis left out (docs/effects.md), e.g. bearing_preload.")
@click.option("--format", "fmt", type=click.Choice(["csv", "json"]), default="csv", show_default=True)
@click.option("-o", "--output", type=click.Path(dir_okay=False), help="Write to FILE instead of stdout.")
@click.option("--plot", type=click.Path(dir_okay=False), help="Also draw the map to FILE (.png or .svg).")
def command(configuration, gear_ratio, low_gear_ratio, axle_gear, torque_fractions, speeds_rpm, physics,
            with_effects, fmt, output, plot):
    """Efficiency map of CONFIGURATION (LD_FWD, LD_RWD, LD_4WD, LD_AWD, HD_RWD, HD_DUAL,
    HD_TANDEM, HD_TANDEM_DUAL, HD_TAG, HD_TAG_DUAL) over torque fractions x speeds."""

    config = canonical_configuration(configuration)
    g = parse_number(gear_ratio, "--gear-ratio")
    low = parse_number(low_gear_ratio, "--low-gear-ratio") if low_gear_ratio is not None else None
    tfs = parse_number_list(torque_fractions, "--torque-fractions")
    speeds = parse_number_list(speeds_rpm, "--speeds-rpm")
    PHYSICS.get(physics)  # an unknown name fails here, before any work
    effects = None
    if with_effects:
        effects = parse_with(with_effects)
        vehicle_level = [e.id for e, _ in effects if e.level != "differential"]
        if vehicle_level:
            raise InputError(f"--with {','.join(vehicle_level)}: vehicle-level effects do not change a "
                             "differential map", hint="Use them with `fleetrun simulate` or `fleetrun run`")
    eta = compute_map(config, g, tfs, speeds, low_gear_ratio=low, axle_gear=axle_gear.lower(),
                      physics=physics, effects=effects)
    if fmt == "csv":
        text = render_csv(tfs, speeds, eta)
    else:
        meta = {"schema": "fleetrun.map/1", "configuration": config, "gear_ratio": g,
                "low_gear_ratio": low, "axle_gear": axle_gear.lower() if low is not None else None,
                "physics": physics, "with": [e.id for e, _ in effects] if effects else []}
        text = render_json(meta, tfs, speeds, eta)
    if plot:
        from fleetrun.plots import efficiency_map_figure, save_figure   # matplotlib: only for --plot

        title = f"{config}, gear ratio {g:g}" + (f", low {low:g} ({axle_gear})" if low is not None else "")
        save_figure(efficiency_map_figure(tfs, speeds, eta, f"{title}, physics {physics}"), plot)
    if output:
        write_text_atomic(output, text)
    else:
        click.echo(text, nl=False)
