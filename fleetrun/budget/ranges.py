"""The 90 % range of a forecast and the drivers' sensitivity, by Monte Carlo (docs/budget.md).

Per scenario, the central gallons of each fuel, duty class and budget year are perturbed by:

- the model's fleet-level error per duty class (:mod:`fleetrun.budget.uncertainty`: a
  manufacturer part a t (t Student or normal) plus a per-vehicle part b z, with the fleet's own
  scales a and b; one draw per duty class shared by both fuels and all years);
- VMT growth: the growth rate + N(0, sd) -> year y's miles x ((1 + g + d) / (1 + g))^(y-1);
- fuel price: ln(price) a random walk with sd per year, turned into gallons by the price
  response of :mod:`fleetrun.budget.drivers`;
- fleet mix: each fuel's miles x (1 + N(0, sd));
- where a fuel is calibrated to collections, the model error and the mix are replaced by the
  uncertainty of the observed gallons, and year 1's price is known (the base year is observed),
  so the calibrated range grows from the observed year onwards.

The same random numbers serve every scenario (a fixed seed: runs are reproducible, and
scenario differences are not blurred by sampling noise). The tornado evaluates the state
revenue of the budget period with one driver at its 5th or 95th percentile, the others central.
"""
from __future__ import annotations

import numpy as np

from dataclasses import dataclass

from fleetrun.budget import drivers
from fleetrun.budget.uncertainty import Z90, half_width, normal_cdf

DUTIES = ("LD", "HD")        # MD rows share the heavy-duty draw
DRIVERS = ("model_LD", "model_HD", "vmt_growth", "fuel_price", "fleet_mix", "observed_gallons")
DRIVER_LABELS = {"model_LD": "Fuel model, light duty", "model_HD": "Fuel model, medium/heavy duty",
                 "vmt_growth": "VMT growth", "fuel_price": "Fuel price (via elasticity)",
                 "fleet_mix": "Fleet mix", "observed_gallons": "Observed base-year gallons"}
MAX_YEARS = 50


@dataclass(frozen=True)
class YearRange:
    """The 90 % range of one total per budget year, relative to its centre (5th and 95th
    percentile / central)."""
    low: np.ndarray
    high: np.ndarray


def standard_normals(samples: int, seed: int) -> dict[str, np.ndarray]:
    """The draws every scenario shares: one column per driver (price: one per year)."""
    rng = np.random.default_rng(seed)
    return {"model_LD": rng.standard_normal(samples), "model_HD": rng.standard_normal(samples),
            "vmt_growth": rng.standard_normal(samples), "fuel_price": rng.standard_normal((samples, MAX_YEARS)),
            "fleet_mix": rng.standard_normal((samples, 2)), "observed_gallons": rng.standard_normal((samples, 2)),
            "maker_LD": rng.standard_normal(samples), "maker_HD": rng.standard_normal(samples)}


def gallons_draws(central: dict, z: dict, spec: dict) -> dict[str, np.ndarray]:
    """Per fuel: gallons (samples x years) under the draws ``z``.

    ``central[(fuel, duty)]``: central gallons per budget year; ``spec``: ``model_error[(fuel,
    duty)]`` = (a, b, df, DutyError) of :meth:`fleetrun.budget.uncertainty.DutyError.scales`, ``growth`` (fraction), ``years``, ``short``/``long`` elasticities, ``calibrated``
    fuels and the driver spreads ``u`` (models/budget.toml).
    """
    u, years = spec["u"], spec["years"]
    g = spec["growth"]
    y = np.arange(years)
    growth = ((1.0 + g + z["vmt_growth"][:, None] * u["vmt_growth_sd_pct_points"] / 100.0) / (1.0 + g)) ** y
    walk = np.cumsum(z["fuel_price"][:, :years] * u["fuel_price_log_sd_per_year"], axis=1)
    out = {}
    for f, fuel in enumerate(drivers.FUELS):
        parts = [(d, c) for (name, d), c in central.items() if name == fuel]
        if not parts:
            continue
        calibrated = fuel in spec["calibrated"]
        price = drivers.response_factor(walk - walk[:, :1] if calibrated else walk, spec["short"], spec["long"])
        total = np.zeros((len(z["vmt_growth"]), years))
        for duty, gallons in parts:
            if calibrated:
                level = 1.0 + z["observed_gallons"][:, f] * spec["observed_sd"]
            else:
                level = (1.0 + _model_error(z, duty, spec, fuel)) * (1.0 + z["fleet_mix"][:, f] * u["fleet_mix_relative_sd"])
            total += level[:, None] * np.asarray(gallons)[None, :]
        out[fuel] = total * growth * price
    return out


def _model_error(z: dict, duty: str, spec: dict, fuel: str) -> np.ndarray:
    """The relative model error of one fuel and duty class per draw: a t + b z (t from the
    shared normal draw through the t quantile function when df is finite); in the tornado
    (``spec["model_at"]``: +-1 per driver) its 5th / 95th percentile. A mixed heavy-duty error
    (``DutyError.components``): the share from the manufacturer draw, the spread from the other."""
    key = "model_LD" if duty == "LD" else "model_HD"
    a, b, df, error = spec["model_error"][(fuel, duty)]
    maker = z["maker_LD" if duty == "LD" else "maker_HD"]
    mixed = error is not None and bool(error.components)
    if "model_at" in spec:          # the tornado: none, or the 5th / 95th percentile
        sign = spec["model_at"].get(key, 0.0)
        if not sign:
            return np.zeros(len(z[key]))
        end = error.range90()[0 if sign < 0 else 1] if mixed else sign * float(half_width(a, b, df))
        return np.full(len(z[key]), end)
    if mixed:
        return error.mixture_error(normal_cdf(maker), z[key])
    if np.isfinite(df):
        from scipy import special      # a t effect only (the stored light-duty effect is normal)

        return a * special.stdtrit(df, normal_cdf(maker)) + b * z[key]
    t = maker
    return a * t + b * z[key]


def fuel_ranges(central: dict, z: dict, spec: dict) -> dict[str, YearRange]:
    """Per fuel: (low, high) / central gallons of each budget year (5th and 95th percentiles),
    and under ``"all"`` the same for the sum of the fuels."""
    draws = gallons_draws(central, z, spec)
    out = {}
    for fuel, samples in draws.items():
        centre = sum(np.asarray(c) for (name, _), c in central.items() if name == fuel)
        low, high = np.percentile(samples, [5, 95], axis=0)
        out[fuel] = YearRange(_ratio(low, centre), _ratio(high, centre))
    if draws:
        centre = sum(np.asarray(c) for c in central.values())
        low, high = np.percentile(sum(draws.values()), [5, 95], axis=0)
        out["all"] = YearRange(_ratio(low, centre), _ratio(high, centre))
    return out


@dataclass(frozen=True)
class PeriodRange:
    """The 90 % range of a scenario's budget-period totals (all fuels), relative to the centre:
    gallons, state and federal revenue (each its own 5th and 95th percentile)."""
    fuel_low: float
    fuel_high: float
    state_low: float
    state_high: float
    federal_low: float
    federal_high: float


def period_range(central: dict, z: dict, spec: dict, state: dict, federal: dict) -> PeriodRange:
    """Percentiles of the budget period's totals over fuels and years; ``state`` / ``federal``:
    each fuel's rate per budget year [$/gal]."""
    draws = gallons_draws(central, z, spec)
    out = {}
    for name, rates in (("fuel", None), ("state", state), ("federal", federal)):
        samples = sum((d * (1.0 if rates is None else rates[f][None, :])).sum(axis=1) for f, d in draws.items())
        centre = sum((np.asarray(c) * (1.0 if rates is None else rates[f])).sum() for (f, _), c in central.items())
        if not draws or centre <= 0:
            out[f"{name}_low"] = out[f"{name}_high"] = 1.0
            continue
        low, high = np.percentile(samples, [5, 95])
        out[f"{name}_low"], out[f"{name}_high"] = float(low / centre), float(high / centre)
    return PeriodRange(**out)


def _ratio(value, centre):
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(centre > 0, value / centre, 1.0)


def tornado(central: dict, spec: dict, state_rates: dict) -> list[dict]:
    """State revenue of the budget period with each driver at its 5th / 95th percentile (-/+
    1.645 sd; the model error's own percentiles) and the others at their centre (the model
    error at none): one row per driver that moves anything."""
    base_z = {k: np.zeros((1,) + v.shape[1:]) for k, v in standard_normals(1, 0).items()}

    def revenue(z, model_at=None):
        draws = gallons_draws(central, z, {**spec, "model_at": model_at or {}})
        return float(sum((draws[f][0] * state_rates[f]).sum() for f in draws))

    centre = revenue(base_z)
    rows = []
    for name in DRIVERS:
        ends = []
        for sign in (-1.0, 1.0):
            z = {k: v.copy() for k, v in base_z.items()}
            if name.startswith("model_"):
                ends.append(revenue(z, {name: sign}))
                continue
            z[name] = z[name] + sign * Z90
            ends.append(revenue(z))
        if abs(ends[1] - ends[0]) > 1e-9 * max(abs(centre), 1.0):
            rows.append({"driver": DRIVER_LABELS[name], "low_usd": min(ends), "high_usd": max(ends),
                         "central_usd": centre})
    return sorted(rows, key=lambda r: r["low_usd"] - r["high_usd"])
