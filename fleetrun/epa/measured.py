"""The measured fuel economy of one vehicle configuration from its test rows.

Tests (docs/interface.md): ``FTP`` (the composite, `RND_ADJ_FE` of an FTP-75 row), ``FTP:bag1..3``
(`FE Bag 1..3` of the FTP rows), ``HWFET`` (`HWFE`) and ``US06``. Only rows on the vehicle's
own fuel count, and values at or above ``[measured] max_valid_mpg`` (placeholders such as
10000) or not above 0 are ignored, and so are analytically derived values (`Analytically
Derived FE?` = Yes, ``[measured] analytically_derived``): EPA's estimate, from another test,
for a configuration whose weight, N/V or road load differ from the facts on the row, not a
measurement of the vehicle the row describes. Several rows of one test (repeats, 2-day and 3-day FTP
runs) give one value: their harmonic mean, i.e. the mean fuel per mile.
"""
from __future__ import annotations

from fleetrun.epa import rules

BAG_TESTS = ("FTP:bag1", "FTP:bag2", "FTP:bag3")
BAG_FIELDS = ("fe_bag1", "fe_bag2", "fe_bag3")


def harmonic_mean(values) -> float:
    """Harmonic mean: the fuel economy of equal distances driven at each value."""
    values = list(values)
    return len(values) / sum(1.0 / v for v in values)


def _valid(value) -> bool:
    return value is not None and 0 < value < rules.constants()["measured"]["max_valid_mpg"]


def measured_results(rows: list[dict], fuel: str) -> list[dict]:
    """One dict per test measured on ``fuel``: test, mpg, n_tests, test_numbers, procedure, csv_rows."""
    out = []
    derived = {str(v).lower() for v in rules.constants()["measured"]["analytically_derived"]}
    own = [r for r in rows if r["fuel"] == fuel and r["test"]
           and str(r.get("analytically_derived") or "").lower() not in derived]
    for test in ("FTP", "HWFET", "US06"):
        these = [r for r in own if r["test"] == test]
        _append(out, test, these, "fe_mpg")
        if test == "FTP":
            for bag, name in zip(BAG_TESTS, BAG_FIELDS):
                _append(out, bag, these, name)
    return out


def _append(out: list, test: str, rows: list[dict], field: str) -> None:
    used = [r for r in rows if _valid(r.get(field))]
    if not used:
        return
    out.append({"test": test, "mpg": round(harmonic_mean(r[field] for r in used), 4), "n_tests": len(used),
                "test_numbers": ";".join(r.get("test_number") or "" for r in used if r.get("test_number")),
                "procedure": "; ".join(dict.fromkeys(r["procedure"] for r in used)),
                "csv_rows": ",".join(str(r["csv_row"]) for r in used)})
