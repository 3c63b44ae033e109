"""Element-wise maximum and minimum against a constant, for the simulation's vehicles x steps arrays.

``np.maximum(x, 0.0)`` on a (V, N) float array runs numpy's loop for a scalar operand, which
is not vectorised (numpy 2.4: 33 us for 64 x 1,120 elements on the benchmark machine); the
same comparison against a (1, N) row filled with the constant runs the vector loop (18 us;
docs/benchmarks-simulation.md). Each element is compared the same way, NaN and signed zeros
included, so the results are the same bit for bit (tests/test_bounds.py checks it on
the edge values).
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

MIN_ROW = 64          # shorter rows (or other shapes and types): numpy's own scalar loop


@lru_cache(maxsize=64)
def _row(value: float, sign: float, n: int) -> np.ndarray:
    """A read-only (1, n) row of ``value`` (``sign`` keeps 0.0 and -0.0 apart in the cache)."""
    row = np.full((1, n), math.copysign(value, sign))
    row.flags.writeable = False
    return row


def _constant_like(x, value):
    """``value`` as a read-only (1, N) row when ``x`` is a (V, N) float64 array with long rows, else as given."""
    if isinstance(x, np.ndarray) and x.ndim == 2 and x.dtype == np.float64 and x.shape[1] >= MIN_ROW:
        value = float(value)
        return _row(value, math.copysign(1.0, value), x.shape[1])
    return value


def maximum(x, value, out=None):
    """``np.maximum(x, value, out=out)`` for a constant ``value``, the same bit for bit.

    Parameters
    ----------
    x : float or array, the values [any unit]
    value : float, the lower bound [the unit of ``x``]
    out : array or None, where to write the result (may be ``x``)

    Returns
    -------
    array, the element-wise maximum (``out`` if given).

    >>> maximum(np.array([[-1.0, 2.0]]), 0.0).tolist()
    [[0.0, 2.0]]
    """
    return np.maximum(x, _constant_like(x, value), out=out)


def minimum(x, value, out=None):
    """``np.minimum(x, value, out=out)`` for a constant ``value``, the same bit for bit.

    Parameters
    ----------
    x : float or array, the values [any unit]
    value : float, the upper bound [the unit of ``x``]
    out : array or None, where to write the result (may be ``x``)

    Returns
    -------
    array, the element-wise minimum (``out`` if given).

    >>> minimum(np.array([[-1.0, 2.0]]), 1.0).tolist()
    [[-1.0, 1.0]]
    """
    return np.minimum(x, _constant_like(x, value), out=out)
