"""The contrast comparison of two physical effects (fleetrun.diagnose.contrast) on generated
problems with a known answer: a grade-like column (fuel ~ v) and a drag-like column (fuel ~
v^3) on a drive with slow and fast stretches, their pooled cosine about 0.9 as on the Camry's
windows (docs/diagnose-realdata.md, 1c-1i), noise AR(1)."""
import numpy as np
import pytest

from fleetrun.diagnose.contrast import ALWAYS_TRAIN, compare, contrast_folds


def _drive(n=600, seed=0):
    rng = np.random.default_rng(seed)
    # 10-s windows of a mixed drive: standstill, town (3-12 m/s), highway (20-30 m/s)
    kind = rng.choice(3, size=n, p=[0.15, 0.45, 0.4])
    v = np.where(kind == 0, 0.0, np.where(kind == 1, rng.uniform(3, 12, n), rng.uniform(20, 30, n)))
    grade = v / 10.0
    drag = v ** 3 / 1000.0
    return rng, grade, drag


def _noise(rng, n, sigma, rho=0.5):
    e = np.zeros(n)
    w = rng.normal(0.0, sigma, n)
    for i in range(1, n):
        e[i] = rho * e[i - 1] + w[i]
    return e


def _shifts(rng, n, b=200):
    return rng.integers(int(0.05 * n), n - int(0.05 * n), b)


def test_folds_split_the_rows_where_either_column_acts_and_never_hold_out_the_rest():
    _, grade, drag = _drive()
    folds = contrast_folds(grade, drag)
    assert set(np.unique(folds)) == {ALWAYS_TRAIN, 0, 1}
    assert np.all(folds[grade == 0] == ALWAYS_TRAIN)
    # the grade's share is larger in the slow rows: they are fold 1
    assert grade[folds == 1].mean() < grade[folds == 0].mean()
    # proportional columns do not split
    assert contrast_folds(grade, 2.0 * grade) is None


@pytest.mark.parametrize("truth", ["grade", "drag"])
def test_the_true_effect_wins_where_the_pooled_fit_cannot_tell(truth):
    """Each at a size where the pooled fit leaves both within noise of each other."""
    wins = 0
    for seed in range(10):
        rng, grade, drag = _drive(seed=seed)
        cos = grade @ drag / np.sqrt((grade @ grade) * (drag @ drag))
        assert 0.85 < cos < 0.95
        x = grade if truth == "grade" else drag
        r = 0.3 * x / np.sqrt(np.mean(x ** 2)) + _noise(rng, len(x), 0.1)
        nums = compare(r, [], (grade, -15.0, 15.0), (drag, 0.0, 20.0), _shifts(rng, len(x)), 0.99)
        who = nums.winner
        wins += who == ("a" if truth == "grade" else "r")
        assert who != ("r" if truth == "grade" else "a"), nums
    assert wins >= 9


@pytest.mark.parametrize("noise", ["own", "both"])
def test_noise_alone_names_no_winner_mostly(noise):
    winners = 0
    for seed in range(20):
        rng, grade, drag = _drive(seed=seed)
        r = _noise(rng, len(grade), 0.1)
        who = compare(r, [], (grade, -15.0, 15.0), (drag, 0.0, 20.0), _shifts(rng, len(grade)), 0.99, noise).winner
        winners += who is not None
    assert winners <= 2


@pytest.mark.parametrize("truth", ["grade", "drag"])
def test_the_null_with_both_effects_in_names_the_true_one_and_never_the_other(truth):
    wins = 0
    for seed in range(10):
        rng, grade, drag = _drive(seed=seed)
        x = grade if truth == "grade" else drag
        r = 0.3 * x / np.sqrt(np.mean(x ** 2)) + _noise(rng, len(x), 0.1)
        who = compare(r, [], (grade, -15.0, 15.0), (drag, 0.0, 20.0), _shifts(rng, len(x)), 0.99, "both").winner
        wins += who == ("a" if truth == "grade" else "r")
        assert who != ("r" if truth == "grade" else "a")
    assert wins >= 9


def test_an_unknown_null_noise_is_an_error():
    rng, grade, drag = _drive()
    with pytest.raises(ValueError, match="noise must be one of"):
        compare(grade, [], (grade, -15.0, 15.0), (drag, 0.0, 20.0), _shifts(rng, len(grade)), 0.99, "pooled")
