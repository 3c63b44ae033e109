"""The speed devices of the simulation kernel change no number: ``bounds.maximum`` /
``bounds.minimum`` against numpy's own maximum / minimum with a scalar, and ``core.row_buffers``
(numpy's ufunc buffer sized to a row) against the default buffer, bit for bit on the edge
values (signed zeros, NaN, infinities, subnormals), in both argument shapes the kernel uses.
Reference: numpy itself (the operations they replace), so the tolerance is zero.
"""
from __future__ import annotations

import numpy as np
import pytest

from fleetrun.simulation import bounds
from fleetrun.simulation.core import row_buffers

EDGES = np.array([-0.0, 0.0, np.nan, -np.nan, np.inf, -np.inf, -1.0, 1.0, 5e-324, -5e-324, 1e-9, -1e-9, 2.0])


@pytest.mark.parametrize("value", [0.0, -0.0, 1e-9, 1.0, np.inf, -np.inf])
@pytest.mark.parametrize("steps", [80, 1120])
def test_bounds_equal_numpys_scalar_maximum_and_minimum_bit_for_bit(value, steps):
    x = np.resize(EDGES, (7, steps))
    for fast, ref in ((bounds.maximum, np.maximum), (bounds.minimum, np.minimum)):
        with row_buffers(steps):
            got = fast(x, value)
            inplace = x.copy()
            fast(inplace, value, out=inplace)
        assert got.tobytes() == ref(x, value).tobytes()
        assert inplace.tobytes() == ref(x, value).tobytes()


def test_bounds_keep_other_shapes_and_types():
    assert bounds.maximum(-3.0, 0.0) == 0.0
    assert bounds.minimum(np.array([1, 5]), 2).tolist() == [1, 2]


def test_row_buffers_change_no_element_and_restore_the_buffer():
    rng = np.random.default_rng(0)
    a, col, row = rng.normal(size=(64, 1120)), rng.normal(size=(64, 1)), rng.normal(size=(1, 1120))
    before = np.getbufsize()
    expected = [a * col, col * row, np.maximum(a, col), (a * row).sum(axis=1), np.clip(a, 0.0, col)]
    with row_buffers(1120):
        assert np.getbufsize() == 1120
        got = [a * col, col * row, np.maximum(a, col), (a * row).sum(axis=1), np.clip(a, 0.0, col)]
    assert np.getbufsize() == before
    assert all(g.tobytes() == e.tobytes() for g, e in zip(got, expected))
