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
