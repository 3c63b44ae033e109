"""The model's fleet-level fuel error, measured on held-out data (docs/budget.md, "Ranges").

A fleet total's relative error (measured / predicted gallons - 1) is modelled as

    E = bias + sum_m (w_m - W_m) u_m + sum_i g_i eps_i,
    u_m ~ N(0, tau^2) per manufacturer, eps_i ~ N(0, sigma^2) per vehicle type,

with ``g_i`` a vehicle type's share of the fleet's predicted gallons, ``w_m`` a manufacturer's
share in the fleet and ``W_m`` in the market the constants were measured on (the EPA list).
The known ``bias`` is corrected in the centre (gallons x (1 + bias)); the spread is

    sd(E) = sqrt(tau^2 D + sigma^2 sum_i g_i^2),  D = sum_m (w_m - W_m)^2,

and where the fleet's manufacturers are not known (rows without ``make`` / ``manufacturer``),
``D = (1 - sum_m W_m^2) sum_i g_i^2``: the expected D of vehicle types drawn from the market.

The constants are data: ``models/fleet_error.toml`` (written by validation/fleet_error.py from
the manufacturer-held-out EPA predictions); the light-duty centre uses the fleet-level bias of
``models/fuel_economy_bias.toml`` where that file exists (the light-duty fuel-economy work
writes it: ``gallons_bias`` = predicted / measured - 1). Heavy-duty rows use
``models/heavy_duty/fuel_economy_error.toml`` where it exists, otherwise the light-duty
constants with a warning.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fleetrun.errors import InputError
from fleetrun.resources import models_dir

ERROR_FILE = "fleet_error.toml"
BIAS_FILE = "fuel_economy_bias.toml"
HEAVY_FILE = Path("heavy_duty") / "fuel_economy_error.toml"
Z90 = 1.6448536269514722     # standard normal 95th percentile: a central 90 % range


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

    def relative_sd(self, gallons, makers=None) -> float:
        """sd of the relative error of the total of ``gallons`` (one entry per vehicle type);
        ``makers``: each row's manufacturer or make (None / blanks: unknown make-up)."""
        gallons = np.asarray(gallons, dtype=float)
        total = gallons.sum()
        if total <= 0:
            return 0.0
        g = gallons / total
        per_vehicle = float((g ** 2).sum())
        d = 1.0 if self.shared else self._make_up(g, makers)
        if d is None:
            d = (1.0 - sum(v ** 2 for v in self.market_share.values())) * per_vehicle
        return math.sqrt(self.tau ** 2 * d + self.sigma ** 2 * per_vehicle)

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
        return float(sum((share.get(m, 0.0) - self.market_share.get(m, 0.0)) ** 2 for m in everyone))


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
        parts = [f"light duty: bias {light.bias:+.2%} corrected in the centre, between manufacturers "
                 f"{light.tau:.1%}, per vehicle type {light.sigma:.1%} ({light.source}"
                 + (f"; {light.note}" if light.note else "") + ")"]
        heavy = self.duty.get("HD")
        if heavy is light:
            parts.append("medium and heavy duty: the light-duty constants (no heavy-duty error measured)")
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
    bias = float(table["bias"]) if bias_override is None else bias_override
    return DutyError(bias=bias, tau=float(table["tau"]), sigma=float(table["sigma"]),
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
    mpg - 1 (mean, p05, p95). From the latter no centre correction is made (a handful of
    reference vehicles against their standards, not measured fleets): each test's mean error
    and spread become one sd, sqrt(mean^2 + ((p95 - p05) / 3.29)^2), the root mean square over
    the tests, all of it treated as shared by the fleet (tau = sd; no manufacturer split)."""
    path = models / HEAVY_FILE
    if not path.is_file():
        return None
    data = _read_toml(path)
    if isinstance(data.get("fleet"), dict):
        return _duty_error(data["fleet"], path, "fleet")
    tests = [t for t in (data.get("tests") or {}).values() if isinstance(t, dict) and "p05" in t and "p95" in t]
    if not tests:
        raise InputError("has neither [fleet] nor [tests.*] with p05/p95", file=path)
    sd = math.sqrt(float(np.mean([t.get("mean", 0.0) ** 2 + ((t["p95"] - t["p05"]) / (2 * Z90)) ** 2
                                  for t in tests])))
    return DutyError(bias=0.0, tau=sd, sigma=0.0, source=str(data.get("source", path.name)),
                     note="per-test errors against reference values; no centre correction", shared=True)


def read_error_model(path: Path | None = None) -> ErrorModel | None:
    """The fleet-level error constants in ``path`` (default ``models/fleet_error.toml``); None
    when the default file is absent (totals then carry only the drivers' range, and say so)."""
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
