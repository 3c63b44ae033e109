"""Where the real label route's HWFET misses come from and the global split F2 that `simulate`
applies to a label (validation/epa_label_sources.py; docs/validation-epa.md "Where the label
route's misses come from"), held out by manufacturer on the 899 Test Car List vehicles joined to
one real MY2022 label (fueleconomy.gov). Slow: the held-out simulation of the list (about 1 min)."""
from __future__ import annotations

import numpy as np
import pytest

from fleetrun.simulation import measured
from validation import epa_label_sources as els


@pytest.fixture(scope="module")
def setup():
    return els.load()


def _within(e, rows, j=1):
    x = e[rows, j]
    x = x[np.isfinite(x)]
    return float(np.mean(np.abs(x) <= 0.05))


@pytest.mark.slow
def test_the_chain_removes_rounding_inversion_and_configuration(setup):
    """Measured (22 folds): whole mpg 76.6 %, unrounded 78.0 %, the formula of the label's own
    UCity / UHighway 82.4 %, of the vehicle's own FTP / HWFET 89.4 % within 5 % on HWFET.
    Tolerance 1.5 points (13 of 899 vehicles) for small model changes; each step must gain."""
    s = setup
    shares = []
    for label in els.chain_labels(s).values():
        e, _ = s.route(els.share_tables(s.err, s.label_k(label)))["22 folds"]
        shares.append(_within(e, s.used))
    for got, want in zip(shares, (0.766, 0.780, 0.824, 0.894)):
        assert abs(got - want) <= 0.015
    assert shares[0] < shares[1] < shares[2] < shares[3] < 0.95


@pytest.mark.slow
def test_the_global_split_gains_on_the_highway_held_out(setup):
    """F2 (pre-registered): FTP / k, HWFET / k^h, US06 / k^s, (h, s) fitted on the other
    manufacturers. Measured HWFET 82.5 % against L1's 78.0 % (22 folds), US06 82.3 % both; the
    folds' h 0.55-0.60 (models/technology.toml stores 0.55). Rule: >= 1 point on HWFET, US06 not
    more than a point lower."""
    s = setup
    comb = s.cols.comb08U.to_numpy()
    base, _ = s.route(els.share_tables(s.err, s.label_k(comb)))["22 folds"]
    tables, grid = els.split_tables(s, comb)
    e, chosen = els.fit([np.where(s.used[:, None], t, np.nan) for t in tables], s.folds["22 folds"])
    assert _within(e, s.used) >= _within(base, s.used) + 0.03
    assert _within(e, s.used, 2) >= _within(base, s.used, 2) - 0.01
    hs = [grid[i][0] for i in chosen]
    assert min(hs) - 0.05 <= measured.label_split().highway_share <= max(hs) + 0.05 < 1.0


@pytest.mark.slow
def test_city_and_highway_figures_with_groups_meet_the_issue_line_as_simulate_applies_them(setup):
    """F5g as `simulate` applies it (`measured.cycle_factors`, the stored constants; in sample for
    the constants): measured HWFET 90.0 %, US06 84.8 %, FTP 91.2 % within 5 % (held out, (h, w, s)
    per fold: 89.2 / 84.8 %). Tolerance 1.5 points on HWFET (13 vehicles), 2.5 on US06 (4); the
    issue's line (88 / 78 %) and better than the combined figure alone (F2g, 86.8 %)."""
    s = setup
    e = els.stored_factors_errors(s, s.groups)
    assert abs(_within(e, s.used) - 0.900) <= 0.015 and _within(e, s.used) >= 0.88
    assert abs(_within(e, s.used, 2) - 0.848) <= 0.025 and _within(e, s.used, 2) >= 0.78
    assert _within(e, s.used, 0) >= 0.89
