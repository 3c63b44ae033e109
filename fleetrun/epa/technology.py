"""Technology classes of Test Car List configurations, by a documented join to EPA's OMEGA
model vehicles of model year 2022 (inputs/epa/omega_vehicles_my2022.csv; rules in
models/epa_technology.toml; docs/epa-import.md "Technology classes").

A configuration matches the OMEGA vehicle of the same manufacturer whose engine displacement
is within ``displacement_tolerance_L`` and whose target road load (A + B v + C v^2 at the
``speeds_mph``) is nearest, if that nearest is within ``road_load_tolerance`` (relative, the
largest difference over the speeds). OMEGA lists the target coefficients of the vehicle
line, so the match is on the vehicle's own measured road load, not on a name. Among equally
near OMEGA rows the one with the most sales wins. The technology names are the parts of
OMEGA's ``cost_curve_class`` mapped by ``[tokens]`` (e.g. ``SS1`` -> ``start_stop``).

A configuration whose road load is farther than the tolerance from every such OMEGA vehicle
(a body, tyre or trim OMEGA does not list) gets the classes of its engine instead: the
technology names most sold among the manufacturer's OMEGA vehicles of that displacement
(``[engine_join]``; the match's ``join`` says which rule applied).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pandas as pd

from fleetrun.resources import inputs_dir, model_file

JOIN_FILE = "epa_technology.toml"


@dataclass(frozen=True)
class TechnologyMatch:
    technology: str          # comma list of fleetrun technology names ("" when none)
    omega_vehicle: str       # OMEGA vehicle_name ("" when unmatched)
    cost_curve_class: str
    road_load_difference: float   # largest relative target-force difference (nan when unmatched)
    note: str                # the rule, for the Derived sheet
    join: str = ""           # "road_load", "engine" or "" (unmatched)


@lru_cache(maxsize=1)
def join_rules() -> dict:
    return model_file(JOIN_FILE)


@lru_cache(maxsize=1)
def omega_vehicles() -> pd.DataFrame:
    """The shipped OMEGA vehicle table with each row's fleetrun technology names."""
    rules = join_rules()
    table = pd.read_csv(inputs_dir() / rules["join"]["source"])
    table["technology"] = [technology_of_class(c) for c in table.cost_curve_class]
    return table


def technology_of_class(cost_curve_class: str) -> str:
    """OMEGA ``cost_curve_class`` -> sorted comma list of fleetrun technology names."""
    tokens = join_rules()["tokens"]
    names = {tokens[p] for p in str(cost_curve_class).split("_") if p in tokens}
    return ",".join(sorted(names))


def target_force_lbf(a, b, c, speeds_mph):
    """Target road-load force [lbf] A + B v + C v^2 at ``speeds_mph`` (rows x speeds)."""
    v = np.asarray(speeds_mph, float)[None, :]
    return np.asarray(a, float)[:, None] + np.asarray(b, float)[:, None] * v + np.asarray(c, float)[:, None] * v * v


def match_configuration(manufacturer, displacement_L, coef_A_lbf, coef_B_lbf_per_mph, coef_C_lbf_per_mph2):
    """The :class:`TechnologyMatch` of one configuration (the module docstring's rule)."""
    rules = join_rules()
    join = rules["join"]
    omega_make = rules["manufacturers"].get(str(manufacturer).strip())
    if omega_make is None:
        return _unmatched(f"manufacturer '{manufacturer}' has no OMEGA counterpart [models/{JOIN_FILE} [manufacturers]]")
    table = omega_vehicles()
    cand = table[(table.manufacturer_id == omega_make)
                 & (np.abs(table.engine_displacement_liters - float(displacement_L)) <= join["displacement_tolerance_L"])]
    if cand.empty:
        return _unmatched(f"no {omega_make} vehicle in OMEGA with {float(displacement_L):g} L "
                          f"(+-{join['displacement_tolerance_L']:g} L)")
    speeds = join["speeds_mph"]
    own = target_force_lbf([coef_A_lbf], [coef_B_lbf_per_mph], [coef_C_lbf_per_mph2], speeds)
    theirs = target_force_lbf(cand.target_coef_a, cand.target_coef_b, cand.target_coef_c, speeds)
    distance = np.abs(own / theirs - 1.0).max(axis=1)
    best = distance.min()
    if not best <= join["road_load_tolerance"]:
        far = (f"nearest {omega_make} target road load of {float(displacement_L):g} L differs by "
               f"{best:.1%} (tolerance {join['road_load_tolerance']:.0%})")
        return _engine_match(cand, far, float(best)) if rules["engine_join"]["enabled"] else _unmatched(far)
    tied = cand[distance <= best + 1e-12]
    row = tied.loc[tied.sales.idxmax()]
    classes = sorted(set(tied.cost_curve_class))
    note = (f"OMEGA MY2022 '{row.vehicle_name}' ({omega_make}, {row.cost_curve_class}, "
            f"{row.engine_displacement_liters:g} L): target road load within {best:.2%}"
            + (f"; {len(classes)} classes equally near ({', '.join(classes)}), the best-selling taken"
               if len(classes) > 1 else "") + f" [models/{JOIN_FILE}]")
    return TechnologyMatch(row.technology, str(row.vehicle_name), str(row.cost_curve_class), float(best), note,
                           "road_load")


def _engine_match(cand: pd.DataFrame, why: str, distance: float) -> TechnologyMatch:
    """The engine's classes: the technology names with the most sales among ``cand`` (the
    manufacturer's OMEGA vehicles of the displacement); their best-selling row is named."""
    sales = cand.groupby("technology").sales.sum()
    technology = sales.idxmax()
    row = cand[cand.technology == technology].sort_values("sales").iloc[-1]
    note = (f"{why}: the engine's classes, '{technology or 'none'}' ({sales.max() / sales.sum():.0%} of the "
            f"{len(cand)} OMEGA vehicles' sales with {row.engine_displacement_liters:g} L; best-selling "
            f"'{row.vehicle_name}', {row.cost_curve_class}) [models/{JOIN_FILE} [engine_join]]")
    return TechnologyMatch(technology, str(row.vehicle_name), str(row.cost_curve_class), distance, note, "engine")


def _unmatched(reason: str) -> TechnologyMatch:
    return TechnologyMatch("", "", "", float("nan"), "no technology class: " + reason)
