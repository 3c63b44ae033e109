"""results.csv's writer (fleetrun.run.outputs.write_csv) formats column by column for speed;
its bytes must be exactly those of pandas.DataFrame.to_csv(index=False), the writer it
replaced (docs/report.md: numbers in Python's shortest round-trip repr), so the golden files
and every reader see no change."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from fleetrun.run import outputs


def _frame(n: int = 2_000) -> pd.DataFrame:
    rng = np.random.default_rng(7)
    floats = rng.standard_normal(n) * 10.0 ** rng.integers(-30, 30, n)
    floats[::17] = np.nan
    floats[:8] = [0.0, -0.0, 1e16, 1e15, 1e-5, 1e-4, 5e-324, 1.7976931348623157e308]
    texts = np.array(["plain", "with, comma", 'a "quote"', "line\nbreak", "cr\rhere", "", "=1+2", "ünï"] * n,
                     dtype=object)[:n]
    texts[5] = None
    return pd.DataFrame({"scenario_id": ["baseline"] * n, "label": texts, "count": rng.integers(0, 10**9, n),
                         "miles_total": rng.integers(0, 10**6, n).astype(float), "value": floats,
                         "mpg": np.where(np.arange(n) % 5 == 0, math.nan, 25.5)})


def test_bytes_equal_pandas_to_csv(tmp_path, monkeypatch):
    frame = _frame()
    monkeypatch.setattr(outputs, "CSV_CHUNK_ROWS", 333)   # several chunks, one of them short
    outputs.write_csv(frame, tmp_path / "fast.csv")
    expected = frame.copy()
    expected["label"] = expected["label"].where(~expected["label"].fillna("").str.startswith("="),
                                                "'" + expected["label"].fillna(""))
    expected.to_csv(tmp_path / "pandas.csv", index=False)
    assert (tmp_path / "fast.csv").read_bytes() == (tmp_path / "pandas.csv").read_bytes()


def test_other_column_kinds_go_through_pandas(tmp_path):
    frame = pd.DataFrame({"when": pd.to_datetime(["2026-01-01", "2026-07-01"]), "x": [1.5, 2.0]})
    outputs.write_csv(frame, tmp_path / "a.csv")
    frame.to_csv(tmp_path / "b.csv", index=False)
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()


def test_nullable_integers_written_as_pandas_writes_them(tmp_path):
    frame = pd.DataFrame({"model_year": pd.array([2019, None, 2024], dtype="Int64"), "x": [1.0, math.nan, 3.25],
                          "label": ["a", None, "b"]})
    outputs.write_csv(frame, tmp_path / "a.csv")
    frame.to_csv(tmp_path / "b.csv", index=False)
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()


def test_float_texts_are_python_repr_over_the_range_of_doubles():
    """The float fields come from Arrow's cast where it writes no exponent (outputs._float_texts);
    they must be Python's own repr, character for character, for any double: random bit patterns
    (every exponent, subnormals, inf, NaN), repr's no-exponent range 1e-4..1e16 on a log scale,
    short decimals, whole numbers up to 2^53 and the neighbours of powers of 10 and 2, where
    the shortest digits and the notation switch."""
    rng = np.random.default_rng(17)
    n = 40_000
    bits = rng.integers(0, 2**63, n, dtype=np.uint64) | (rng.integers(0, 2, n, dtype=np.uint64) << np.uint64(63))
    powers = np.concatenate([10.0 ** np.arange(-6, 18), 2.0 ** np.arange(-20, 60)])
    samples = [bits.view(np.float64),
               np.where(rng.random(n) < 0.5, -1.0, 1.0) * 10.0 ** rng.uniform(-5, 16.5, n),
               np.round(rng.uniform(0, 1e6, n), 3), rng.integers(-2**53, 2**53, n).astype(float),
               rng.integers(1, 10**6, n).astype(float) * 10.0 ** rng.integers(-12, 12, n),
               np.concatenate([powers, np.nextafter(powers, 0), np.nextafter(powers, np.inf), -powers,
                               [0.0, -0.0, np.nan, np.inf, -np.inf, 5e-324]]),
               np.zeros(n)]
    for values in samples:
        expected = ["" if math.isnan(x) else repr(x) for x in values.tolist()]
        assert outputs._column_texts(pd.Series(values)) == expected


def test_text_columns_of_pandas_string_dtype(tmp_path):
    """A string-dtype column of plain texts is written as it is (outputs._column_texts' fast
    path); one with a comma, a quote, a line break or a missing value goes cell by cell: both as
    pandas writes them."""
    frame = pd.DataFrame({"plain": pd.array(["a", "b c", "", "ünï"] * 3, dtype="str"),
                          "comma": pd.array(["x", "y, z", 'q"', "r"] * 3, dtype="str"),
                          "missing": pd.array(["x", None, "y", "z"] * 3, dtype="str"),
                          "value": [1.5] * 12})
    outputs.write_csv(frame, tmp_path / "fast.csv")
    frame.to_csv(tmp_path / "pandas.csv", index=False)
    assert (tmp_path / "fast.csv").read_bytes() == (tmp_path / "pandas.csv").read_bytes()
