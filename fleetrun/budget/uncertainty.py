"""Ranges on fuel totals from the model's measured fuel-economy error.

The error distribution is measured, not assumed: ``models/fuel_economy_error.toml`` is
written by the fuel-economy validation (``validation/``, held-out vehicles of the EPA Test Car
List) and holds, per test (``FTP``, ``HWFET``, ``US06``), the relative error
``e = predicted mpg / measured mpg - 1`` and its 5th and 95th percentiles.

Arithmetic (docs/report.md, "Ranges"): gallons go as 1/mpg, so the measured gallons of a
vehicle whose predicted mpg is off by ``e`` are ``predicted gallons x (1 + e)``. A cycle's
range is its dynamometer gallons per mile x (1 + p05) and x (1 + p95), each then turned into
on-road fuel like the central value. A vehicle's range on a cycle mix is the share-weighted
sum. Fleet totals add the vehicles' lows and highs: the error is the model's own, shared by
every vehicle (fully correlated), so ranges add rather than shrink as sqrt(n).
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

from fleetrun.errors import InputError
from fleetrun.resources import models_dir

ERROR_FILE = "fuel_economy_error.toml"
# Which measured test stands for a drive cycle; other cycles by their kind (city / highway).
TEST_OF_CYCLE = {"FTP": "FTP", "UDDS": "FTP", "NYCC": "FTP", "HD-UDDS": "FTP", "FTP:BAG1": "FTP",
                 "FTP:BAG2": "FTP", "FTP:BAG3": "FTP", "HWFET": "HWFET", "US06": "US06"}
TEST_OF_KIND = {"city": "FTP", "highway": "HWFET"}


@dataclass(frozen=True)
class ErrorModel:
    """The measured relative mpg error per test: ``{test: {"p05": ..., "p95": ..., ...}}``."""
    source: str
    measured_on: str
    tests: dict
    path: str = ""

    def relative_range(self, cycle: str, kind: str) -> tuple[float, float]:
        """(p05, p95) of the relative mpg error for ``cycle`` (NaN when not measured)."""
        test = TEST_OF_CYCLE.get(Path(cycle).name.upper()) or TEST_OF_KIND.get(kind)
        entry = self.tests.get(test) or self.tests.get(TEST_OF_KIND.get(kind, ""))
        if not entry:
            return math.nan, math.nan
        return float(entry["p05"]), float(entry["p95"])

    def describe(self) -> str:
        parts = [f"{t}: 5-95 % {e['p05']:+.1%} to {e['p95']:+.1%} (n = {e.get('n', '?')})"
                 for t, e in sorted(self.tests.items())]
        return f"{self.source}; measured {self.measured_on}; " + "; ".join(parts)


def read_error_model(path: Path | None = None) -> ErrorModel | None:
    """The error distribution in ``path`` (default ``models/fuel_economy_error.toml``);
    None when the default file is absent (totals then carry no range, and the run says so)."""
    default = path is None
    path = Path(path) if path is not None else models_dir() / ERROR_FILE
    if default and not path.is_file():
        return None
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError("fuel-economy error file not found", file=path) from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"is not valid TOML ({exc})", file=path) from None
    tests = data.get("tests")
    if not isinstance(tests, dict) or not tests:
        raise InputError("has no [tests.<name>] tables", file=path,
                         hint="Write it with the fuel-economy validation script")
    for name, entry in tests.items():
        for key in ("p05", "p95"):
            value = entry.get(key) if isinstance(entry, dict) else None
            if not isinstance(value, (int, float)) or not -1.0 < value < 10.0:
                raise InputError(f"[tests.{name}] {key} must be a relative error above -1, got {value!r}",
                                 file=path)
        if entry["p05"] > entry["p95"]:
            raise InputError(f"[tests.{name}] p05 {entry['p05']} is above p95 {entry['p95']}", file=path)
    return ErrorModel(source=str(data.get("source", "")), measured_on=str(data.get("measured_on", "")),
                      tests=tests, path=str(path))
