"""EPA's ALPHA response surfaces (as shipped with the OMEGA model, inputs/epa/omega_alpha_rse_my2022.csv)
evaluated for Test Car List vehicles, for the side-by-side comparison of validation/epa_technology.py.

Per OMEGA class: CO2e [g/mi] per phase = a quadratic in ETW [lb], RLHP20 and RLHP60 (road-load
hp at 20 / 60 mph per lb of ETW; omega_functions.calc_roadload_hp) and HP_ETW (rated hp per lb).
Composites as OMEGA weights them (omega_model/test_inputs/drive_cycle_weights.csv and
drive_cycles.csv): FTP = (0.43 x 3.591 bag 1 + 3.859 bag 2 + 0.57 x 3.591 bag 3) / 7.45 (bag
distances 3.591, 3.859 mi; the surfaces' bag 4 is 0); US06 = its two phases by distance (1.772, 6.235 mi). mpg =
8,887 / CO2 [g/mi] for gasoline and 10,180 for diesel (EPA 420-F-18-008, grams of CO2 per
gallon). The class comes from the technology join (fleetrun/epa/technology.py).
"""
from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

import numpy as np
import pandas as pd

from fleetrun.cycles import FTP_HOT_WEIGHT, FTP_TRANSIENT_WEIGHT

ROOT = Path(__file__).resolve().parents[1]
RSE = ROOT / "inputs" / "epa" / "omega_alpha_rse_my2022.csv"
G_CO2_PER_GAL = {"gasoline": 8887.0, "diesel": 10180.0}
LBF_TO_N, MPH_TO_MPS, KW_PER_HP = 1.0 / 0.224808943, 1000.0 / 3600.0 / 0.621371, 0.746
UDDS_MI = (3.591, 3.859)
US06_MI = (1.772, 6.235)
_ALLOWED = re.compile(r"^[0-9eE.+\-*/() ,a-zA-Z_]+$")
NAMES = ("RLHP20", "RLHP60", "HP_ETW", "ETW")
_NUMBER = re.compile(r"(?<![A-Za-z_0-9])\d+\.?\d*(?:[eE][+-]?\d+)?")


def roadload_hp(a_lbf, b_lbf_per_mph, c_lbf_per_mph2, mph):
    """OMEGA's calc_roadload_hp: (A + B v + C v^2) v in hp (0.746 kW per hp)."""
    mps = mph * MPH_TO_MPS
    force_N = a_lbf * LBF_TO_N + b_lbf_per_mph * LBF_TO_N / MPH_TO_MPS * mps + c_lbf_per_mph2 * LBF_TO_N / MPH_TO_MPS ** 2 * mps ** 2
    return force_N * mps / 1000.0 / KW_PER_HP


@lru_cache(maxsize=1)
def surfaces() -> pd.DataFrame:
    return pd.read_csv(RSE).set_index("cost_curve_class")


def evaluate(expression: str, values: dict) -> float:
    """One RSE string (arithmetic, max, and the four names only) at ``values``."""
    names = set(re.findall(r"[A-Za-z_][A-Za-z_0-9]*", _NUMBER.sub(" ", expression)))
    if not _ALLOWED.match(expression) or names - set(NAMES) - {"max"}:
        raise ValueError(f"unexpected response-surface text: {expression[:60]}")
    return float(eval(expression, {"__builtins__": {}, "max": max}, dict(values)))  # noqa: S307 (checked above)


def alpha_mpg(cost_curve_class, etw_lb, rated_hp, a, b, c, fuel) -> dict:
    """ALPHA's FTP composite, HWFET and US06 mpg of one vehicle (NaN when its class is unknown)."""
    if cost_curve_class not in surfaces().index:
        return {t: np.nan for t in ("FTP", "HWFET", "US06")}
    row = surfaces().loc[cost_curve_class]
    values = {"ETW": etw_lb, "RLHP20": roadload_hp(a, b, c, 20.0) / etw_lb, "RLHP60": roadload_hp(a, b, c, 60.0) / etw_lb,
              "HP_ETW": rated_hp / etw_lb}
    co2 = {k.split(":")[0].removeprefix("cs_"): evaluate(v, values) for k, v in row.items()}
    ftp = (FTP_TRANSIENT_WEIGHT * co2["ftp_1"] * UDDS_MI[0] + co2["ftp_2"] * UDDS_MI[1]
           + FTP_HOT_WEIGHT * co2["ftp_3"] * UDDS_MI[0]) / sum(UDDS_MI)
    us06 = (co2["us06_1"] * US06_MI[0] + co2["us06_2"] * US06_MI[1]) / sum(US06_MI)
    per_gal = G_CO2_PER_GAL[fuel]
    return {"FTP": per_gal / ftp, "HWFET": per_gal / co2["hwfet"], "US06": per_gal / us06}


def alpha_table(specs, classes) -> pd.DataFrame:
    """ALPHA mpg per vehicle (rows of ``specs``; ``classes``: OMEGA class or '' per vehicle)."""
    rows = []
    for v, cls in zip(specs, classes):
        etw_lb = v.test_weight_kg / 0.45359237
        hp = (v.rated_power_kW or np.nan) / 0.745699872
        rows.append(alpha_mpg(cls, etw_lb, hp, v.coastdown_A_lbf, v.coastdown_B_lbf_per_mph,
                              v.coastdown_C_lbf_per_mph2, v.fuel) if cls else {t: np.nan for t in ("FTP", "HWFET", "US06")})
    return pd.DataFrame(rows)
