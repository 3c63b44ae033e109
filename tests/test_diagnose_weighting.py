"""Noise-weighted windows (fleetrun.diagnose.weighting) and hot-start declarations of a joint
diagnosis (fleetrun.diagnose.joint.without_warmup).

Generated problems with a known answer: a residual whose noise grows with the reference's
fuel (as the same-trace residual of the Argonne Camry pair does, 0.024 g/s at idle against
0.09 g/s driving, docs/diagnose-realdata.md 1b), and an effect that acts at idle too.
"""
import numpy as np
import pytest

from fleetrun.diagnose.engine import IntegralSpec, Problem, Settings, select
from fleetrun.diagnose.joint import join, join_coarse, without_warmup
from fleetrun.diagnose.select import Candidate
from fleetrun.diagnose.weighting import MIN_SCALE_SHARE, noise_weighted, noise_weights, reweighted
from fleetrun.errors import InputError

N = 2000


def test_weights_follow_the_inverse_noise_variance():
    # noise sd 0.02 + 0.05 x level over levels 0.1-2: the weights at the lowest and the highest
    # bin's median level must stand as the inverse variances there. With 800 samples a bin
    # the scale's relative standard error is 1.166 / sqrt(800) = 4 %, a variance ratio's about
    # 12 %; the bins' spread of level adds a few per cent: 20 %.
    rng = np.random.default_rng(0)
    level = rng.uniform(0.1, 2.0, 4000)
    sd = 0.02 + 0.05 * level
    w = noise_weights(rng.normal(0.0, sd), level, np.ones(4000, bool))
    assert w.mean() == pytest.approx(1.0)
    lo, hi = np.argmin(np.abs(level - np.quantile(level, 0.1))), np.argmin(np.abs(level - np.quantile(level, 0.9)))
    assert w[lo] / w[hi] == pytest.approx((sd[hi] / sd[lo]) ** 2, rel=0.2)


def test_a_silent_bin_is_floored_and_inactive_samples_keep_weight_one():
    level = np.r_[np.full(100, 0.16), np.linspace(0.5, 2.0, 400)]
    residual = np.r_[np.zeros(100), np.random.default_rng(1).normal(0.0, 0.1, 400)]
    active = np.ones(500, bool)
    active[:10] = False
    w = noise_weights(residual, level, active)
    assert np.all(w[:10] == 1.0)
    # the silent idle bin's scale is held at MIN_SCALE_SHARE of the largest: its weight at
    # most 1 / MIN_SCALE_SHARE^2 times the noisiest bin's
    assert w[10:100].max() / w[100:].min() <= 1.0 / MIN_SCALE_SHARE ** 2 * 1.000001


def _idle_problem(seed: int, load: float) -> Problem:
    """A recording a third at idle: noise 0.01 g/s at idle, 0.2 g/s driving; a constant load
    (all engine-on samples) of ``load`` g/s and a rival that is zero at idle (a drag)."""
    rng = np.random.default_rng(seed)
    t = np.arange(N, dtype=float)
    idle = (t // 60) % 3 == 0
    speed = np.where(idle, 0.0, 10.0 + 8.0 * np.sin(2 * np.pi * t / 170.0))
    base = np.where(idle, 0.16, 0.5 + 0.08 * speed)
    on = np.ones(N)
    noise = rng.normal(0.0, np.where(idle, 0.01, 0.2))
    cands = [Candidate("accessory_load", [on], [{}], 0.0, 5.0),
             Candidate("aero_drag", [1e-4 * speed ** 3], [{}], 0.0, 5.0)]
    return Problem("vehicle", "fuel_rate_g_per_s", t, base + load * on + noise, base, cands, {},
                   driver_channels={"speed": speed}, units="g/s",
                   integral=IntegralSpec(moving=speed > 0.1, speed_mps=speed, weight=np.ones(N), unit="g"))


def test_weighted_windows_size_a_load_the_idle_noise_resolves():
    # load 0.01 g/s: 667 idle samples of noise 0.01 give it a standard error of 0.0004 g/s
    # (weighted least squares), the driving samples alone 0.005; the weighted selection must
    # name it within 3 of the former's standard errors plus the weights' own error (10 %)
    p = _idle_problem(2, 0.01)
    sel = select(noise_weighted(p), Settings(n_shifts=50))
    found = {f.effect: f.parameters for f in sel.findings}
    assert list(found) == ["accessory_load"]
    # the candidate's column is 1 g/s per unit of its linear parameter here
    size = next(a.coefficient for a in sel.accepted)
    assert size == pytest.approx(0.01, abs=3 * 0.01 / np.sqrt(667) + 0.001)


def test_weighted_windows_stay_quiet_on_noise_alone():
    for seed in (3, 4, 5):
        sel = select(noise_weighted(_idle_problem(seed, 0.0)), Settings(n_shifts=50))
        assert not sel.findings


def test_reweighting_is_weighted_least_squares():
    p = _idle_problem(6, 0.01)
    w = np.random.default_rng(7).uniform(0.5, 2.0, N)
    q = reweighted(p, w)
    x, r = p.candidates[0].columns[0], p.residual
    wls = float(np.sum(w * x * r) / np.sum(w * x * x))
    xq = q.candidates[0].columns[0]
    assert float(xq @ q.residual / (xq @ xq)) == pytest.approx(wls, rel=1e-12)


def _warm_problem(seed: int) -> Problem:
    t = np.arange(300, dtype=float)
    rng = np.random.default_rng(seed)
    cands = [Candidate("warmup", [np.exp(-t / 60.0)], [{"tau_s": 60.0}], 0.0, 20.0),
             Candidate("accessory_load", [np.ones(300)], [{}], 0.0, 5.0)]
    return Problem("vehicle", "fuel_rate_g_per_s", t, rng.normal(0.0, 0.01, 300), np.zeros(300), cands, {},
                   units="g/s", integral=IntegralSpec(moving=np.ones(300, bool), speed_mps=None,
                                                      weight=np.ones(300), unit="g"))


def test_a_declared_hot_start_has_no_warmup_candidate():
    joined, _ = join([_warm_problem(1), _warm_problem(2)], ["cold", "hot"])
    kept = without_warmup(joined, ["hot"])
    assert [c.id for c in kept.candidates] == ["warmup@cold", "accessory_load"]
    with pytest.raises(InputError, match="warmup@nosuch"):
        without_warmup(joined, ["nosuch"])


def test_an_unknown_weighting_names_the_valid_ones():
    with pytest.raises(InputError, match="noise"):
        join_coarse([_warm_problem(1), _warm_problem(2)], ["a", "b"], 10, weights="nois")
