"""The model's fleet-level fuel error, measured on held-out data (docs/budget.md, "Ranges").

A fleet total's relative error (measured / predicted gallons - 1) is modelled as

    E = bias + sum_m (w_m - W_m) u_m + sum_i g_i eps_i,
    u_m = tau_m t_m, t_m ~ Student t (df degrees of freedom; df = inf: normal) per manufacturer,
    tau_m^2 = tau^2 (W_m / share_ref)^-2gamma + tau_size^2 share_ref / W_m, eps_i ~ N(0, sigma^2)
    per vehicle type,

with ``g_i`` a vehicle type's share of the fleet's predicted gallons, ``w_m`` a manufacturer's
share in the fleet and ``W_m`` in the market the constants were measured on (the EPA list).
The known ``bias`` is corrected in the centre (gallons x (1 + bias)); the spread has two parts,

    E - bias = a t + b z,  a = sqrt(D),  b = sigma sqrt(sum_i g_i^2),
    D = sum_m (w_m - W_m)^2 tau_m^2,

(the manufacturers' sum of t terms taken as one t of scale a: exact for a fleet of one
manufacturer, which is where the tails matter), z standard normal,

and where the fleet's manufacturers are not known (rows without ``make`` / ``manufacturer``),
``D = sum_i g_i^2 sum_m W_m (1 - W_m) tau_m^2``: the expected D of vehicle types drawn
from the market.

The stored light-duty effect is normal (sums of manufacturers exact) with ``tau_size`` > 0 and
gamma = 0: a part every manufacturer shares (tau) and a part that averages out over a larger
manufacturer's many engine families and models, its variance inversely proportional to the
manufacturer's share (docs/budget.md, "Ranges").

The constants are data: ``models/fleet_error.toml`` (written by validation/fleet_error.py from
the manufacturer-held-out EPA predictions); the light-duty centre uses the fleet-level bias of
``models/fuel_economy_bias.toml`` where that file exists (the light-duty fuel-economy work
writes it: ``gallons_bias`` = predicted / measured - 1). Heavy-duty rows use
``models/heavy_duty/fuel_economy_error.toml`` where it exists, otherwise the light-duty
constants with a warning. Heavy-duty errors given per test (tractor, vocational) are mixed by
an unknown share of each (:func:`_heavy`).
"""
from __future__ import annotations

import math
import statistics
import tomllib
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from fleetrun.errors import InputError
from fleetrun.resources import models_dir

ERROR_FILE = "fleet_error.toml"
BIAS_FILE = "fuel_economy_bias.toml"
HEAVY_FILE = Path("heavy_duty") / "fuel_economy_error.toml"
Z90 = 1.6448536269514722     # standard normal 95th percentile: a central 90 % range
_GRID = 2000                 # quantile points of t in the convolution (half_width_factor)
_NORMAL = statistics.NormalDist()


def normal_cdf(x) -> np.ndarray:
    """The standard normal distribution function, elementwise (no scipy on the run's path).

    Parameters
    ----------
    x : float or array, standard normal variate [-]

    Returns
    -------
    Phi(x) [-], the shape of ``x``.
    """
    return 0.5 * (1.0 + np.vectorize(math.erf, otypes=[float])(np.asarray(x, dtype=float) / math.sqrt(2.0)))


@lru_cache(maxsize=64)
def _factor_table(df: float, p: float) -> tuple[np.ndarray, np.ndarray]:
    """q(rho) on a grid of rho = a / sqrt(a^2 + b^2): the p-quantile of (a t_df + b z) / sqrt(a^2 + b^2)."""
    from scipy import special      # only for a finite df (the stored light-duty effect is normal)

    t = special.stdtrit(df, (np.arange(_GRID) + 0.5) / _GRID)
    rho = np.linspace(0.0, 1.0, 201)
    q = np.empty_like(rho)
    for k, r in enumerate(rho):
        a, b = r, math.sqrt(max(0.0, 1.0 - r * r))
        if b < 1e-9:
            q[k] = float(special.stdtrit(df, p))
            continue
        lo, hi = 0.0, float(special.stdtrit(df, p)) + Z90 + 1.0
        for _ in range(60):                      # bisection on P(a t + b z <= x) = p
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if special.ndtr((mid - a * t) / b).mean() < p else (lo, mid)
        q[k] = 0.5 * (lo + hi)
    return rho, q


def half_width(a, b, df: float = math.inf, p: float = 0.95):
    """The p-quantile of a t_df + b z (t Student, z normal, independent; symmetric, so the central
    range of 2p - 1 is +- this); ``a``, ``b`` scalars or arrays. Normal (df = inf): sqrt(a^2 + b^2) z_p;
    otherwise the convolution over 2,000 quantile points of t, tabulated in rho = a / sqrt(a^2 + b^2).

    Parameters
    ----------
    a : float or array, scale of the t term [any unit]
    b : float or array, scale of the normal term [the unit of a]
    df : float, degrees of freedom of t [-] (inf: normal)
    p : float, the quantile [-]

    Returns
    -------
    half-width [the unit of a], the broadcast shape of ``a`` and ``b``.
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    norm = np.hypot(a, b)
    if not math.isfinite(df):
        return norm * _NORMAL.inv_cdf(p)
    rho, q = _factor_table(float(df), float(p))
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(norm > 0, a / norm, 0.0)
    return norm * np.interp(ratio, rho, q)


@dataclass(frozen=True)
class DutyError:
    """The fleet-level error constants of one duty class."""
    bias: float
    tau: float
    sigma: float
    market_share: dict = field(default_factory=dict)
    makes: dict = field(default_factory=dict)
    source: str = ""
    note: str = ""
    shared: bool = False        # tau shared by every vehicle (no manufacturer make-up measured)
    df: float = math.inf        # degrees of freedom of the manufacturer effect (inf: normal)
    share_exponent: float = 0.0  # gamma: a manufacturer's effect scale is tau (W_m / share_ref)^-gamma
    share_ref: float = 0.01
    tau_size: float = 0.0       # plus an effect of variance tau_size^2 share_ref / W_m (averages out with size)
    size_share: dict = field(default_factory=dict)  # shares that size the effects, if not market_share's
    components: tuple = ()      # shared (mean, sd) per test, mixed by an unknown share (heavy duty)

    def mixture_error(self, uniform, normal):
        """Relative error draws of a total under :attr:`components`: mean interpolated between the
        components' means at ``uniform`` (a share in 0-1), sd likewise, times ``normal``."""
        means, sds = np.array(self.components, dtype=float).T
        knots = np.linspace(0.0, 1.0, len(means)) if len(means) > 1 else np.zeros(1)
        return np.interp(uniform, knots, means) + np.interp(uniform, knots, sds) * normal

    def range90(self, gallons=(1.0,), makers=None) -> tuple[float, float]:
        """5th and 95th percentile of the relative error of a total about its centre."""
        if self.components:
            grid = (np.arange(400) + 0.5) / 400
            u, z = np.meshgrid(grid, [_NORMAL.inv_cdf(q) for q in grid])
            low, high = np.quantile(self.mixture_error(u.ravel(), z.ravel()), [0.05, 0.95])
            return float(low), float(high)
        h = self.half_width90(gallons, makers)
        return -h, h

    def effect_variance(self, maker: str) -> float:
        """tau_m^2, the variance (squared scale) of a manufacturer's effect: tau^2 (W_m /
        share_ref)^-2gamma + tau_size^2 share_ref / W_m, W_m its market share (unknown to the
        market or below its smallest share: the smallest share)."""
        if not self.share_exponent and not self.tau_size:
            return self.tau ** 2
        sizes = self.size_share or self.market_share
        floor = min(sizes.values())
        share = max(sizes.get(maker, floor), floor)
        return self.tau ** 2 * (share / self.share_ref) ** (-2 * self.share_exponent) + self.tau_size ** 2 * self.share_ref / share

    def scales(self, gallons, makers=None) -> tuple[float, float]:
        """(a, b): the scales of the manufacturer part (t) and the per-vehicle part (normal) of
        the relative error of the total of ``gallons`` (one entry per vehicle type);
        ``makers``: each row's manufacturer or make (None / blanks: unknown make-up)."""
        gallons = np.asarray(gallons, dtype=float)
        total = gallons.sum()
        if total <= 0:
            return 0.0, 0.0
        g = gallons / total
        per_vehicle = float((g ** 2).sum())
        d = self.tau ** 2 if self.shared else self._make_up(g, makers)
        if d is None:      # types drawn from the market: E (w_m - W_m)^2 = W_m (1 - W_m) sum g^2
            d = sum(w * (1.0 - w) * self.effect_variance(m) for m, w in self.market_share.items()) * per_vehicle
        return math.sqrt(d), self.sigma * math.sqrt(per_vehicle)

    def half_width90(self, gallons, makers=None) -> float:
        """Half the 90 % range of the relative error of the total (about the bias)."""
        return float(half_width(*self.scales(gallons, makers), self.df))

    def manufacturer_of(self, name) -> str | None:
        """The list's manufacturer of a make or manufacturer name (None when blank)."""
        if name is None or (isinstance(name, float) and math.isnan(name)) or not str(name).strip():
            return None
        key = str(name).strip()
        if key in self.market_share:
            return key
        return self.makes.get(key.upper(), key)

    def _make_up(self, g: np.ndarray, makers) -> float | None:
        if makers is None:
            return None
        names = [self.manufacturer_of(m) for m in makers]
        if any(n is None for n in names):
            return None
        share: dict[str, float] = {}
        for name, part in zip(names, g):
            share[name] = share.get(name, 0.0) + float(part)
        everyone = set(share) | set(self.market_share)
        return float(sum((share.get(m, 0.0) - self.market_share.get(m, 0.0)) ** 2 * self.effect_variance(m)
                         for m in everyone))


@dataclass(frozen=True)
class ErrorModel:
    """The fleet-level error per duty class (``LD``, ``MD``, ``HD``) and where it comes from."""
    duty: dict
    path: str = ""
    warnings: tuple = ()

    def for_duty(self, duty_class: str) -> DutyError:
        return self.duty.get(duty_class) or self.duty["LD"]

    def describe(self) -> str:
        light = self.duty["LD"]
        effect = f"Student t, {light.df:g} degrees of freedom, scale" if math.isfinite(light.df) else "sd"
        size = (f" plus {light.tau_size:.1%} at {light.share_ref:.0%} of the market, shrinking with the "
                "square root of a manufacturer's share" if light.tau_size else "")
        parts = [f"light duty: bias {light.bias:+.2%} corrected in the centre, between manufacturers "
                 f"{effect} {light.tau:.1%}{size}, per vehicle type {light.sigma:.1%} ({light.source}"
                 + (f"; {light.note}" if light.note else "") + ")"]
        heavy = self.duty.get("HD")
        if heavy is light:
            parts.append("medium and heavy duty: the light-duty constants (no heavy-duty error measured)")
        elif heavy is not None and heavy.components:
            low, high = heavy.range90()
            parts.append("medium and heavy duty: no centre correction; measured / modelled gallons between "
                         + " and ".join(f"{m:+.1%} (sd {sd:.1%})" for m, sd in heavy.components)
                         + f" on the reference vehicles, mixed by an unknown share: 90 % range {low:+.0%} to {high:+.0%}"
                         + f" ({heavy.source})")
        elif heavy is not None:
            parts.append(f"medium and heavy duty: bias {heavy.bias:+.2%}, shared sd {heavy.tau:.1%}"
                         + (f", per vehicle type {heavy.sigma:.1%}" if heavy.sigma else "")
                         + f" ({heavy.source}" + (f"; {heavy.note}" if heavy.note else "") + ")")
        return "; ".join(parts)


def _read_toml(path: Path) -> dict:
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError("fleet error file not found", file=path) from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"is not valid TOML ({exc})", file=path) from None


def _duty_error(table, path: Path, name: str, bias_override: float | None = None) -> DutyError:
    if not isinstance(table, dict):
        raise InputError(f"has no [{name}] table", file=path, hint="Write it with validation/fleet_error.py fit --write")
    for key in ("bias", "tau", "sigma"):
        value = table.get(key)
        if not isinstance(value, (int, float)) or not -0.5 < value < 1.0 or (key != "bias" and value < 0):
            raise InputError(f"[{name}] {key} must be a relative error (0 to 1; bias above -0.5), got {value!r}",
                             file=path)
    df = table.get("df", math.inf)
    if not isinstance(df, (int, float)) or not df >= 1:
        raise InputError(f"[{name}] df (degrees of freedom of the manufacturer effect) must be 1 or more "
                         f"(inf: normal), got {df!r}", file=path)
    bias = float(table["bias"]) if bias_override is None else bias_override
    gamma, ref = table.get("share_exponent", 0.0), table.get("share_ref", 0.01)
    if not isinstance(gamma, (int, float)) or not 0 <= gamma <= 2 or not isinstance(ref, (int, float)) or not 0 < ref <= 1:
        raise InputError(f"[{name}] share_exponent must be 0-2 and share_ref a share (0-1], got {gamma!r}, {ref!r}",
                         file=path)
    tau_size = table.get("tau_size", 0.0)
    if not isinstance(tau_size, (int, float)) or not 0 <= tau_size < 1:
        raise InputError(f"[{name}] tau_size must be a relative error (0 to 1), got {tau_size!r}", file=path)
    return DutyError(bias=bias, tau=float(table["tau"]), sigma=float(table["sigma"]), df=float(df),
                     share_exponent=float(gamma), share_ref=float(ref), tau_size=float(tau_size),
                     market_share={str(k): float(v) for k, v in table.get("market_share", {}).items()},
                     makes={str(k).upper(): str(v) for k, v in table.get("makes", {}).items()},
                     source=str(table.get("source", path.name)),
                     note="" if bias_override is None else f"bias from {BIAS_FILE}")


def _bias_of(models: Path) -> float | None:
    """measured / predicted - 1 from ``models/fuel_economy_bias.toml`` (``gallons_bias`` is
    predicted / measured - 1), None without the file."""
    path = models / BIAS_FILE
    if not path.is_file():
        return None
    value = _read_toml(path).get("gallons_bias")
    if not isinstance(value, (int, float)) or not -0.5 < value < 1.0:
        raise InputError(f"gallons_bias must be a relative error, got {value!r}", file=path)
    return 1.0 / (1.0 + float(value)) - 1.0


def _heavy(models: Path) -> DutyError | None:
    """Heavy-duty constants from ``models/heavy_duty/fuel_economy_error.toml``: a ``[fleet]``
    table with bias/tau/sigma, or per-test ``[tests.*]`` distributions of predicted / reference
    mpg - 1 (mean, p05, p95; docs/validation-heavy-duty.md), which is measured / predicted
    gallons - 1 of a vehicle at its reference. From the latter the error of an MD/HD total is
    a mix of the tests (:meth:`DutyError.mixture_error`): a fleet's share of each kind
    (tractor / vocational) is not known from its rows, so a share s ~ U(0, 1) moves the mean
    between the tests' means (sorted), and each test's own spread (p95 - p05) / 3.29 the rest;
    no centre correction (reference vehicles against their standards, not measured fleets).
    A known one-sided miss thus widens the range on its own side only."""
    path = models / HEAVY_FILE
    if not path.is_file():
        return None
    data = _read_toml(path)
    if isinstance(data.get("fleet"), dict):
        return _duty_error(data["fleet"], path, "fleet")
    tests = [t for t in (data.get("tests") or {}).values() if isinstance(t, dict) and "p05" in t and "p95" in t]
    if not tests:
        raise InputError("has neither [fleet] nor [tests.*] with p05/p95", file=path)
    parts = sorted((float(t.get("mean", 0.5 * (t["p05"] + t["p95"]))), (t["p95"] - t["p05"]) / (2 * Z90)) for t in tests)
    return DutyError(bias=0.0, tau=0.0, sigma=0.0, source=str(data.get("source", path.name)), shared=True,
                     components=tuple(parts),
                     note="per-test errors against reference values, mixed by an unknown share; no centre correction")


def read_error_model(path: Path | None = None) -> ErrorModel | None:
    """The fleet-level error constants in ``path`` (default ``models/fleet_error.toml``); None
    when the default file is absent (totals then carry only the drivers' range, and say so).

    Parameters
    ----------
    path : Path or None, the error file (None: ``models/fleet_error.toml``)

    Returns
    -------
    ErrorModel or None, the fleet-level error per duty class.
    """
    models = models_dir()
    default = path is None
    path = Path(path) if path is not None else models / ERROR_FILE
    if default and not path.is_file():
        return None
    data = _read_toml(path)
    light = _duty_error(data.get("LD"), path, "LD", _bias_of(models) if default else None)
    duty = {"LD": light}
    warnings = []
    heavy = _duty_error(data["HD"], path, "HD") if isinstance(data.get("HD"), dict) else (
        _heavy(models) if default else None)
    if heavy is None:
        warnings.append("MD/HD ranges use the light-duty fleet error: no heavy-duty error file "
                        f"(models/{HEAVY_FILE.as_posix()})")
        heavy = light
    duty["MD"] = duty["HD"] = heavy
    return ErrorModel(duty=duty, path=str(path), warnings=tuple(warnings))
